"""A track's aggregate is what its runs make (issue 16, Medium 6).

The probe deleted a run while the worker stored it: the delete read which chunks the run
covered before the store had committed them, recomputed nothing, and 432 033 points of the
deleted run stayed in the track's profile. Here the store is held open in a second
connection while the delete runs; the delete must wait for it (the track lock taken before
reading) and leave an aggregate equal to the runs' (``python -m app check-aggregates``).
"""

from __future__ import annotations

import contextlib
import io
import threading
import time

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from api.api_support import sql, upload
from app.cli import main as cli_main
from app.core.config import get_settings
from app.db.models import TrackRunLevels
from app.db.session import Database
from app.services.track.aggregate import recompute_aggregate
from app.services.track.consistency import check_aggregate


def _check_command(monkeypatch, settings, *args: str) -> tuple[int, str]:
    monkeypatch.setenv("DATABASE_URL", settings.sqlalchemy_url)
    get_settings.cache_clear()
    out = io.StringIO()
    try:
        with contextlib.redirect_stdout(out):
            code = cli_main(["check-aggregates", *args])
    finally:
        get_settings.cache_clear()
    return code, out.getvalue()


def _two_runs(client, synthetic_run) -> tuple[int, int]:
    ids = []
    for i, start in enumerate((12.0, 12.3)):
        # distinct logs (a trailing blank line): the same bytes again are the stored run
        csv = synthetic_run["csv"] + b"\n" * i
        r = upload(client, csv, track="L", start_chainage_m=start)
        assert r.status_code == 201, r.text
        ids.append(r.json()["id"])
    return ids[0], ids[1]


def test_the_command_finds_and_fixes_a_stale_aggregate(client, settings, synthetic_run,
                                                       monkeypatch) -> None:  # fmt: skip
    """Consistent after uploads and a delete (exit 0); after a run's levels vanish without
    a recompute (what the race left) it reports the track (exit 1); --fix rebuilds it."""
    a, b = _two_runs(client, synthetic_run)
    tid = client.get("/api/v1/tracks/L").json()["id"]
    code, out = _check_command(monkeypatch, settings)
    assert code == 0 and "ok" in out, out
    assert client.delete(f"/api/v1/runs/{b}").status_code == 204
    assert _check_command(monkeypatch, settings)[0] == 0
    sql(settings, "DELETE FROM track_run_levels WHERE run_id = :r", r=a)
    code, out = _check_command(monkeypatch, settings)
    assert code == 1 and "DIFFERS" in out, out
    code, out = _check_command(monkeypatch, settings, "--fix", "L")
    assert code == 0 and "rebuilt" in out
    assert _check_command(monkeypatch, settings)[0] == 0
    assert client.get(f"/api/v1/tracks/{tid}/profile").json().get("n", 0) == 0


@pytest.mark.sqlite_only
def test_a_delete_waits_for_a_store_in_progress(start_app, settings, synthetic_run) -> None:
    """A store of run R (its levels and the aggregate written, not yet committed) is held
    open while R is deleted: the delete waits for it, then takes R out of the aggregate."""
    # no worker anywhere: the queued run R is stored by this test alone
    client = start_app(start_worker=False)
    done_id, _ = _two_runs(client, synthetic_run)
    queued = start_app(inline_max_samples=0, start_worker=False)
    r = upload(queued, synthetic_run["csv"] + b"\n" * 2, track="L", start_chainage_m=12.6)
    assert r.status_code == 202, r.text
    run_id = r.json()["id"]
    tid = client.get("/api/v1/tracks/L").json()["id"]
    db = Database(settings.sqlalchemy_url)
    store = Session(db.engine)
    rows = store.execute(select(TrackRunLevels).where(TrackRunLevels.run_id == done_id)).scalars()
    chunks = []
    for row in list(rows):
        store.add(TrackRunLevels(run_id=run_id, chunk=row.chunk, track_id=tid, levels=row.levels,
                                 force_n=row.force_n))  # fmt: skip
        chunks.append(row.chunk)
    store.flush()  # the store's transaction now holds the write lock
    recompute_aggregate(store, tid, min(chunks), max(chunks))
    answer = {}

    def delete() -> None:
        answer["status"] = client.delete(f"/api/v1/runs/{run_id}").status_code

    t = threading.Thread(target=delete)
    t.start()
    time.sleep(0.5)  # the delete reads (and, unlocked, decides) while the store is open
    store.commit()
    store.close()
    t.join(30)
    assert answer == {"status": 204}
    with db.session() as s:
        chk = check_aggregate(s, tid)
    db.dispose()
    assert chk.ok, chk
