"""Crash safety with a real server process: SIGKILL while a run is processed, then restart.

A run is either fully stored or not at all: its profile, soft spots and "done" are written in
one transaction, so a process killed at any moment leaves the run 'processing' with no profile
rows and its input kept (then a restart resumes it), or 'done' with every row — never half a
profile. After too many interruptions the run is marked failed with the reason.
"""

from __future__ import annotations

import io
import time
from typing import Any

import httpx
import numpy as np
import pytest

from api.api_support import row_counts, sql, stored_points
from api.live_server import LiveServer, wait_status
from engine.logio import read_run_csv
from engine.pipeline import process_run
from engine.setup import RunSetup, prepare_run

N_SAMPLES = 600_000
"""10 minutes at 1 kHz, 15 km at 25 m/s: ~60 000 profile rows, long enough to kill mid-run."""

START_M = 12.0
QUEUED = {
    "TRACKPROFILE_INLINE_MAX_SAMPLES": 1000,  # every log goes to the background worker
    "TRACKPROFILE_LEASE_S": 5,  # a claim orphaned by a reused pid is taken over soon anyway
}


@pytest.fixture(scope="module")
def long_log() -> dict[str, Any]:
    """A 600 000-sample log (random body motion with two dips) and what the engine makes of
    it: the number of profile grid points and of soft spots a complete result has."""
    rng = np.random.default_rng(7)
    t = np.arange(N_SAMPLES) / 1000.0
    x = START_M + 25.0 * t
    accel = 0.02 * rng.standard_normal(N_SAMPLES)
    for x0 in (3000.0, 9000.0):  # two soft dips the inversion picks up
        accel += 0.4 * np.exp(-(((x - x0) / 3.0) ** 2)) * np.sin((x - x0) / 1.5)
    pitch = 2e-4 * rng.standard_normal(N_SAMPLES)
    buf = io.StringIO()
    buf.write("time_s,accel_z_mps2,pitch_rate_radps,speed_mps\n")
    np.savetxt(buf, np.column_stack([t, accel, pitch, np.full(N_SAMPLES, 25.0)]),
               fmt=["%.3f", "%.6f", "%.7f", "%.1f"], delimiter=",")  # fmt: skip
    data = buf.getvalue().encode()
    result = process_run(prepare_run(read_run_csv(data), RunSetup(start_chainage_m=START_M)))
    return {
        "csv": data,
        "n_points": int(result.chainage_m.size),
        "n_spots": len(result.soft_spots),
    }


def _upload(c: httpx.Client, data: bytes, key: str = "crash-1") -> httpx.Response:
    return c.post(
        "/api/v1/runs",
        files={"file": ("long.csv", data, "text/csv")},
        data={"track": "crash", "start_chainage_m": str(START_M)},
        headers={"Idempotency-Key": key},
    )


def _send(url: str, data: bytes, key: str) -> None:
    """Upload, not minding that the server may die under the request."""
    try:
        with httpx.Client(base_url=url, timeout=120) as c:
            _upload(c, data, key=key)
    except httpx.HTTPError:
        pass


def _wait_processing(c: httpx.Client, run_id: int, timeout: float = 60.0) -> float:
    """Poll until a worker has the run (stage inverting or storing); the time it was seen."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        run = c.get(f"/api/v1/runs/{run_id}").json()
        if run["status"] != "processing" or run["stage"] in ("inverting", "storing"):
            return time.monotonic()
        time.sleep(0.01)
    raise AssertionError(f"run {run_id} was not picked up within {timeout} s")


def _stored(settings, run_id: int) -> dict[str, Any]:
    """The run's state and its rows, read from the database with the server dead."""
    [(status, attempts, error)] = sql(
        settings, "SELECT status, attempts, error FROM runs WHERE id=:id", id=run_id
    )
    count = {
        table: sql(settings, f"SELECT count(*) FROM {table} WHERE run_id=:id", id=run_id)[0][0]
        for table in ("soft_spots", "run_inputs")
    }
    count["profile_points"] = stored_points(settings).get(run_id, 0)
    return {"status": status, "attempts": attempts, "error": error, **count}


