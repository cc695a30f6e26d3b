"""Concurrency against real server processes (loopback, bounded in count and time).

Parallel uploads (inline and queued), idempotent resends racing each other, deletes while
runs are processed, and readers throughout: no 5xx, no lost run, every run done. Several app
processes on one database process each queued run exactly once. These run on SQLite (WAL)
and, with ``TEST_DATABASE_URL``, on PostgreSQL.
"""

from __future__ import annotations

import io
import random
import threading
import time
from collections import Counter
from typing import Any

import httpx
import numpy as np
import pytest

from api.api_support import sql, stored_points
from api.live_server import live_servers, wait_status

TIME_LIMIT_S = 180.0
"""No thread of these tests runs longer than this."""


def _variant(base: bytes, k: int) -> bytes:
    """The synthetic run shortened by ``k`` samples: a distinct log, still invertible."""
    lines = base.decode().splitlines()
    return ("\n".join(lines[: len(lines) - k]) + "\n").encode()


def _noise_log(n: int, seed: int) -> bytes:
    """A queued-size log (``n`` samples at 1 kHz, 25 m/s) of random body motion."""
    rng = np.random.default_rng(seed)
    buf = io.StringIO()
    buf.write("time_s,accel_z_mps2,pitch_rate_radps,speed_mps\n")
    cols = [np.arange(n) / 1000, 0.05 * rng.standard_normal(n), 5e-4 * rng.standard_normal(n),
            np.full(n, 25.0)]  # fmt: skip
    np.savetxt(buf, np.column_stack(cols), fmt=["%.3f", "%.5f", "%.6f", "%.1f"], delimiter=",")
    return buf.getvalue().encode()


def _post(c: httpx.Client, data: bytes, track: str, key: str | None = None) -> httpx.Response:
    return c.post(
        "/api/v1/runs",
        files={"file": ("run.csv", data, "text/csv")},
        data={"track": track, "start_chainage_m": "12"},
        headers={"Idempotency-Key": key} if key else None,
    )


