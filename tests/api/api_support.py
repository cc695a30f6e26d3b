"""Helpers of the API tests: row counts, sample runs, uploads, zone checks."""

from __future__ import annotations

import json
import sqlite3
import time
from pathlib import Path
from typing import Any

import pytest
from starlette.testclient import TestClient

from app.core.config import Settings
from support.samples import shared_data_dir

TABLES = (
    "tracks", "vehicles", "runs", "run_inputs", "profile_points", "soft_spots", "run_signals",
    "api_keys",
)  # fmt: skip


def db_file(settings: Settings) -> Path:
    """The SQLite file of a test app."""
    return Path(settings.sqlalchemy_url.removeprefix("sqlite:///"))


def row_counts(settings: Settings) -> dict[str, int]:
    """Number of rows in every table (read with plain sqlite3, outside the app)."""
    con = sqlite3.connect(db_file(settings))
    try:
        return {t: con.execute(f"SELECT count(*) FROM {t}").fetchone()[0] for t in TABLES}
    finally:
        con.close()


def sample(name: str) -> tuple[bytes, dict[str, Any]]:
    """A shared sample run's CSV bytes and its truth; skips when ../shared is absent."""
    d = shared_data_dir()
    if d is None or not (d / f"{name}.csv").exists():
        pytest.skip(f"shared sample {name} not available (set SHARED_DIR to the shared folder)")
    return (d / f"{name}.csv").read_bytes(), json.loads((d / f"{name}.truth.json").read_text())


def upload(
    client: TestClient,
    data: bytes,
    filename: str = "run.csv",
    *,
    params: dict[str, str] | None = None,
    headers: dict[str, str] | None = None,
    **fields: Any,
) -> Any:
    """POST a multipart upload; form fields given as keyword arguments (None left out)."""
    form = {k: str(v) for k, v in fields.items() if v is not None}
    return client.post(
        "/api/v1/runs",
        files={"file": (filename, data, "text/csv")},
        data=form,
        params=params,
        headers=headers,
    )


def assert_zones_match(
    found: list[dict[str, float]], zones: list[dict[str, float]], tol_m: float = 1.5
) -> None:
    """Every true zone is found once with start and end within ``tol_m``; nothing else."""
    assert len(found) == len(zones), f"found {found}, expected {zones}"
    for spot, zone in zip(sorted(found, key=lambda s: s["start_m"]), zones, strict=True):
        assert abs(spot["start_m"] - zone["start_m"]) <= tol_m, (spot, zone)
        assert abs(spot["end_m"] - zone["end_m"]) <= tol_m, (spot, zone)


def wait_done(client: TestClient, run_id: int, timeout: float = 60.0) -> dict[str, Any]:
    """Poll a run until it is no longer processing; returns its final state."""
    deadline = time.monotonic() + timeout
    while True:
        run = client.get(f"/api/v1/runs/{run_id}").json()
        if run["status"] != "processing" or time.monotonic() > deadline:
            return run
        time.sleep(0.05)


RAW_EPOCH0 = 1_763_800_000.0
GRAVITY = 9.81


def to_raw_imu(
    canonical_csv: bytes,
    names: tuple[str, str, str, str] = ("timestamp", "az_g", "gyro_y_dps", "speed_kmh"),
    delimiter: str = ",",
) -> bytes:
    """A canonical CSV rewritten the way a logger writes it: epoch seconds, acceleration in g
    including gravity, pitch rate in deg/s, speed in km/h (8 significant digits)."""
    import io

    import numpy as np

    a = np.loadtxt(io.BytesIO(canonical_csv), delimiter=",", skiprows=1)
    t, acc, rate, v = a[:, 0], a[:, 1], a[:, 2], a[:, 3]
    cols = [RAW_EPOCH0 + t, (acc + GRAVITY) / GRAVITY, np.degrees(rate), v * 3.6]
    out = io.StringIO()
    out.write(delimiter.join(names) + "\n")
    np.savetxt(
        out, np.column_stack(cols), fmt=["%.3f", "%.8g", "%.8g", "%.8g"], delimiter=delimiter
    )
    return out.getvalue().encode()
