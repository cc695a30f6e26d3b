"""A queued run is answered done before its long level (the 3-100 m level D2 is filtered from,
``engine.track_quality.long_level``): the worker that stored the run inverts and stores it
next, in a transaction of its own. Until then the quality answer names the run and does not
present D2 from a missing level; a process stopped in between leaves the run marked and an idle
look inverts it again from the stored log; a realignment in between does not lose it; the
level stored is the one the run's inline processing stores. Runs stored before the long level
was kept (its column NULL) answer D2 from the 3-40 m level, flagged.
"""

from __future__ import annotations

import dataclasses
import io
import time
from datetime import timedelta
from typing import Any

import numpy as np
import pytest
from sqlalchemy import select, update

import app.services.run_lifecycle.jobs.long_level as long_level_job
from api.api_support import upload
from app.db.models import Run, Track, TrackRunLevels
from app.services.run_lifecycle.jobs import LongLevelJob
from app.services.run_lifecycle.queue import Worker
from app.services.storage.profiles import unpack_long_level
from app.services.track.integrate import realign_track, store_long_level
from app.services.track.quality import Analysis, read_levels, track_quality
from app.services.views.window import Window
from engine.logio import write_run_csv
from engine.quality_limits import QualityLimits
from engine.synthetic import REALISTIC_SENSOR, make_run, make_track
from engine.vehicle import PRESETS

pytestmark = pytest.mark.slow

SENSOR = dataclasses.replace(REALISTIC_SENSOR, sample_rate_hz=500.0)


@pytest.fixture(scope="module")
def long_run() -> dict[str, Any]:
    """A 330 m run of the paper's coach over German low-disturbance geometry: long enough for
    the 100 m band (twice its longest wavelength), short enough for a test."""
    track = make_track(330.0, irregularity="german-low", seed=3401)
    syn = make_run(
        track=track, vehicle=PRESETS["table1"], speed=25.0, start_chainage_m=10.0,
        sensor=SENSOR, sim_rate_hz=1000.0, seed=3402,
    )  # fmt: skip
    buf = io.StringIO()
    write_run_csv(syn.log, buf, digits=8)
    return {"csv": buf.getvalue().encode(), "start_chainage_m": 10.0}


def _upload(c, run: dict[str, Any], track: str, status: int) -> int:
    r = upload(c, run["csv"], track=track, vehicle="table1",
               start_chainage_m=run["start_chainage_m"])  # fmt: skip
    assert r.status_code == status, r.text
    return int(r.json()["id"])


def _drain(worker: Worker) -> None:
    deadline = time.monotonic() + 120
    while worker.run_once():
        assert time.monotonic() < deadline


def _long(ctx, run_id: int) -> dict[int, np.ndarray]:
    """A run's stored long level by chunk (NULL chunks left out), mm."""
    t = TrackRunLevels.__table__
    with ctx.db.session() as s:
        rows = s.execute(select(t.c.chunk, t.c.long_mm).where(t.c.run_id == run_id)).all()
    return {int(c): unpack_long_level(b) for c, b in rows if b is not None}


def _quality(c, track: str) -> dict[str, Any]:
    r = c.get(f"/api/v1/tracks/{track}/quality")
    assert r.status_code == 200, r.text
    return r.json()


def _same_long(a: dict[int, np.ndarray], b: dict[int, np.ndarray]) -> None:
    assert a and sorted(a) == sorted(b)
    for chunk in a:
        assert np.array_equal(np.isnan(a[chunk]), np.isnan(b[chunk]))
        ok = np.isfinite(a[chunk])
        # the stored log is the parsed one: same level to the column's 0.001 mm resolution
        assert np.max(np.abs(a[chunk][ok] - b[chunk][ok])) <= 0.002


