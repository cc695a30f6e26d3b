"""Retention (issue 15): a run's detail expires, what the track learned from it stays.

Detail = the run's profile, signals and stored log; kept for ever = the run's metadata and
soft spots, its aligned level (the aggregate's input), the aggregate, the register and the
separation. The sweep removes detail one run per transaction; readers get all of a run's
detail or 410, never an error or part of it.
"""

from __future__ import annotations

import threading
from typing import Any

import pytest
from starlette.testclient import TestClient

from api.api_support import row_counts, sql, stored_points, upload
from app.services.run_lifecycle.jobs import SweepJob
from app.services.run_lifecycle.queue import Worker
from app.services.storage.retention import RetentionPolicy, sweep

OLD = "2020-03-01T08:00:00Z"
NEW = "2026-11-20T08:00:00Z"
STARTS = (12.0, 12.5, 13.0)  # m: three distinct runs of the same stretch


def _runs(client: TestClient, csv: bytes, recorded: list[str]) -> list[int]:
    ids = []
    for i, (start, when) in enumerate(zip(STARTS, recorded, strict=False)):
        # distinct logs (a trailing blank line each): the same bytes again are the stored run
        r = upload(client, csv + b"\n" * i, track="R", start_chainage_m=start, recorded_at=when)
        assert r.status_code == 201, r.text
        assert r.json()["status"] == "done"
        ids.append(r.json()["id"])
    return ids


def _kept_views(client: TestClient, ids: list[int]) -> dict[str, Any]:
    """Everything that must survive expiry, as the API serves it."""
    out: dict[str, Any] = {}
    for rid in ids:
        run = client.get(f"/api/v1/runs/{rid}").json()
        run.pop("detail_expired_at", None)
        out[f"run {rid}"] = run
        out[f"spots {rid}"] = client.get(f"/api/v1/runs/{rid}/soft-spots").json()
    for path in ("profile", "defects", "alerts?since=2019-01-01T00:00:00Z", "stiffness"):
        r = client.get(f"/api/v1/tracks/R/{path}")
        assert r.status_code == 200, (path, r.text)
        out[path] = r.json()
    return out


@pytest.fixture()
def expired(start_app, synthetic_run) -> tuple[TestClient, list[int], dict[str, Any]]:
    """Three runs of one track, the first recorded long ago; detail older than 30 days swept."""
    client = start_app(detail_retention_days=30, start_worker=False)
    ids = _runs(client, synthetic_run["csv"], [OLD, NEW, NEW])
    before = _kept_views(client, ids)
    policy = RetentionPolicy.from_settings(client.app.state.ctx.settings)
    result = sweep(client.app.state.ctx.db, policy)
    assert (result.expired_runs, result.dropped_logs) == (1, 0)
    assert sweep(client.app.state.ctx.db, policy).removed == 0  # nothing left to do
    return client, ids, before


def test_expired_detail_is_gone_and_answers_410(expired, settings) -> None:
    """The old run's profile, signals and log are removed; its detail routes say so (410,
    naming the run and the policy); the other runs keep theirs."""
    client, (old, new, _), _ = expired
    points = stored_points(settings)
    assert old not in points and points[new] > 400
    for table in ("run_signals", "run_inputs"):
        rows = sql(settings, f"SELECT run_id FROM {table}")
        assert (old,) not in rows and (new,) in rows, table
    for path in (
        f"/api/v1/runs/{old}/profile",
        f"/api/v1/runs/{old}/profile?format=csv",
        f"/api/v1/runs/{old}/signals",
        f"/api/v1/views/runs/{old}/profile",
    ):
        r = client.get(path)
        assert r.status_code == 410, (path, r.status_code, r.text)
        detail = r.json()["detail"]
        assert f"run {old}'s" in detail["message"] and "expired" in detail["message"], detail
        assert detail["expired_at"].startswith("20"), detail
    run = client.get(f"/api/v1/runs/{old}").json()
    assert run["detail_expired_at"] is not None
    assert client.get(f"/api/v1/runs/{new}").json()["detail_expired_at"] is None
    assert client.get(f"/api/v1/runs/{new}/profile").status_code == 200
    assert client.get(f"/api/v1/runs/{new}/signals").status_code == 200


def test_kept_things_are_served_unchanged(expired) -> None:
    """Metadata, soft spots, the aggregate, the register, alerts and the separation read the
    same after the sweep; the aggregate is still what every run (the expired one too) makes,
    also when a new run arrives and the aggregate there is recomputed."""
    client, ids, before = expired
    assert _kept_views(client, ids) == before
    # the expired run is still one of the runs the aggregate is the median of
    assert max(before["profile"]["n_runs"]) == 3
    ctx = client.app.state.ctx
    from app.services.track.consistency import check_aggregate

    with ctx.db.session() as s:
        track_id = client.get("/api/v1/tracks/R").json()["id"]
        assert check_aggregate(s, track_id).ok


