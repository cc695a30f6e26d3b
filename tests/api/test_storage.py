"""Storage: data survives a restart, migrations, SQLite settings, the per-chainage layout."""

from __future__ import annotations

import os
import sqlite3
import time

import numpy as np
import pytest
from sqlalchemy import select
from sqlalchemy.exc import IntegrityError

from api.api_support import db_file, is_sqlite, row_counts, sql, stored_points, upload
from app.db.migrate import alembic_config, current_revision
from app.db.models import Run, RunProfileBlock
from app.db.session import Database


def test_restart_keeps_the_data(start_app, synthetic_run) -> None:
    """A new app instance on the same database file serves the same runs, profiles and spots."""
    first = start_app()
    rid = upload(first, synthetic_run["csv"], track="T",
                 start_chainage_m=synthetic_run["start_chainage_m"]).json()["id"]  # fmt: skip
    before = {
        p: first.get(f"/api/v1/runs/{rid}{p}").json() for p in ("", "/profile", "/soft-spots")
    }
    first.__exit__(None, None, None)
    second = start_app()
    after = {
        p: second.get(f"/api/v1/runs/{rid}{p}").json() for p in ("", "/profile", "/soft-spots")
    }
    assert after == before
    assert after["/profile"]["n"] > 400


def test_migrations_run_on_start_and_are_idempotent(start_app, settings) -> None:
    """Starting the app brings an empty database to the latest revision; starting again
    changes nothing (the Table 1 vehicle is seeded once)."""
    from alembic.script import ScriptDirectory

    start_app()
    start_app()
    head = ScriptDirectory.from_config(alembic_config()).get_current_head()
    db = Database(settings.sqlalchemy_url)
    assert current_revision(db) == head
    assert row_counts(settings)["vehicles"] == 1
    db.dispose()


def test_the_migrations_build_the_models_schema(start_app, settings) -> None:
    """The schema the migrations make is the one the models declare (tables, columns and
    their types, indexes, keys): a model changed without its migration fails here."""
    from alembic.autogenerate import compare_metadata
    from alembic.migration import MigrationContext

    from app.db.base import Base

    start_app()
    db = Database(settings.sqlalchemy_url)
    with db.engine.connect() as conn:
        context = MigrationContext.configure(conn, opts={"compare_type": True})
        assert compare_metadata(context, Base.metadata) == []
    db.dispose()


@pytest.mark.sqlite_only
def test_sqlite_runs_in_wal_mode_with_foreign_keys(client, settings) -> None:
    """The app's connections use WAL, enforce foreign keys and wait on a busy database."""
    ctx = client.app.state.ctx
    with ctx.db.engine.connect() as conn:
        raw = conn.connection.driver_connection
        assert raw.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
        assert raw.execute("PRAGMA foreign_keys").fetchone()[0] == 1
        assert raw.execute("PRAGMA busy_timeout").fetchone()[0] >= 5000


def _write_scratch(db: Database, size: int) -> None:
    with db.engine.begin() as conn:
        conn.exec_driver_sql("CREATE TABLE scratch (data BLOB)")
        conn.exec_driver_sql("INSERT INTO scratch VALUES (?)", (os.urandom(size),))


@pytest.mark.sqlite_only
def test_a_commit_leaves_the_wal_to_the_checkpoint(start_app) -> None:
    """A large commit (an hour's log is ~50 MB) is not copied into the database file on the
    committing request's path, as SQLite's default (past 1000 pages) would; a checkpoint
    copies it."""
    client = start_app(start_worker=False)
    db = client.app.state.ctx.db
    path = db_file(client.app.state.ctx.settings)
    _write_scratch(db, 8 << 20)  # ~2050 pages of 4 KiB
    assert path.stat().st_size < 4 << 20, "the commit copied the WAL into the database"
    assert db.checkpoint() > 2000
    assert path.stat().st_size > 8 << 20


@pytest.mark.sqlite_only
def test_the_idle_worker_checkpoints_the_wal(start_app) -> None:
    client = start_app()
    path = db_file(client.app.state.ctx.settings)
    _write_scratch(client.app.state.ctx.db, 8 << 20)
    deadline = time.monotonic() + 10
    while path.stat().st_size < 8 << 20 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert path.stat().st_size > 8 << 20, "the idle worker did not checkpoint the WAL"


