"""Migration 0009 (issue 15): a track's aggregate stored a row per 0.25 m grid point comes
through the move to packed chunks value for value.

Runs are stored, the database is brought back to 0008 (the aggregate written out as one row
per grid point, as that revision kept it) and upgraded again: the track's profile, defects and
stiffness are served exactly as before, and the stored aggregate is what the runs make
(``app.services.track.consistency.check_aggregate``). SQLite and, with ``TEST_DATABASE_URL``,
PostgreSQL.
"""

from __future__ import annotations

from typing import Any

from alembic import command

from api.api_support import row_counts, sql, upload
from app.db.migrate import alembic_config, current_revision, upgrade
from app.db.session import Database
from app.services.track.consistency import check_aggregate


def _track(client: Any) -> dict[str, Any]:
    out = {}
    for path in ("", "/profile", "/defects", "/stiffness"):
        r = client.get(f"/api/v1/tracks/G{path}")
        assert r.status_code == 200, (path, r.text)
        out[path] = r.json()
    return out


def test_upgrade_moves_the_aggregate_value_for_value(start_app, settings, synthetic_run) -> None:
    client = start_app(start_worker=False)
    for k, start in enumerate((12.0, 12.5)):
        r = upload(client, synthetic_run["csv"] + b"\n" * k, track="G", start_chainage_m=start,
                   recorded_at=f"2026-11-0{k + 1}T08:00:00Z")  # fmt: skip
        assert r.json()["status"] == "done", r.text
    before = _track(client)
    assert before["/profile"]["n"] > 500 and max(before["/profile"]["n_runs"]) == 2
    client.__exit__(None, None, None)

    db = Database(settings.sqlalchemy_url)
    cfg = alembic_config()
    with db.engine.begin() as conn:
        cfg.attributes["connection"] = conn
        command.downgrade(cfg, "0008")
    assert current_revision(db) == "0008"
    counts = row_counts(settings)
    assert "track_profile_chunks" not in counts
    assert counts["track_profile_points"] == before["/profile"]["n"]
    ((n_two,),) = sql(settings, "SELECT COUNT(*) FROM track_profile_points WHERE n_runs = 2")
    assert n_two == before["/profile"]["n_runs"].count(2)

    upgrade(db)
    assert "track_profile_points" not in row_counts(settings)
    assert 0 < row_counts(settings)["track_profile_chunks"] <= before["/profile"]["n"] / 100
    with db.session() as s:
        track_id = sql(settings, "SELECT id FROM tracks WHERE name = 'G'")[0][0]
        check = check_aggregate(s, track_id)
    db.dispose()
    assert check.ok and check.stored_points == before["/profile"]["n"], check
    after = start_app()
    assert _track(after) == before
