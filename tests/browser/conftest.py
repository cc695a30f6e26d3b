"""Fixtures of the real-browser tests: the service under uvicorn, Debian's Chromium via Playwright.

Screenshots of the pages go to ``docs/screenshots`` when ``UPDATE_SCREENSHOTS=1`` is set, and
to a temporary folder otherwise (so that a test run leaves the work tree clean).
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from browser.harness import (
    CHROMIUM,
    CHROMIUM_ARGS,
    SAMPLE_START_M,
    SAMPLE_ZONES,
    SCREENSHOTS,
    VIEWPORT,
    LiveServer,
    PageWatch,
    ensure_plotly_bundle,
    start_server,
    stop_server,
)

from support.samples import shared_data_dir


@pytest.fixture(scope="session")
def live_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LiveServer]:
    """The service on an empty database, shared by the tests of the session; it serves the
    dashboard's plotly.js bundle (built from npm when missing), so every chart test draws
    with it."""
    ensure_plotly_bundle()
    server = start_server(tmp_path_factory.mktemp("browser-service"))
    try:
        yield server
    finally:
        stop_server(server)


@pytest.fixture(scope="session")
def browser() -> Iterator[Any]:
    """Debian's Chromium, headless, driven by Playwright (sync API)."""
    if not CHROMIUM.exists():
        pytest.skip("Debian chromium is not installed (apt-get install chromium)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            yield b
        finally:
            b.close()


@pytest.fixture
def page(browser: Any) -> Iterator[Any]:
    """A fresh page at 1366x768 with a ``watch`` attribute (errors, dialogs, 5xx)."""
    context = browser.new_context(viewport=VIEWPORT, accept_downloads=True)
    pg = context.new_page()
    watch = PageWatch()
    pg.on("pageerror", lambda exc: watch.page_errors.append(str(exc)))

    def on_dialog(dialog: Any) -> None:
        watch.dialogs.append(f"{dialog.type}: {dialog.message}")
        dialog.dismiss()

    pg.on("dialog", on_dialog)
    pg.on(
        "response",
        lambda r: watch.server_errors.append(f"{r.status} {r.url}") if r.status >= 500 else None,
    )
    pg.watch = watch
    pg.set_default_timeout(30_000)
    try:
        yield pg
    finally:
        context.close()


@pytest.fixture(scope="session")
def sample_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``sample_noisy.csv`` from the shared folder, else a stand-in simulated like it.

    Either way the run starts at chainage 24.13 m and has soft zones at 140-146 m (50 %) and
    333-337 m (35 %).
    """
    shared = shared_data_dir()
    if shared is not None and (shared / "sample_noisy.csv").exists():
        truth = json.loads((shared / "sample_noisy.truth.json").read_text())
        zones = tuple((z["start_m"], z["end_m"]) for z in truth["zones"])
        assert zones == SAMPLE_ZONES and truth["start_chainage_m"] == SAMPLE_START_M
        return shared / "sample_noisy.csv"
    from engine.logio import write_run_csv
    from engine.synthetic import REALISTIC_SENSOR, make_run
    from engine.track import SoftZone

    run = make_run(
        length=500.0,
        zones=(SoftZone(140, 146, 0.5), SoftZone(333, 337, 0.35)),
        speed=22.0,
        start_chainage_m=SAMPLE_START_M,
        jitter=0.05,
        sensor=REALISTIC_SENSOR,
        seed=7,
    )
    path = tmp_path_factory.mktemp("sample") / "sample_noisy.csv"
    write_run_csv(run.log, path, digits=8)
    return path


@pytest.fixture(scope="session")
def screenshots(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Where the tests write page screenshots: docs/screenshots with ``UPDATE_SCREENSHOTS=1``
    (to refresh the README's pictures), a temporary folder otherwise."""
    if os.environ.get("UPDATE_SCREENSHOTS") != "1":
        return tmp_path_factory.mktemp("screenshots")
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    return SCREENSHOTS