def test_new_run_after_expiry_keeps_the_expired_runs_share(start_app, synthetic_run) -> None:
    """A run stored after another's detail expired is aggregated with it: the aggregate over
    the stretch counts all runs, as if nothing had expired."""
    client = start_app(detail_retention_days=30, start_worker=False)
    ids = _runs(client, synthetic_run["csv"], [OLD, NEW])
    sweep(client.app.state.ctx.db, RetentionPolicy.from_settings(client.app.state.ctx.settings))
    assert client.get(f"/api/v1/runs/{ids[0]}/profile").status_code == 410
    # a third log (a trailing blank line): the same bytes again would be a stored run
    r = upload(client, synthetic_run["csv"] + b"\n" * 2, track="R", start_chainage_m=STARTS[2],
               recorded_at=NEW)  # fmt: skip
    assert r.json()["status"] == "done", r.text
    agg = client.get("/api/v1/tracks/R/profile").json()
    assert max(agg["n_runs"]) == 3


def test_count_policy_and_log_retention(start_app, synthetic_run, settings) -> None:
    """``detail_retention_runs`` keeps the newest runs of each track; ``log_retention_runs``
    removes the log of older runs but keeps their profile. The worker sweeps on its own."""
    client = start_app(
        detail_retention_runs=2, log_retention_runs=1, start_worker=False, retention_interval_s=3600
    )
    ids = _runs(client, synthetic_run["csv"], [OLD, NEW, "2026-11-25T08:00:00Z"])
    worker = Worker(client.app.state.ctx)
    assert worker.job(SweepJob).look() is True
    assert worker.job(SweepJob).look() is False  # not due again for an hour
    assert client.get(f"/api/v1/runs/{ids[0]}/profile").status_code == 410
    assert client.get(f"/api/v1/runs/{ids[1]}/profile").status_code == 200
    assert client.get(f"/api/v1/runs/{ids[2]}/profile").status_code == 200
    logs = {r[0] for r in sql(settings, "SELECT run_id FROM run_inputs")}
    assert logs == {ids[2]}  # the newest run of the vehicle only


def test_reads_during_the_sweep_never_fail(start_app, synthetic_run) -> None:
    """Readers hammer the runs' profiles and signals while the sweep removes them one by one:
    every answer is the whole detail (200, every point) or 410, never an error or a part."""
    client = start_app(detail_retention_days=30, start_worker=False)
    ids = []
    for k in range(4):
        # four logs (trailing blank lines): the same bytes again would be the stored run
        r = upload(client, synthetic_run["csv"] + b"\n" * k, track="R",
                   start_chainage_m=12.0 + 0.25 * k, recorded_at=OLD)  # fmt: skip
        ids.append(r.json()["id"])
    full = {rid: client.get(f"/api/v1/runs/{rid}/profile").json()["n"] for rid in ids}
    answers: list[tuple[int, int]] = []
    stop = threading.Event()
    errors: list[str] = []

    def read() -> None:
        with TestClient(client.app) as c:
            k = 0
            while not stop.is_set():
                rid = ids[k % len(ids)]
                k += 1
                for path in ("profile", "signals"):
                    r = c.get(f"/api/v1/runs/{rid}/{path}")
                    answers.append((rid, r.status_code))
                    if r.status_code == 200 and path == "profile" and r.json()["n"] != full[rid]:
                        errors.append(f"run {rid}: {r.json()['n']} of {full[rid]} points")
                    elif r.status_code not in (200, 410):
                        errors.append(f"run {rid} {path}: {r.status_code} {r.text[:200]}")

    readers = [threading.Thread(target=read) for _ in range(3)]
    for t in readers:
        t.start()

    def wait_for_more_answers(n: int = 12) -> None:
        seen = len(answers)
        while len(answers) < seen + n and not errors:
            stop.wait(0.01)

    try:
        wait_for_more_answers()
        ctx = client.app.state.ctx
        policy = RetentionPolicy.from_settings(ctx.settings)
        total = 0
        while True:
            n = sweep(ctx.db, policy).expired_runs
            total += n
            if n == 0:
                break
        wait_for_more_answers()
    finally:
        stop.set()
        for t in readers:
            t.join()
    assert total == len(ids)
    assert not errors, errors[:5]
    codes = {code for _, code in answers}
    assert 200 in codes and 410 in codes, codes
    assert row_counts(client.app.state.ctx.settings)["run_profile_blocks"] == 0
