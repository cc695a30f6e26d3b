"""Fixtures of the API tests: the real app on a real SQLite file in a temporary directory.

Every test gets its own database; the app is built with ``create_app(settings)`` and driven
through Starlette's httpx-based test client, which runs the app's lifespan (migrations, the
background worker) like uvicorn does.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from app.core.config import REPO_ROOT, Settings
from app.main import create_app

with warnings.catch_warnings():
    # Starlette announces a move to httpx2 for its test client; httpx is what is installed.
    warnings.simplefilter("ignore")
    from starlette.testclient import TestClient


def make_settings(tmp_path: Path, **overrides: Any) -> Settings:
    """Settings for a test app whose database is ``tmp_path/trackprofile.db``."""
    values: dict[str, Any] = {
        "data_dir": tmp_path,
        "database_url": f"sqlite:///{tmp_path / 'trackprofile.db'}",
        "static_dir": REPO_ROOT / "static",
        "poll_interval_s": 0.05,
    }
    values.update(overrides)
    return Settings(**values)


@pytest.fixture
def settings(tmp_path: Path) -> Settings:
    """Default test settings (short logs processed inline, worker running)."""
    return make_settings(tmp_path)


@pytest.fixture
def client(settings: Settings) -> Iterator[TestClient]:
    """A client of a freshly started app on an empty database."""
    with TestClient(create_app(settings)) as c:
        yield c


@pytest.fixture
def start_app(tmp_path: Path) -> Iterator[Callable[..., TestClient]]:
    """Start apps with custom settings on the test's database: ``start_app(**settings)``."""
    clients: list[TestClient] = []

    def start(**overrides: Any) -> TestClient:
        c = TestClient(create_app(make_settings(tmp_path, **overrides)))
        c.__enter__()
        clients.append(c)
        return c

    yield start
    for c in reversed(clients):
        c.__exit__(None, None, None)


@pytest.fixture(scope="session")
def synthetic_run() -> dict[str, Any]:
    """A short noisy run made with the engine's forward model (independent of ../shared).

    160 m of track with one 50 % soft zone at 70-75 m, 25 m/s, realistic sensor, seed 3.
    Returns the canonical CSV bytes, the start chainage (m) and the true zones.
    """
    import io

    from engine.logio import write_run_csv
    from engine.synthetic import REALISTIC_SENSOR, make_run
    from engine.track import SoftZone

    zones = [SoftZone(70.0, 75.0, 0.5)]
    run = make_run(
        length=160.0, zones=zones, speed=25.0, start_chainage_m=12.0, jitter=0.03,
        sensor=REALISTIC_SENSOR, seed=3,
    )  # fmt: skip
    buf = io.StringIO()
    write_run_csv(run.log, buf, digits=8)
    return {
        "csv": buf.getvalue().encode(),
        "start_chainage_m": 12.0,
        "zones": [{"start_m": z.start_m, "end_m": z.end_m} for z in zones],
        "n_samples": run.log.n,
    }
