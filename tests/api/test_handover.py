"""A queued upload is prepared (checked) once and handed to this process's worker in memory as
a PreparedRun; other processes' workers and reprocessing read the stored log and prepare it
again."""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import replace

import pytest

import app.services.run_lifecycle.accept as accept_mod
import app.services.run_lifecycle.inversion as inversion_mod
import app.services.run_lifecycle.processing as processing_mod
import engine.plausibility as plausibility_mod
import engine.setup as setup_mod
from api.api_support import row_counts, upload, wait_done
from app.services.run_lifecycle.handover import Handover
from app.services.run_lifecycle.jobs.process import HANDOVER_GRACE_S
from app.services.run_lifecycle.logs import pack_log
from app.services.run_lifecycle.queue import Worker
from engine.runlog import RunLog
from engine.setup import PreparedRun, RunSetup, prepare_run
from engine.vehicle import TABLE1


@pytest.fixture
def calls(monkeypatch) -> Counter:
    """Counts of prepare_run (pre-flight and worker), of full plausibility checks (not the
    CSV reader's own column checks) and of stored logs unpacked by the worker."""
    seen: Counter = Counter()

    def spy(name, real):
        def wrapped(*args, **kwargs):
            seen[name] += 1
            return real(*args, **kwargs)

        return wrapped

    prepare = spy("prepare_run", setup_mod.prepare_run)
    for module in (setup_mod, accept_mod, inversion_mod):
        monkeypatch.setattr(module, "prepare_run", prepare)
    monkeypatch.setattr(
        plausibility_mod, "check_time_steps", spy("plausible", plausibility_mod.check_time_steps)
    )
    monkeypatch.setattr(inversion_mod, "unpack_log", spy("unpack", inversion_mod.unpack_log))
    return seen


def _queue(c, synthetic_run, **fields) -> int:
    r = upload(c, synthetic_run["csv"], track="T",
               start_chainage_m=synthetic_run["start_chainage_m"], **fields)  # fmt: skip
    assert r.status_code == 202, r.text
    return int(r.json()["id"])


def test_queued_upload_is_checked_once_and_reprocessing_checks_again(
    start_app, settings, synthetic_run, calls
) -> None:
    """One pre-flight check per upload: the CSV reader's column checks stand for the
    plausibility check, the worker takes the parsed log and its check from memory (nothing
    unpacked) while the input is stored all the same; a new vehicle version reprocesses the
    stored log and checks it again."""
    c = start_app(inline_max_samples=0)
    r = c.post("/api/v1/vehicles", json={"name": "coach", "params": TABLE1.to_dict()})
    assert r.status_code == 201, r.text
    run_id = _queue(c, synthetic_run, vehicle="coach")
    assert wait_done(c, run_id)["status"] == "done"
    assert calls == {"prepare_run": 1}
    assert row_counts(settings)["run_inputs"] == 1
    assert len(c.app.state.ctx.handover) == 0

    r = c.patch("/api/v1/vehicles/coach", json={"params": {"ms": 17000.0}})
    assert r.status_code == 200, r.text
    deadline = time.monotonic() + 60
    while (run := c.get(f"/api/v1/runs/{run_id}").json())["vehicle_version"] != 2:
        assert time.monotonic() < deadline, run
        time.sleep(0.05)
    assert run["status"] == "done"
    assert calls == {"prepare_run": 2, "plausible": 1, "unpack": 1}


def test_short_upload_processed_inline_is_checked_once(start_app, synthetic_run, calls) -> None:
    c = start_app()
    r = upload(c, synthetic_run["csv"], track="T",
               start_chainage_m=synthetic_run["start_chainage_m"])  # fmt: skip
    assert r.status_code == 201, r.text
    assert calls == {"prepare_run": 1}


def test_json_columns_are_checked_once(start_app, synthetic_run, calls) -> None:
    """Arrays sent as JSON have no reader's column checks: the pre-flight's plausibility check
    runs, once; the worker does not repeat it."""
    from engine.logio import read_run_csv

    log = read_run_csv(synthetic_run["csv"])
    columns = {k: getattr(log, k).tolist() for k in ("time_s", "accel_z_mps2",
                                                     "pitch_rate_radps", "speed_mps")}  # fmt: skip
    c = start_app(inline_max_samples=0)
    calls.clear()
    start = synthetic_run["start_chainage_m"]
    r = c.post("/api/v1/runs", json={"track": "T", "columns": columns, "start_chainage_m": start})
    assert r.status_code == 202, r.text
    assert wait_done(c, r.json()["id"])["status"] == "done"
    assert calls == {"prepare_run": 1, "plausible": 1}


def test_another_process_processes_from_the_stored_input(start_app, synthetic_run, calls) -> None:
    """Queued by a process without a worker (nothing held in memory), the run is processed by
    another app process from its stored input, checked there."""
    c = start_app(inline_max_samples=0, start_worker=False)
    assert c.app.state.ctx.handover is None
    run_id = _queue(c, synthetic_run)
    other = start_app(inline_max_samples=0)
    assert wait_done(other, run_id)["status"] == "done"
    assert calls == {"prepare_run": 2, "plausible": 1, "unpack": 1}


def _check(log: RunLog) -> PreparedRun:
    return prepare_run(log, RunSetup(start_chainage_m=12.0))


def _small_log() -> RunLog:
    import numpy as np

    t = np.arange(20_000) / 1000.0
    return RunLog(time_s=t, accel_z_mps2=np.zeros_like(t), pitch_rate_radps=np.zeros_like(t),
                  speed_mps=np.full_like(t, 20.0))  # fmt: skip


