"""Helpers of the API tests: row counts, sample runs, uploads, zone checks."""

from __future__ import annotations

import json
import sqlite3
import struct
import time
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import create_engine, inspect, text
from sqlalchemy.engine import make_url
from sqlalchemy.pool import NullPool
from starlette.testclient import TestClient

from app.core.config import Settings
from support.samples import REPO, shared_data_dir

TABLES = (
    "tracks", "vehicles", "runs", "run_inputs", "run_profile_blocks", "soft_spots", "run_signals",
    "api_keys",
)  # fmt: skip
"""Tables a run writes to (``row_counts`` counts every table there is)."""


def is_sqlite(settings: Settings) -> bool:
    """True when the test app's database is a SQLite file."""
    return make_url(settings.sqlalchemy_url).get_backend_name() == "sqlite"


def db_file(settings: Settings) -> Path:
    """The SQLite file of a test app."""
    return Path(settings.sqlalchemy_url.removeprefix("sqlite:///"))


def row_counts(settings: Settings) -> dict[str, int]:
    """Number of rows in every table of the database (Alembic's bookkeeping aside), read
    outside the app: plain sqlite3 for a SQLite file, a separate connection otherwise.

    Tables are listed from the database itself, so tables added by later migrations are
    counted too.
    """
    if is_sqlite(settings):
        con = sqlite3.connect(db_file(settings))
        try:
            names = [
                r[0]
                for r in con.execute(
                    "SELECT name FROM sqlite_master WHERE type='table' "
                    "AND name NOT LIKE 'sqlite_%' AND name != 'alembic_version'"
                )
            ]
            return {t: con.execute(f'SELECT count(*) FROM "{t}"').fetchone()[0] for t in names}
        finally:
            con.close()
    engine = create_engine(settings.sqlalchemy_url, poolclass=NullPool)
    try:
        with engine.connect() as conn:
            names = [t for t in inspect(conn).get_table_names() if t != "alembic_version"]
            return {
                t: conn.execute(text(f'SELECT count(*) FROM "{t}"')).scalar_one() for t in names
            }
    finally:
        engine.dispose()


def stored_points(settings: Settings) -> dict[int, int]:
    """Grid points of each run's stored profile (``run_profile_blocks``), read outside the
    app: the point count every block carries in its header."""
    counts: dict[int, int] = {}
    for run_id, data in sql(settings, "SELECT run_id, data FROM run_profile_blocks"):
        counts[run_id] = counts.get(run_id, 0) + struct.unpack_from("<I", bytes(data), 4)[0]
    return counts


def sql(settings: Settings, statement: str, **params: Any) -> list[tuple[Any, ...]]:
    """Run one SQL statement on the test app's database outside the app (committed);
    the rows it returns. Parameters are named (``:name``)."""
    engine = create_engine(settings.sqlalchemy_url, poolclass=NullPool)
    try:
        with engine.begin() as conn:
            result = conn.execute(text(statement), params)
            return [tuple(r) for r in result] if result.returns_rows else []
    finally:
        engine.dispose()


def sample(name: str) -> tuple[bytes, dict[str, Any]]:
    """A shared sample run's CSV bytes and its truth; skips when ../shared is absent."""
    d = shared_data_dir()
    if d is None or not (d / f"{name}.csv").exists():
        pytest.skip(f"shared sample {name} not available (set SHARED_DIR to the shared folder)")
    return (d / f"{name}.csv").read_bytes(), json.loads((d / f"{name}.truth.json").read_text())


def example() -> tuple[bytes, dict[str, Any]]:
    """The example log shipped in the repository (``examples/example_run.csv.gz``: a logger's
    raw format, epoch s, g with gravity, deg/s, km/h) uncompressed, and its truth. Always there:
    tests of the raw upload path need no shared folder."""
    import gzip

    data = gzip.decompress((REPO / "examples" / "example_run.csv.gz").read_bytes())
    return data, json.loads((REPO / "examples" / "example_run.truth.json").read_text())


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