def _assert_whole_or_nothing(state: dict[str, Any], log: dict[str, Any]) -> None:
    if state["status"] == "done":
        assert state["profile_points"] == log["n_points"], state
        assert state["soft_spots"] == log["n_spots"], state
        assert state["run_inputs"] == 1, state  # kept for reprocessing and calibration
    else:
        assert state["profile_points"] == 0 and state["soft_spots"] == 0, state
        if state["status"] == "processing":
            assert state["run_inputs"] == 1, state  # kept for the resume


@pytest.mark.slow
@pytest.mark.dialect
def test_run_killed_mid_processing_is_resumed_whole(settings, long_log) -> None:
    """SIGKILL while the worker inverts a queued run leaves it 'processing' with no profile
    rows and its input kept; resending the file (same Idempotency-Key) to the restarted server
    adds nothing; the restart resumes the run (attempt 2) and stores the complete profile."""
    first = LiveServer(settings, "first", **QUEUED).start()
    try:
        with httpx.Client(base_url=first.url, timeout=120) as c:
            r = _upload(c, long_log["csv"])
            assert r.status_code == 202, r.text
            run_id = r.json()["id"]
            _wait_processing(c, run_id)
            first.kill()
    finally:
        first.kill()
    killed = _stored(settings, run_id)
    assert killed["status"] == "processing", "the run finished before the kill: use a longer log"
    _assert_whole_or_nothing(killed, long_log)
    before = row_counts(settings)

    second = LiveServer(settings, "second", **QUEUED).start()
    try:
        with httpx.Client(base_url=second.url, timeout=120) as c:
            again = _upload(c, long_log["csv"])
            assert again.status_code == 200, again.text
            assert again.json()["id"] == run_id and again.json()["duplicate"] is True
            done = wait_status(c, run_id, {"done", "failed"})
            assert done["status"] == "done", done
            assert done["n_soft_spots"] == long_log["n_spots"]
            assert c.get(f"/api/v1/runs/{run_id}/profile").json()["n"] == long_log["n_points"]
    finally:
        second.stop()
    state = _stored(settings, run_id)
    _assert_whole_or_nothing(state, long_log)
    assert state["attempts"] == 2
    assert (run_id, 2) in second.claims()
    after = row_counts(settings)
    assert after["runs"] == before["runs"] == 1  # the resend made no second run


@pytest.mark.slow
@pytest.mark.dialect
def test_kills_at_any_moment_leave_whole_runs_or_none(settings, long_log) -> None:
    """Killed at several moments across the processing window (measured first), the run is
    each time either still processing with no profile rows or done with all of them; the
    last restart finishes it."""
    measure = LiveServer(settings, "measure", **QUEUED).start()
    try:
        with httpx.Client(base_url=measure.url, timeout=120) as c:
            r = _upload(c, long_log["csv"], key="measure")
            seen = _wait_processing(c, r.json()["id"])
            wait_status(c, r.json()["id"], {"done", "failed"})
            window = time.monotonic() - seen
            assert c.delete(f"/api/v1/runs/{r.json()['id']}").status_code == 204
    finally:
        measure.stop()

    run_id = None
    outcomes = []
    # the window is measured once; where the machine's load falls after, the run is quicker
    # than measured, and only an early kill still lands inside it
    for k, fraction in enumerate((0.1, 0.3, 0.6, 0.85, 0.97)):
        server = LiveServer(settings, f"kill{k}", **QUEUED, TRACKPROFILE_MAX_ATTEMPTS=10).start()
        try:
            with httpx.Client(base_url=server.url, timeout=120) as c:
                if run_id is None:
                    r = _upload(c, long_log["csv"], key="sweep")
                    assert r.status_code == 202, r.text
                    run_id = r.json()["id"]
                seen = _wait_processing(c, run_id)
                time.sleep(max(0.0, fraction * window - (time.monotonic() - seen)))
                server.kill()
        finally:
            server.kill()
        state = _stored(settings, run_id)
        _assert_whole_or_nothing(state, long_log)
        outcomes.append(state["status"])
        if state["status"] == "done":
            break
    assert "processing" in outcomes  # at least one kill hit the run mid-way

    final = LiveServer(settings, "final", **QUEUED, TRACKPROFILE_MAX_ATTEMPTS=10).start()
    try:
        with httpx.Client(base_url=final.url, timeout=120) as c:
            assert wait_status(c, run_id, {"done", "failed"})["status"] == "done"
    finally:
        final.stop()
    _assert_whole_or_nothing(_stored(settings, run_id), long_log)


