"""Background processing: queued runs, several workers, crashes, failures and deletes."""

from __future__ import annotations

import subprocess
import sys
import threading
from datetime import UTC, datetime

import pytest
from starlette.testclient import TestClient

from api.api_support import assert_zones_match, row_counts, sql, stored_points, upload, wait_done
from app.services.run_lifecycle.jobs import RUNS
from app.services.run_lifecycle.queue import Worker


def _queue(c: TestClient, synthetic_run, *, may_finish: bool = False, **fields) -> dict:
    """Upload over the inline limit: answered 202 'processing'. With ``may_finish`` the
    worker may already have ended the run before the answer is read (an inversion that fails
    at once): then 201 with the run's final status, never 202 with a final one."""
    r = upload(c, synthetic_run["csv"], track="T",
               start_chainage_m=synthetic_run["start_chainage_m"], **fields)  # fmt: skip
    processing = r.json().get("status") == "processing"
    assert r.status_code == (202 if processing else 201), r.text
    assert processing or may_finish, r.text
    return r.json()


def _now() -> datetime:
    return datetime.now(UTC).replace(tzinfo=None)


def test_long_log_is_processed_in_the_background(start_app, settings, synthetic_run) -> None:
    """A log over the inline limit is answered 202 'processing' and finished by the worker;
    its log stays stored (reprocessing, calibration)."""
    c = start_app(inline_max_samples=0)
    run = _queue(c, synthetic_run)
    assert run["status"] == "processing"
    assert run["stage"] in ("queued", "inverting", "storing")
    assert 0 < run["progress"] < 1
    done = wait_done(c, run["id"])
    assert done["status"] == "done", done
    assert done["progress"] == 1
    assert done["stage"] is None
    assert_zones_match(c.get(f"/api/v1/runs/{run['id']}/soft-spots").json(), synthetic_run["zones"])
    # the log stays stored: a new vehicle version reprocesses it, calibration reads it
    assert row_counts(settings)["run_inputs"] == 1


def test_queued_run_waits_for_a_worker_and_has_no_results_yet(start_app, synthetic_run):
    """Without a worker the run stays queued; its profile is 409 until another app process
    (sharing the database) picks it up."""
    c = start_app(inline_max_samples=0, start_worker=False)
    run = _queue(c, synthetic_run)
    for path in ("profile", "soft-spots"):
        r = c.get(f"/api/v1/runs/{run['id']}/{path}")
        assert r.status_code == 409
        assert "processing" in r.json()["detail"]["message"]
    assert c.get(f"/api/v1/runs/{run['id']}/signals").status_code == 200  # known at upload
    assert c.get("/healthz").json()["runs_processing"] == 1
    other = start_app(inline_max_samples=0)
    assert wait_done(other, run["id"])["status"] == "done"
    assert c.get(f"/api/v1/runs/{run['id']}/profile").status_code == 200


def test_wait_parameter_returns_the_result(start_app, synthetic_run) -> None:
    """?wait=true holds the answer until the worker is done: 201 with the final run."""
    c = start_app(inline_max_samples=0)
    start = synthetic_run["start_chainage_m"]
    r = upload(c, synthetic_run["csv"], track="T", start_chainage_m=start, params={"wait": "true"})
    assert r.status_code == 201, r.text
    assert r.json()["status"] == "done"


def _dead_pid() -> int:
    p = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                       capture_output=True, text=True, check=True)  # fmt: skip
    return int(p.stdout)


def test_run_interrupted_by_a_crash_is_resumed_at_start(start_app, settings, synthetic_run):
    """A run left claimed by a process that died (same host) is resumed when the service
    starts again, from its stored input, without waiting for the lease to expire."""
    import socket

    c = start_app(inline_max_samples=0, start_worker=False)
    run = _queue(c, synthetic_run)
    owner = f"{socket.gethostname()}:{_dead_pid()}:deadbeef"
    sql(settings, "UPDATE runs SET claimed_by=:owner, heartbeat_at=:now, attempts=1, "
        "stage='inverting' WHERE id=:id", owner=owner, now=_now(), id=run["id"])  # fmt: skip
    restarted = start_app(inline_max_samples=0, lease_s=3600)
    done = wait_done(restarted, run["id"])
    assert done["status"] == "done", done
    assert sum(stored_points(settings).values()) > 0
    assert sql(settings, "SELECT attempts FROM runs WHERE id=:id", id=run["id"]) == [(2,)]


