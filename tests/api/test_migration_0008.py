"""Migration 0008 (issue 15): a database holding runs stored before compact storage keeps
every result when upgraded.

The database is brought to the revision before 0008 with runs in it, stored the way that
revision stored them: a row per 0.25 m grid point with each column as the engine computed it
(float64), float32 chunks of aligned levels, the log as an uncompressed ``.npz``. Upgraded,
the service serves the same runs, profiles (to the stated resolution), signals, soft spots,
aggregate, register and separation as before, and calibration and reprocessing still read
the logs. Runs on SQLite and, with ``TEST_DATABASE_URL``, PostgreSQL.
"""

from __future__ import annotations

import io
from typing import Any

import numpy as np
from alembic import command
from alembic.script import ScriptDirectory

from api.api_support import row_counts, sql, upload, wait_done
from app.db.migrate import alembic_config, current_revision, upgrade
from app.db.session import Database
from app.services.run_lifecycle.logs import LOG_COLUMNS, parse_csv
from app.services.run_lifecycle.processing import invert
from engine.setup import RunSetup, prepare_run
from engine.track import TrackParams
from engine.vehicle import VehicleParams

STARTS = (12.0, 12.5, 13.0)
DETAIL = ("front_level_mm", "rear_level_mm", "baseline_mm", "front_force_n", "rear_force_n")


def _previous_revision() -> str:
    script = ScriptDirectory.from_config(alembic_config())
    down = script.get_revision("0008").down_revision
    assert isinstance(down, str)
    return down


def _served(client: Any, ids: list[int]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for rid in ids:
        for path in ("", "/profile?include=all", "/soft-spots", "/signals"):
            r = client.get(f"/api/v1/runs/{rid}{path}")
            assert r.status_code == 200, (rid, path, r.text)
            body = r.json()
            if path == "":
                # computed when a run is processed since a later revision (0014); an upgrade
                # from before it has none to keep
                body.pop("detection_limit", None)
            out[f"{rid}{path}"] = body
    for path in ("", "/profile", "/defects", "/stiffness"):
        r = client.get(f"/api/v1/tracks/M{path}")
        assert r.status_code == 200, (path, r.text)
        out[f"track{path}"] = r.json()
    return out


def _engine_profile(client: Any, rid: int, csv: bytes, start: float) -> Any:
    """What the engine computes for the run (float64), as the old schema stored it."""
    from app.db.models import Run

    with client.app.state.ctx.db.session() as s:
        run = s.get(Run, rid)
        vp = VehicleParams.from_dict(run.vehicle.params_dict())
        tp = TrackParams.from_dict(run.track.params_dict())
    return invert(prepare_run(parse_csv(csv, {}), RunSetup(start, "increasing", vp, tp))).result


def _as_legacy(settings: Any, rid: int, res: Any) -> None:
    """Overwrite a downgraded run's profile rows with the engine's full-precision values,
    as the pre-0007 service wrote them (one row per grid point, NULL = no data)."""

    def num(a: np.ndarray, i: int) -> float | None:
        return float(a[i]) if np.isfinite(a[i]) else None

    from sqlalchemy import create_engine, text
    from sqlalchemy.pool import NullPool

    engine = create_engine(settings.sqlalchemy_url, poolclass=NullPool)
    rows = [
        {"r": rid, "c": float(res.chainage_m[i]), "lv": num(res.level_mm, i),
         **{k: num(getattr(res, k), i) for k in DETAIL}}
        for i in range(res.chainage_m.size)
    ]  # fmt: skip
    sets = ", ".join(f"{k} = :{k}" for k in DETAIL)
    with engine.begin() as conn:
        n = conn.execute(
            text(f"UPDATE profile_points SET level_mm = :lv, {sets} "
                 "WHERE run_id = :r AND chainage_m = :c"),
            rows,
        ).rowcount  # fmt: skip
    engine.dispose()
    assert n == len(rows)


def test_upgrade_keeps_every_result(start_app, settings, synthetic_run) -> None:
    csv = synthetic_run["csv"]
    client = start_app(start_worker=False, log_retention_runs=None)
    ids = []
    for k, start in enumerate(STARTS):
        r = upload(client, csv + b"\n" * k, track="M", start_chainage_m=start,
                   recorded_at=f"2026-11-0{k + 1}T08:00:00Z")  # fmt: skip
        assert r.json()["status"] == "done", r.text
        ids.append(r.json()["id"])
    engine_result = _engine_profile(client, ids[0], csv, STARTS[0])
    before = _served(client, ids)
    client.__exit__(None, None, None)

    # The database as the previous revision had it, with these runs in it.
    db = Database(settings.sqlalchemy_url)
    cfg = alembic_config()
    previous = _previous_revision()
    with db.engine.begin() as conn:
        cfg.attributes["connection"] = conn
        command.downgrade(cfg, previous)
    assert current_revision(db) == previous
    counts = row_counts(settings)
    assert "run_profile_blocks" not in counts
    assert counts["profile_points"] == sum(before[f"{rid}/profile?include=all"]["n"] for rid in ids)
    _as_legacy(settings, ids[0], engine_result)
    blob = sql(settings, "SELECT data FROM run_inputs WHERE run_id = :r", r=ids[0])[0][0]
    with np.load(io.BytesIO(bytes(blob)), allow_pickle=False) as z:  # the old .npz log
        assert set(z.files) <= set(LOG_COLUMNS) and z["time_s"].size > 1000
    levels = sql(settings, "SELECT levels FROM track_run_levels WHERE run_id = :r", r=ids[0])
    assert levels and all(len(bytes(b)) == 4000 for (b,) in levels)  # raw float32 chunks

    upgrade(db)
    db.dispose()
    assert "profile_points" not in row_counts(settings)
    after_client = start_app(log_retention_runs=None)
    after = _served(after_client, ids)
    assert after.keys() == before.keys()
    for key in before:
        assert after[key] == before[key], key
    # the legacy float64 rows came through to the stated resolution
    prof = after[f"{ids[0]}/profile?include=all"]
    for name, tol in (
        ("level_mm", 5e-5),
        *((k, 5e-5 if k.endswith("mm") else 0.5) for k in DETAIL),
    ):
        got = np.array([np.nan if v is None else v for v in prof[name]])
        want = getattr(engine_result, name)
        assert np.array_equal(np.isnan(got), np.isnan(want)), name
        ok = np.isfinite(want)
        assert np.abs(got[ok] - want[ok]).max() <= tol * (1 + 1e-9), name
    # the logs are readable: reprocessing with new vehicle parameters reads them
    vehicle = after[str(ids[0])]["vehicle"]
    r = after_client.patch(f"/api/v1/vehicles/{vehicle}", json={"params": {"ms": 40_000.0}})
    assert r.status_code == 200, r.text
    for rid in ids:
        run = wait_done(after_client, rid)
        assert run["status"] == "done" and run["vehicle_version"] == 2, run