@pytest.mark.slow
@pytest.mark.dialect
def test_run_interrupted_too_often_is_failed_with_its_error(settings, long_log) -> None:
    """With TRACKPROFILE_MAX_ATTEMPTS=1 a run whose processing was killed once is marked
    failed at the restart, with the reason, no profile rows and its input removed."""
    env = {**QUEUED, "TRACKPROFILE_MAX_ATTEMPTS": 1}
    first = LiveServer(settings, "first", **env).start()
    try:
        with httpx.Client(base_url=first.url, timeout=120) as c:
            run_id = _upload(c, long_log["csv"]).json()["id"]
            _wait_processing(c, run_id)
            first.kill()
    finally:
        first.kill()
    assert _stored(settings, run_id)["status"] == "processing"
    second = LiveServer(settings, "second", **env).start()
    try:
        with httpx.Client(base_url=second.url, timeout=120) as c:
            failed = wait_status(c, run_id, {"done", "failed"})
    finally:
        second.stop()
    assert failed["status"] == "failed", failed
    assert failed["error"]["kind"] == "Interrupted"
    assert "interrupted once" in failed["error"]["message"]
    state = _stored(settings, run_id)
    assert state["profile_points"] == state["soft_spots"] == state["run_inputs"] == 0


@pytest.mark.slow
@pytest.mark.dialect
def test_inline_upload_killed_mid_request_stores_all_or_nothing(settings, long_log) -> None:
    """A log processed inside the request (under the inline limit) is stored in one
    transaction with its track: killed at several moments of the request, the server leaves
    every table exactly as before (nothing) or the run done with all its rows."""
    import threading

    inline = {"TRACKPROFILE_INLINE_MAX_SAMPLES": 1_000_000}
    measure = LiveServer(settings, "inline-measure", **inline).start()
    try:
        with httpx.Client(base_url=measure.url, timeout=120) as c:
            times = []
            for j in range(2):  # the first request of a process is slower: take the faster
                t0 = time.monotonic()
                r = _upload(c, long_log["csv"], key=f"inline-measure-{j}")
                times.append(time.monotonic() - t0)
                assert r.status_code == 201, r.text
                assert c.delete(f"/api/v1/runs/{r.json()['id']}").status_code == 204
            full = min(times)
    finally:
        measure.stop()
    before = row_counts(settings)

    outcomes = []
    for k, fraction in enumerate((0.4, 0.7, 0.95)):
        server = LiveServer(settings, f"inline{k}", **inline).start()
        sender = threading.Thread(target=_send, args=(server.url, long_log["csv"], f"inline-{k}"))
        sender.start()
        time.sleep(fraction * full)
        server.kill()
        sender.join(60)
        after = row_counts(settings)
        if after == before:
            outcomes.append("nothing")
        else:
            [(run_id,)] = sql(settings, "SELECT id FROM runs WHERE idempotency_key=:k",
                              k=f"inline-{k}")  # fmt: skip
            state = _stored(settings, run_id)
            assert state["status"] == "done", state
            _assert_whole_or_nothing(state, long_log)
            outcomes.append("whole")
            before = after
    assert "nothing" in outcomes, outcomes  # at least one kill hit the request mid-way