def test_handover_is_bounded_and_taken_once(monkeypatch) -> None:
    log = _small_log()
    chk = _check(log)
    h = Handover(capacity=2, ttl_s=60.0)
    for run_id in (1, 2, 3):
        h.put(run_id, chk)
    assert len(h) == 2
    assert h.take(1) is None  # pushed out by newer ones
    handed = h.take(3)
    assert handed is not None and handed.prepared is chk and handed.inversion is None
    assert h.take(3) is None and len(h) == 1
    h.put(4, chk)
    now = time.monotonic()
    monkeypatch.setattr(time, "monotonic", lambda: now + 61.0)
    assert h.take(4) is None and h.take(2) is None  # waited too long


def test_a_started_inversion_serves_only_its_set_up(synthetic_run) -> None:
    """The worker takes the upload's started inversion only for the set-up it was prepared
    with (the run's set-up when claimed); another set-up is prepared again from the handed
    log."""
    from concurrent.futures import Future

    from app.services.run_lifecycle.handover import Handed

    log = _small_log()
    chk = _check(log)
    handed = Handed(chk, time.monotonic(), Future())
    assert handed.started_for(RunSetup(start_chainage_m=12.0)) is handed.inversion
    assert handed.started_for(RunSetup(start_chainage_m=13.0)) is None
    heavier = RunSetup(start_chainage_m=12.0, vehicle=replace(TABLE1, ms=17000.0))
    assert handed.started_for(heavier) is None
    assert handed.prepared.with_setup(heavier).setup == heavier


def test_logs_of_runs_claimed_elsewhere_are_freed_when_the_worker_finds_nothing(
    start_app, monkeypatch
) -> None:
    """A held log whose run this worker cannot claim (another process has it, or it is gone)
    is dropped at the worker's next look that finds nothing to claim, once older than the
    grace; a newer one (a run another thread of this process is about to take) stays."""
    c = start_app(inline_max_samples=0)
    ctx = c.app.state.ctx
    worker = c.app.state.worker
    log = _small_log()
    chk = _check(log)
    ctx.handover.put(10_001, chk)  # no such queued run here
    assert worker.run_once() is False and len(ctx.handover) == 1  # within the grace
    now = time.monotonic()
    monkeypatch.setattr(time, "monotonic", lambda: now + HANDOVER_GRACE_S + 1)
    ctx.handover.put(10_002, chk)
    assert worker.run_once() is False
    assert ctx.handover.take(10_001) is None and ctx.handover.take(10_002) is not None


@pytest.fixture
def inversions(monkeypatch) -> list[tuple[str, float]]:
    """Every engine inversion (``process_run``) of a stored run: the thread it ran on and the
    vehicle body mass it used, kg."""
    seen: list[tuple[str, float]] = []
    real = processing_mod.process_run

    def spy(run, **kwargs):
        import threading

        seen.append((threading.current_thread().name, run.setup.vehicle.ms))
        return real(run, **kwargs)

    monkeypatch.setattr(processing_mod, "process_run", spy)
    return seen


def test_queued_upload_is_inverted_while_its_input_is_stored(
    start_app, synthetic_run, inversions
) -> None:
    """The upload starts the inversion as soon as the log is checked (on a thread of its own,
    beside the storing of the input); the worker that claims the run takes that result
    instead of inverting the log a second time."""
    c = start_app(inline_max_samples=0)
    run_id = _queue(c, synthetic_run)
    run = wait_done(c, run_id)
    assert run["status"] == "done" and run["n_soft_spots"] >= 1
    assert [name for name, _ in inversions] == ["early-inversion"]
    assert len(c.app.state.ctx.handover) == 0


def test_a_started_inversion_is_not_used_when_the_vehicle_changed_meanwhile(
    start_app, synthetic_run, inversions
) -> None:
    """A vehicle version registered between the upload and the claim: the worker inverts
    again with the new parameters and stores that result, not the started one."""
    c = start_app(inline_max_samples=0, start_worker=False)
    ctx = c.app.state.ctx
    ctx.handover = Handover()  # as the worker's start sets it, without its threads
    r = c.post("/api/v1/vehicles", json={"name": "coach", "params": TABLE1.to_dict()})
    assert r.status_code == 201, r.text
    run_id = _queue(c, synthetic_run, vehicle="coach")
    r = c.patch("/api/v1/vehicles/coach", json={"params": {"ms": 17000.0}})
    assert r.status_code == 200, r.text
    assert Worker(ctx).run_once() is True
    run = c.get(f"/api/v1/runs/{run_id}").json()
    assert run["status"] == "done" and run["vehicle_version"] == 2
    assert inversions == [("early-inversion", TABLE1.ms), ("MainThread", 17000.0)]


def test_a_submission_failing_after_the_start_leaves_no_slot_taken(
    start_app, settings, synthetic_run, monkeypatch, inversions
) -> None:
    """The request fails after it started the inversion (here: packing the input breaks):
    nothing is stored, nothing is handed over, and the slot the inversion held is free again
    once it ends (the next upload starts its own)."""

    def broken_pack(_log):
        raise RuntimeError("packing failed (test)")

    c = start_app(inline_max_samples=0)
    ctx = c.app.state.ctx
    monkeypatch.setattr(accept_mod, "pack_log", broken_pack)
    r = upload(c, synthetic_run["csv"], track="T",
               start_chainage_m=synthetic_run["start_chainage_m"])  # fmt: skip
    assert r.status_code == 500, r.text
    assert row_counts(settings)["runs"] == 0 and len(ctx.handover) == 0
    assert ctx.slots.acquire(timeout=60)  # the started inversion ended and let it go
    ctx.slots.release()
    monkeypatch.setattr(accept_mod, "pack_log", pack_log)
    run_id = _queue(c, synthetic_run)
    assert wait_done(c, run_id)["status"] == "done"
    assert [name for name, _ in inversions] == ["early-inversion", "early-inversion"]