def test_the_long_level_follows_the_done_run_and_survives_a_stop(
    start_app, long_run, monkeypatch
) -> None:
    """Worker path with a stop after the run's commit (track W), without one (track L), and
    the inline path (track I) on one database: W and L end with I's long level and D2."""
    c = start_app(inline_max_samples=0, start_worker=False)
    ctx = c.app.state.ctx
    # the process "stops" after the run's commit, before its long level
    monkeypatch.setattr(LongLevelJob, "complete", lambda self, *args: False)
    w_id = _upload(c, long_run, "W", 202)
    _drain(Worker(ctx))
    assert c.get(f"/api/v1/runs/{w_id}").json()["status"] == "done"
    assert _long(ctx, w_id) == {}
    with ctx.db.session() as s:
        run = s.get(Run, w_id)
        assert run is not None and run.long_level_pending
        processed_at = run.processed_at
        # waiting: D2 leaves the pass out (its own D2 pass level too), and says so
        lv = read_levels(s, run.track_id, Window())
        assert lv is not None and lv.long_pending == {w_id}
        q = Analysis(lv, QualityLimits(), (), Window())
        assert w_id in q.pass_levels("D1") and w_id not in q.pass_levels("D2")
    waiting = _quality(c, "W")
    assert any("still being inverted (run id " + f"{w_id})" in n for n in waiting["notes"])
    assert waiting["sections"] and {s["d2_level"] for s in waiting["sections"]} == {"quality"}
    assert waiting["d2_band_m"] == [25.0, 40.0] and waiting["d2_waiting_runs"] == [w_id]
    csv = c.get("/api/v1/tracks/W/quality.csv").text
    assert csv.startswith(f"# D2 leaves out run id {w_id}:")

    with ctx.db.session() as s:
        # a level inverted for an earlier result of the run is not stored
        assert processed_at is not None
        grid = np.arange(0.0, 400.0, 0.25)
        earlier = processed_at - timedelta(seconds=1)
        assert not store_long_level(s, w_id, earlier, grid, np.zeros(grid.size))
        # a realignment while it waits keeps the mark
        track_id = s.scalar(select(Track.id).where(Track.name == "W"))
        realign_track(s, track_id)
        s.commit()
    assert _long(ctx, w_id) == {}

    monkeypatch.undo()
    w = Worker(ctx)
    assert w.job(LongLevelJob).look() is False  # still the storing worker's, for a while
    monkeypatch.setattr(long_level_job, "LONG_LEVEL_GRACE_S", 0.0)
    assert w.run_once() is True  # an idle look inverts it from the stored log
    assert w.run_once() is False  # nothing waits any more
    with ctx.db.session() as s:
        assert s.scalar(select(Run.long_level_pending).where(Run.id == w_id)) is False

    # without a stop, the worker that stored the run stores its long level next
    l_id = _upload(c, long_run, "L", 202)
    assert w.run_once() is True
    assert _long(ctx, l_id)
    assert w.job(LongLevelJob).look() is False

    inline = start_app()  # same database; short runs processed in the request
    i_id = _upload(inline, long_run, "I", 201)
    _same_long(_long(ctx, w_id), _long(ctx, i_id))
    _same_long(_long(ctx, l_id), _long(ctx, i_id))
    want = _quality(inline, "I")
    assert {s["d2_level"] for s in want["sections"]} == {"long"}
    for name in ("W", "L"):
        got = _quality(c, name)
        assert not any("still being inverted" in n for n in got["notes"])
        assert got["d2_waiting_runs"] == []
        assert [s["d2_level"] for s in got["sections"]] == [s["d2_level"] for s in want["sections"]]
        for a, b in zip(got["sections"], want["sections"], strict=True):
            assert a["d2_sd_mm"] == pytest.approx(b["d2_sd_mm"], abs=0.002)


def test_runs_without_a_long_level_answer_d2_from_the_quality_level_flagged(
    start_app, long_run
) -> None:
    """Runs stored before the long level was kept (``long_mm`` NULL): every section says
    ``d2_level: "quality"``, ``d2_band_m`` is the 40 m level's [25, 40] and a note says why;
    their D2 is the 40 m level's, smaller than the long level's over these 25-70 m waves."""
    c = start_app()
    _upload(c, long_run, "old", 201)
    ctx = c.app.state.ctx
    with ctx.db.session() as s:
        track = s.scalar(select(Track).where(Track.name == "old"))
        assert track is not None
        kept = track_quality(s, track)
        assert kept["d2_band_m"] == [25.0, 70.0]
        assert kept["sections"] and {x["d2_level"] for x in kept["sections"]} == {"long"}
        s.execute(update(TrackRunLevels).values(long_mm=None))
        old = track_quality(s, track)
    assert {x["d2_level"] for x in old["sections"]} == {"quality"}
    assert old["d2_band_m"] == [25.0, 40.0]
    assert any("were stored before their 100 m level was kept" in n for n in old["notes"])
    assert not any("still being inverted" in n for n in old["notes"])
    pairs = zip(kept["sections"], old["sections"], strict=True)
    d2 = [(a["d2_sd_mm"], b["d2_sd_mm"]) for a, b in pairs if a["d2_sd_mm"] is not None]
    assert d2 and all(b < a for a, b in d2)