def test_claim_of_another_host_is_taken_over_after_its_lease(start_app, settings, synthetic_run):
    """A run claimed by a worker elsewhere that stopped sending heartbeats is taken over once
    its lease is older than lease_s."""
    c = start_app(inline_max_samples=0, start_worker=False)
    run = _queue(c, synthetic_run)
    sql(settings, "UPDATE runs SET claimed_by='elsewhere:1:abc', heartbeat_at=:now "
        "WHERE id=:id", now=_now(), id=run["id"])  # fmt: skip
    other = start_app(inline_max_samples=0, lease_s=1.0)
    assert wait_done(other, run["id"], timeout=30)["status"] == "done"


def test_live_claim_is_not_taken(start_app, settings, synthetic_run) -> None:
    """A claim with a fresh heartbeat belongs to a live worker: nobody else takes the run."""
    c = start_app(inline_max_samples=0, start_worker=False)
    run = _queue(c, synthetic_run)
    sql(settings, "UPDATE runs SET claimed_by='elsewhere:1:abc', heartbeat_at=:now "
        "WHERE id=:id", now=_now(), id=run["id"])  # fmt: skip
    w = Worker(c.app.state.ctx)
    assert w.claim(RUNS) is None


def test_run_interrupted_too_often_is_failed(start_app, settings, synthetic_run) -> None:
    """After max_attempts interruptions the run is marked failed with the reason, and its
    stored input is removed."""
    c = start_app(inline_max_samples=0, start_worker=False)
    run = _queue(c, synthetic_run)
    sql(settings, "UPDATE runs SET attempts=3 WHERE id=:id", id=run["id"])
    other = start_app(inline_max_samples=0, max_attempts=3)
    failed = wait_done(other, run["id"])
    assert failed["status"] == "failed"
    assert failed["error"]["kind"] == "Interrupted"
    assert "interrupted 3 times" in failed["error"]["message"]
    assert row_counts(settings)["run_inputs"] == 0


def test_log_that_cannot_be_inverted_is_refused_before_it_is_queued(start_app, settings) -> None:
    """A log over the inline limit that the engine's pre-flight (prepare_run) rejects (speed
    below 1 m/s) is answered 422 at once, naming the speed, instead of being queued to fail
    later; nothing is stored."""
    rows = "\n".join(f"{i / 1000:.3f},0.0,0.0,0.8" for i in range(3000))
    data = f"time_s,accel_z_mps2,pitch_rate_radps,speed_mps\n{rows}\n".encode()
    c = start_app(inline_max_samples=0)
    before = row_counts(settings)
    r = upload(c, data, track="T", start_chainage_m=10)
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert detail["kind"] == "InversionError"
    assert "0.80 m/s" in detail["message"] and "1.0 m/s" in detail["message"]
    assert row_counts(settings) == before


def test_engine_error_in_the_background_marks_the_run_failed(
    start_app, settings, synthetic_run, monkeypatch
) -> None:
    """An engine error that only the inversion finds ends the queued run as 'failed' with the
    engine's message and no stored input or profile; resending the file replaces the failed
    run."""
    import app.services.run_lifecycle.processing as processing_mod
    from engine.errors import InversionError

    def failing_inversion(*_args, **_kwargs):
        raise InversionError("the profile band has no energy (test)")

    # the engine call behind every inversion: the one the upload starts, the worker's own
    monkeypatch.setattr(processing_mod, "process_run", failing_inversion)
    c = start_app(inline_max_samples=0)
    failed = wait_done(c, _queue(c, synthetic_run, may_finish=True)["id"])
    assert failed["status"] == "failed"
    assert failed["error"]["kind"] == "InversionError"
    assert failed["error"]["message"] == "the profile band has no energy (test)"
    assert c.get(f"/api/v1/runs/{failed['id']}/profile").status_code == 409
    counts = row_counts(settings)
    assert counts["run_inputs"] == counts["run_profile_blocks"] == counts["soft_spots"] == 0
    monkeypatch.undo()
    again = _queue(c, synthetic_run)
    assert again["id"] != failed["id"]
    assert wait_done(c, again["id"])["status"] == "done"
    assert c.get(f"/api/v1/runs/{failed['id']}").status_code == 404


