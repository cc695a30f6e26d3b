"""Soft-spot labels on the run page's chainage chart at phone width (390 px): close soft
spots must not print their labels over one another."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from browser.harness import LiveServer, wait_for_plot

pytestmark = pytest.mark.browser

ZONES = [{"start_m": 80.0 + 35.0 * i, "end_m": 86.0 + 35.0 * i, "loss": 0.5} for i in range(6)]


@pytest.fixture(scope="module")
def close_spots_run(live_server: LiveServer) -> dict[str, Any]:
    """A simulated 400 m run over six soft zones 35 m apart."""
    with live_server.api() as api:
        r = api.post(
            "/api/v1/simulate?wait=true",
            json={"track": "label line", "length_m": 400, "speed_mps": 20, "seed": 5,
                  "zones": ZONES},
        )  # fmt: skip
        assert r.status_code == 201, r.text
        run: dict[str, Any] = r.json()["run"]
    assert run["n_soft_spots"] >= 5, run
    return run


@pytest.mark.parametrize("width", [390, 1280])
def test_soft_spot_labels_do_not_overlap(
    page: Any,
    live_server: LiveServer,
    close_spots_run: dict[str, Any],
    width: int,
    screenshots: Path,
) -> None:
    """Six soft spots 35 m apart on a 400 m run: every label drawn is clear of the others
    (boxes compared in the page), and at least half the spots keep a label."""
    run = close_spots_run
    page.set_viewport_size({"width": width, "height": 900})
    page.goto(f"{live_server.url}/#/runs/{run['id']}")
    wait_for_plot(page, "#profile-plot")
    boxes = page.evaluate(
        """() => [...document.querySelectorAll('#profile-plot .annotation')]
            .map(a => a.getBoundingClientRect())
            .map(b => [b.left, b.top, b.right, b.bottom])"""
    )
    assert len(boxes) >= run["n_soft_spots"] / 2, boxes
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            apart = a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1]
            assert apart, (width, a, b)
    if width == 390:
        page.locator("#profile-plot").scroll_into_view_if_needed()
        page.screenshot(path=str(screenshots / "run-phone.png"), full_page=False)
    page.watch.assert_clean()