@pytest.mark.slow
@pytest.mark.dialect
def test_parallel_uploads_readers_and_deletes(settings, synthetic_run) -> None:
    """6 uploaders (24 runs, inline and queued), 2 threads resending one file with one
    Idempotency-Key, a thread deleting runs while they process, and 4 readers (lists, runs,
    profile windows, tracks) against one server: zero 5xx, every upload accepted once, every
    kept run done, deleted runs gone without leftovers."""
    base = synthetic_run["csv"]
    env = {"TRACKPROFILE_INLINE_MAX_SAMPLES": 5300, "TRACKPROFILE_WORKERS": 2}
    statuses: Counter[int] = Counter()
    failures: list[str] = []
    uploaded: list[int] = []
    deleted: list[int] = []
    lock = threading.Lock()
    uploads_done = threading.Event()
    deadline = time.monotonic() + TIME_LIMIT_S

    def record(r: httpx.Response, what: str) -> None:
        with lock:
            statuses[r.status_code] += 1
            if r.status_code >= 500:
                failures.append(f"{what}: {r.status_code} {r.text[:300]}")

    with live_servers(settings, **env) as [server]:

        def uploader(u: int) -> None:
            with httpx.Client(base_url=server.url, timeout=120) as c:
                for j in range(4):
                    k = 1 + 10 * (4 * u + j)  # 1..231 samples fewer: 5124-5354 samples
                    r = _post(c, _variant(base, k), track=f"line {u % 3}")
                    record(r, "upload")
                    if r.status_code not in (201, 202):
                        failures.append(f"upload {u}/{j}: {r.status_code} {r.text[:300]}")
                        continue
                    with lock:
                        uploaded.append(r.json()["id"])

        resent: list[int] = []

        def resender() -> None:
            with httpx.Client(base_url=server.url, timeout=120) as c:
                r = _post(c, _variant(base, 500), track="resent", key="same-key")
                record(r, "resend")
                if r.status_code in (200, 201, 202):
                    with lock:
                        resent.append(r.json()["id"])
                else:
                    failures.append(f"resend: {r.status_code} {r.text[:300]}")

        def deleter() -> None:
            with httpx.Client(base_url=server.url, timeout=120) as c:
                for j in range(3):
                    r = _post(c, _variant(base, 5 + 10 * j), track="deleted")  # queued
                    record(r, "upload to delete")
                    if r.status_code != 202:
                        failures.append(f"upload to delete: {r.status_code} {r.text[:300]}")
                        continue
                    run_id = r.json()["id"]
                    time.sleep(0.05 * j)  # queued, being inverted, or just stored
                    d = c.delete(f"/api/v1/runs/{run_id}")
                    record(d, "delete")
                    if d.status_code != 204:
                        failures.append(f"delete {run_id}: {d.status_code} {d.text[:300]}")
                    with lock:
                        deleted.append(run_id)

        def reader(seed: int) -> None:
            rng = random.Random(seed)
            with httpx.Client(base_url=server.url, timeout=120) as c:
                while not uploads_done.is_set() and time.monotonic() < deadline:
                    with lock:
                        known = list(uploaded)
                    paths = ["/api/v1/runs?limit=50", "/api/v1/tracks", "/healthz"]
                    if known:
                        rid = rng.choice(known)
                        paths += [
                            f"/api/v1/runs/{rid}",
                            f"/api/v1/runs/{rid}/profile?from_m=40&to_m=90",
                        ]
                    for p in paths:
                        r = c.get(p)
                        record(r, f"GET {p}")
                        if r.status_code not in (200, 409):  # 409: profile not ready yet
                            failures.append(f"GET {p}: {r.status_code} {r.text[:300]}")

        writers = [threading.Thread(target=uploader, args=(u,)) for u in range(6)]
        writers += [threading.Thread(target=resender) for _ in range(2)]
        writers.append(threading.Thread(target=deleter))
        readers = [threading.Thread(target=reader, args=(s,)) for s in range(4)]
        for t in writers + readers:
            t.start()
        for t in writers:
            t.join(TIME_LIMIT_S)
        uploads_done.set()
        for t in readers:
            t.join(TIME_LIMIT_S)

        assert not failures, failures[:5]
        assert len(uploaded) == 24 and len(set(uploaded)) == 24
        assert len(resent) == 2 and resent[0] == resent[1]  # one run for the repeated key
        with httpx.Client(base_url=server.url, timeout=120) as c:
            for rid in [*uploaded, resent[0]]:
                run = wait_status(c, rid, {"done", "failed"})
                assert run["status"] == "done", run
            for rid in deleted:
                assert c.get(f"/api/v1/runs/{rid}").status_code == 404
            listed = c.get("/api/v1/runs", params={"limit": 1000}).json()
        assert listed["count"] == 25
        assert {r["id"] for r in listed["data"]} == {*uploaded, resent[0]}
    assert sum(n for code, n in statuses.items() if code >= 500) == 0
    assert statuses[200] > 50  # the readers did read throughout
    for table in ("run_profile_blocks", "soft_spots", "run_inputs", "run_signals"):
        leftovers = sql(
            settings,
            f"SELECT count(*) FROM {table} WHERE run_id NOT IN (SELECT id FROM runs)",
        )[0][0]
        assert leftovers == 0, table


@pytest.mark.slow
@pytest.mark.dialect
def test_two_app_processes_process_each_run_exactly_once(settings) -> None:
    """Eight runs queued through two app processes (two worker threads each) on one database,
    four to each: every run is claimed once (attempts = 1, one claim in the two logs together)
    although both processes' workers look for queued runs in the same table, both processes
    take part, and every run is done with its profile stored once.

    (The runs are posted once both processes are up: a backlog queued before they start is
    drained by whichever starts first when the runs are short — seen in CI once processing got
    faster — which says nothing about the claim race.)"""
    logs = [_noise_log(150_000, seed) for seed in range(8)]
    env: dict[str, Any] = {"TRACKPROFILE_WORKERS": 2, "TRACKPROFILE_INLINE_MAX_SAMPLES": 1000}
    with live_servers(settings, count=2, **env) as servers:
        clients = [httpx.Client(base_url=s.url, timeout=120) for s in servers]
        try:
            ids = []
            for k, data in enumerate(logs):
                r = _post(clients[k % 2], data, track=f"queued {k // 4}")
                assert r.status_code == 202, r.text
                ids.append(r.json()["id"])
            for rid in ids:
                assert wait_status(clients[0], rid, {"done", "failed"})["status"] == "done"
            profile_n = {
                rid: clients[1].get(f"/api/v1/runs/{rid}/profile").json()["n"] for rid in ids
            }
        finally:
            for c in clients:
                c.close()
    claims = [rid for s in servers for rid, _attempt in s.claims()]
    assert sorted(claims) == sorted(ids), claims  # each run claimed exactly once
    assert all(s.claims() for s in servers), [s.claims() for s in servers]
    attempts = dict(sql(settings, "SELECT id, attempts FROM runs"))
    assert attempts == {rid: 1 for rid in ids}
    rows = stored_points(settings)
    assert rows == profile_n