def test_missing_input_fails_cleanly(start_app, settings, synthetic_run) -> None:
    """A queued run whose stored input has vanished is failed with a clear message."""
    c = start_app(inline_max_samples=0, start_worker=False)
    run = _queue(c, synthetic_run)
    sql(settings, "DELETE FROM run_inputs WHERE run_id=:id", id=run["id"])
    w = Worker(c.app.state.ctx)
    assert w.run_once() is True
    r = c.get(f"/api/v1/runs/{run['id']}").json()
    assert r["status"] == "failed"
    assert "input is missing" in r["error"]["message"]


def test_each_run_is_claimed_by_exactly_one_worker(start_app, synthetic_run) -> None:
    """Workers racing for queued runs (as several processes would) never share a run."""
    c = start_app(inline_max_samples=0, start_worker=False)
    ids = set()
    for k in range(4):
        ids.add(_queue(c, {**synthetic_run, "csv": synthetic_run["csv"] + b"\n" * k})["id"])
    ctx = c.app.state.ctx
    workers = [Worker(ctx) for _ in range(4)]
    claims: list[tuple[str, int]] = []
    lock = threading.Lock()

    def grab(w: Worker) -> None:
        while (rid := w.claim(RUNS)) is not None:
            with lock:
                claims.append((w.id, rid))

    threads = [threading.Thread(target=grab, args=(w,)) for w in workers]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    claimed = [rid for _, rid in claims]
    assert sorted(claimed) == sorted(ids)  # every run once, none twice


def test_run_deleted_while_processing_leaves_nothing(start_app, settings, synthetic_run,
                                                     monkeypatch) -> None:  # fmt: skip
    """If the run is deleted while the engine works on it, the result is dropped: no orphan
    profile rows, no error."""
    import app.services.run_lifecycle.inversion as inversion_mod

    c = start_app(inline_max_samples=0, start_worker=False)
    run = _queue(c, synthetic_run)
    real_invert = inversion_mod.invert

    def invert_then_delete(*args, **kwargs):
        result = real_invert(*args, **kwargs)
        assert c.delete(f"/api/v1/runs/{run['id']}").status_code == 204
        return result

    monkeypatch.setattr(inversion_mod, "invert", invert_then_delete)
    w = Worker(c.app.state.ctx)
    assert w.run_once() is True
    counts = row_counts(settings)
    assert counts["runs"] == counts["run_profile_blocks"] == counts["soft_spots"] == 0
    assert counts["run_inputs"] == counts["run_signals"] == 0


@pytest.mark.parametrize("n", [2])
def test_parallel_uploads_and_reads(start_app, synthetic_run, n) -> None:
    """Uploads and reads in parallel threads all succeed (no 5xx, no lost run)."""
    c = start_app(inline_max_samples=0, workers=2)
    results: list[int] = []
    errors: list[str] = []

    def work(k: int) -> None:
        r = upload(c, synthetic_run["csv"] + b"\n" * (k + 1), track=f"T{k % 2}",
                   start_chainage_m=synthetic_run["start_chainage_m"])  # fmt: skip
        if r.status_code != 202:
            errors.append(r.text)
            return
        for _ in range(3):
            g = c.get("/api/v1/runs")
            if g.status_code != 200:
                errors.append(g.text)
        results.append(r.json()["id"])

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4 * n)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert len(set(results)) == 4 * n
    for rid in results:
        assert wait_done(c, rid)["status"] == "done"