@pytest.mark.sqlite_only
def test_profile_is_stored_in_blocks_and_read_by_key(client, settings, synthetic_run):
    """A profile is a few compressed 1 km blocks; a chainage window is a primary-key range
    search over them, in block order without sorting."""
    r = upload(client, synthetic_run["csv"], track="T",
               start_chainage_m=synthetic_run["start_chainage_m"])  # fmt: skip
    rid = r.json()["id"]
    prof = client.get(f"/api/v1/runs/{rid}/profile").json()
    assert stored_points(settings) == {rid: prof["n"]}
    span_km = (prof["chainage_m"][-1] - prof["chainage_m"][0]) / 1000
    assert row_counts(settings)["run_profile_blocks"] <= span_km + 2
    ctx = client.app.state.ctx
    t = RunProfileBlock.__table__
    stmt = (
        select(t.c.first, t.c.data)
        .where(t.c.run_id == rid, t.c.block >= 0, t.c.block <= 2)
        .order_by(t.c.block)
    )
    sql_text = str(stmt.compile(ctx.db.engine, compile_kwargs={"literal_binds": True}))
    con = sqlite3.connect(db_file(settings))
    plan = " ".join(str(row[-1]) for row in con.execute(f"EXPLAIN QUERY PLAN {sql_text}"))
    con.close()
    # the (run_id, block) key: SQLite names it PRIMARY KEY or its automatic index
    assert "run_id=? AND block>" in plan and "SCAN" not in plan, plan
    assert "TEMP B-TREE" not in plan  # blocks come in chainage order without sorting


def test_stored_profile_keeps_levels_to_the_stated_resolution(client, settings, synthetic_run):
    """What is served is the engine's profile rounded to 0.0001 mm (levels) and 1 N (forces);
    where an axle did not pass its level is missing (null), never NaN in the JSON."""
    from app.services.run_lifecycle.logs import parse_csv
    from app.services.run_lifecycle.processing import invert
    from engine.setup import RunSetup, prepare_run
    from engine.track import TrackParams
    from engine.vehicle import VehicleParams

    rid = upload(client, synthetic_run["csv"], track="T",
                 start_chainage_m=synthetic_run["start_chainage_m"]).json()["id"]  # fmt: skip
    prof = client.get(f"/api/v1/runs/{rid}/profile", params={"include": "all"}).json()
    assert None in prof["front_level_mm"] or None in prof["rear_level_mm"]
    ctx = client.app.state.ctx
    with ctx.db.session() as s:
        run = s.get(Run, rid)
        vp = VehicleParams.from_dict(run.vehicle.params_dict())
        tp = TrackParams.from_dict(run.track.params_dict())
    setup = RunSetup(synthetic_run["start_chainage_m"], "increasing", vp, tp)
    res = invert(prepare_run(parse_csv(synthetic_run["csv"], {}), setup)).result
    assert prof["n"] == res.chainage_m.size
    np.testing.assert_array_equal(np.asarray(prof["chainage_m"]), res.chainage_m)
    tolerance = {"front_force_n": 0.5, "rear_force_n": 0.5}  # N; levels 0.00005 mm
    for name in ("level_mm", "front_level_mm", "rear_level_mm", "baseline_mm", *tolerance):
        tol = tolerance.get(name, 5e-5)
        got = np.array([np.nan if v is None else v for v in prof[name]])
        want = getattr(res, name)
        assert np.array_equal(np.isnan(got), np.isnan(want)), name
        ok = np.isfinite(want)
        assert np.abs(got[ok] - want[ok]).max() <= tol * (1 + 1e-9), name


def test_deleting_a_track_with_runs_is_prevented_by_the_database(client, settings) -> None:
    """Foreign keys are enforced: a track with runs cannot be removed underneath them."""
    r = client.post("/api/v1/simulate", json={"track": "fk", "length_m": 120, "zones": [],
                                              "speed_mps": 25})  # fmt: skip
    assert r.status_code == 201, r.text
    if is_sqlite(settings):
        con = sqlite3.connect(db_file(settings))
        con.execute("PRAGMA foreign_keys=ON")
        with pytest.raises(sqlite3.IntegrityError):
            con.execute("DELETE FROM tracks WHERE name='fk'")
        con.close()
    else:
        with pytest.raises(IntegrityError):
            sql(settings, "DELETE FROM tracks WHERE name='fk'")
    assert row_counts(settings)["tracks"] == 1
