"""Load test: sustained uploads per minute, and read latencies while uploads go on.

    python benchmarks/load_test.py [--duration 60] [--uploaders 2] [--readers 2]
                                   [--max-requests 20000] [--port 8045] [--workers 2]
                                   [--database-url URL]

Everything stays on this machine: the service runs as a real ``uvicorn app.main:app`` process
bound to 127.0.0.1 on a fresh database (a SQLite file in a temporary folder, or
``--database-url``, e.g. a PostgreSQL database), and every request goes to that address. The
test stops itself after ``--duration`` seconds or ``--max-requests`` requests, whichever comes
first, and then stops the server.

1. A long run (10 km, 400 s at 25 m/s, random body motion: 40 000 profile points) is stored
   first, so that 2 km chainage windows can be read.
2. Idle reads: each read kind alone, ``--idle-reads`` times, for reference.
3. Under load: ``--uploaders`` threads upload short runs back to back (the 134 m synthetic run
   of the API tests, 5 355 samples at 1 kHz, each upload a distinct log, processed inline:
   201 with the result) on 4 tracks, while ``--readers`` threads read in turn: a page of runs
   (``GET /api/v1/runs?limit=50``), a run (``GET /api/v1/runs/{id}``), a 2 km profile window
   of the long run, and a 20 m window of a just-stored short run.

Prints the figures as a Markdown table (``--json`` also writes them as JSON).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import random
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

import httpx
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import machine  # noqa: E402

HOST = "127.0.0.1"  # loopback only, never configurable


def short_run_csv() -> bytes:
    """The API tests' synthetic run: 160 m of track, a 50 % soft zone at 70-75 m, 25 m/s,
    realistic sensor noise (5 355 samples at 1 kHz)."""
    from engine.logio import write_run_csv
    from engine.synthetic import REALISTIC_SENSOR, make_run
    from engine.track import SoftZone

    run = make_run(
        length=160.0, zones=[SoftZone(70.0, 75.0, 0.5)], speed=25.0, start_chainage_m=12.0,
        jitter=0.03, sensor=REALISTIC_SENSOR, seed=3,
    )  # fmt: skip
    buf = io.StringIO()
    write_run_csv(run.log, buf, digits=8)
    return buf.getvalue().encode()


def variant(base: bytes, k: int) -> bytes:
    """The short run without its last ``k % 1000`` samples, plus ``k // 1000`` blank lines:
    a distinct upload (content hash) of an invertible log for every ``k``."""
    lines = base.decode().splitlines()
    return ("\n".join(lines[: len(lines) - k % 1000]) + "\n" * (1 + k // 1000)).encode()


def long_run_csv(seconds: float = 400.0) -> bytes:
    """A 1 kHz log of random body motion at 25 m/s over ``seconds`` (10 km for 400 s)."""
    n = int(seconds * 1000)
    rng = np.random.default_rng(11)
    cols = [np.arange(n) / 1000, 0.05 * rng.standard_normal(n), 5e-4 * rng.standard_normal(n),
            np.full(n, 25.0)]  # fmt: skip
    buf = io.StringIO()
    buf.write("time_s,accel_z_mps2,pitch_rate_radps,speed_mps\n")
    np.savetxt(buf, np.column_stack(cols), fmt=["%.3f", "%.5f", "%.6f", "%.1f"], delimiter=",")
    return buf.getvalue().encode()


def percentiles(ms: list[float]) -> dict[str, float]:
    """n, p50, p95, p99 and max of latencies in ms."""
    if not ms:
        return {"n": 0, "p50": float("nan"), "p95": float("nan"), "p99": float("nan"),
                "max": float("nan")}  # fmt: skip
    q = np.percentile(ms, [50, 95, 99])
    return {"n": len(ms), "p50": float(q[0]), "p95": float(q[1]), "p99": float(q[2]),
            "max": float(max(ms))}  # fmt: skip


class Server:
    """A uvicorn process of the service on 127.0.0.1."""

    def __init__(
        self,
        port: int,
        data_dir: Path,
        database_url: str | None,
        workers: int,
        settings: dict[str, str] | None = None,
    ) -> None:
        env = {k: v for k, v in os.environ.items() if not k.startswith("TRACKPROFILE_")}
        env.pop("DATABASE_URL", None)
        env |= {
            "TRACKPROFILE_DATA_DIR": str(data_dir),
            "TRACKPROFILE_WORKERS": str(workers),
            "PYTHONPATH": str(REPO),
        } | (settings or {})
        if database_url:
            env["DATABASE_URL"] = database_url
        self.url = f"http://{HOST}:{port}"
        self.log = open(data_dir / "server.log", "wb")  # noqa: SIM115
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "uvicorn", "app.main:app", "--host", HOST, "--port",
             str(port), "--no-access-log", "--log-level", "warning"],
            cwd=REPO, env=env, stdout=self.log, stderr=subprocess.STDOUT,
        )  # fmt: skip
        deadline = time.monotonic() + 90
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise SystemExit(f"the server exited: see {data_dir / 'server.log'}")
            try:
                if httpx.get(self.url + "/healthz", timeout=2).status_code == 200:
                    return
            except httpx.HTTPError:
                pass
            time.sleep(0.2)
        self.stop()
        raise SystemExit("the server did not start within 90 s")

    def stop(self) -> None:
        """Stop the process (SIGTERM, then SIGKILL)."""
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
        self.log.close()


def upload(c: httpx.Client, data: bytes, track: str, start: float) -> httpx.Response:
    """POST a CSV as a multipart upload."""
    return c.post(
        "/api/v1/runs",
        files={"file": ("run.csv", data, "text/csv")},
        data={"track": track, "start_chainage_m": str(start)},
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--duration", type=float, default=60.0, help="load phase length, s (<= 600)")
    p.add_argument("--uploaders", type=int, default=2, help="upload threads (1-8)")
    p.add_argument("--readers", type=int, default=2, help="read threads (0-8)")
    p.add_argument("--max-requests", type=int, default=20_000, help="stop after this many")
    p.add_argument("--idle-reads", type=int, default=50, help="reads of each kind before load")
    p.add_argument("--port", type=int, default=8045)
    p.add_argument("--workers", type=int, default=2, help="TRACKPROFILE_WORKERS of the server")
    p.add_argument("--database-url", default=None, help="default: SQLite in a temporary folder")
    p.add_argument("--json", type=Path, default=None, help="also write the figures here")
    a = p.parse_args()
    duration = min(max(a.duration, 5.0), 600.0)
    uploaders = min(max(a.uploaders, 1), 8)
    readers = min(max(a.readers, 0), 8)

    base = short_run_csv()
    long_csv = long_run_csv()
    with tempfile.TemporaryDirectory(prefix="trackprofile-load-") as tmp:
        server = Server(a.port, Path(tmp), a.database_url, a.workers)
        try:
            figures = run_load(server.url, base, long_csv, duration, uploaders, readers, a)
        finally:
            server.stop()
    figures["machine"] = machine()
    print_table(figures)
    if a.json:
        a.json.write_text(json.dumps(figures, indent=2))


def run_load(
    url: str, base: bytes, long_csv: bytes, duration: float, uploaders: int, readers: int,
    a: argparse.Namespace,
) -> dict[str, Any]:  # fmt: skip
    """Store the long run, time idle reads, then upload and read concurrently."""
    with httpx.Client(base_url=url, timeout=300) as c:
        r = c.post(
            "/api/v1/runs",
            params={"wait": "true"},
            files={"file": ("long.csv", long_csv, "text/csv")},
            data={"track": "long line", "start_chainage_m": "0"},
        )
        if r.status_code not in (200, 201) or r.json()["status"] != "done":
            raise SystemExit(f"the long run was not stored: {r.status_code} {r.text[:300]}")
        long_id = r.json()["id"]
        long_max = r.json()["chainage_max_m"]
        first = upload(c, variant(base, 0), "line 0", 12.0)
        if first.status_code != 201:
            raise SystemExit(f"the short run was not stored: {first.status_code} {first.text}")

    rng = random.Random(5)
    lock = threading.Lock()
    latencies: dict[str, list[float]] = defaultdict(list)
    statuses: Counter[int] = Counter()
    done_ids: list[int] = [first.json()["id"]]
    upload_times: list[float] = []
    budget = [a.max_requests]
    stop = threading.Event()

    def spend() -> bool:
        with lock:
            budget[0] -= 1
            if budget[0] < 0:
                stop.set()
            return budget[0] >= 0

    def read_once(c: httpx.Client, kind: str, r_: random.Random, sink: dict[str, list[float]]):
        with lock:
            rid = r_.choice(done_ids)
        if kind == "runs page":
            path = "/api/v1/runs?limit=50"
        elif kind == "run":
            path = f"/api/v1/runs/{rid}"
        elif kind == "profile 2 km window":
            x0 = r_.uniform(0.0, max(0.0, long_max - 2000.0))
            path = f"/api/v1/runs/{long_id}/profile?from_m={x0:.2f}&to_m={x0 + 2000:.2f}"
        else:
            path = f"/api/v1/runs/{rid}/profile?from_m=60&to_m=80"
        t0 = time.perf_counter()
        resp = c.get(path)
        ms = 1000 * (time.perf_counter() - t0)
        with lock:
            statuses[resp.status_code] += 1
            sink[kind].append(ms)

    kinds = ["runs page", "run", "profile 2 km window", "profile 20 m window"]
    idle: dict[str, list[float]] = defaultdict(list)
    with httpx.Client(base_url=url, timeout=60) as c:
        for kind in kinds:
            for _ in range(a.idle_reads):
                read_once(c, kind, rng, idle)

    counter = [1]
    t_start = time.monotonic()
    t_end = t_start + duration

    def uploader(u: int) -> None:
        with httpx.Client(base_url=url, timeout=120) as c:
            while not stop.is_set() and time.monotonic() < t_end and spend():
                with lock:
                    k = counter[0]
                    counter[0] += 1
                t0 = time.perf_counter()
                resp = upload(c, variant(base, k), f"line {k % 4}", 12.0)
                dt = time.perf_counter() - t0
                with lock:
                    statuses[resp.status_code] += 1
                    if resp.status_code == 201:
                        upload_times.append(dt)
                        done_ids.append(resp.json()["id"])

    def reader(seed: int) -> None:
        r_ = random.Random(seed)
        with httpx.Client(base_url=url, timeout=60) as c:
            i = 0
            while not stop.is_set() and time.monotonic() < t_end and spend():
                read_once(c, kinds[i % len(kinds)], r_, latencies)
                i += 1

    threads = [threading.Thread(target=uploader, args=(u,)) for u in range(uploaders)]
    threads += [threading.Thread(target=reader, args=(100 + s,)) for s in range(readers)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(duration + 300)
    elapsed = time.monotonic() - t_start
    return {
        "duration_s": elapsed,
        "uploaders": uploaders,
        "readers": readers,
        "server_workers": a.workers,
        "database": "PostgreSQL" if a.database_url else "SQLite (WAL)",
        "uploads_stored": len(upload_times),
        "uploads_per_minute": 60.0 * len(upload_times) / elapsed,
        "upload_latency_ms": percentiles([1000 * t for t in upload_times]),
        "statuses": dict(sorted(statuses.items())),
        "server_errors": sum(n for code, n in statuses.items() if code >= 500),
        "idle_ms": {k: percentiles(v) for k, v in idle.items()},
        "under_load_ms": {k: percentiles(latencies[k]) for k in kinds},
    }


def print_table(f: dict[str, Any]) -> None:
    """The figures as Markdown."""
    print(f"Machine: {f['machine']}")
    print(
        f"{f['database']}, server with TRACKPROFILE_WORKERS={f['server_workers']}; "
        f"{f['uploaders']} upload threads, {f['readers']} read threads, "
        f"{f['duration_s']:.0f} s"
    )
    print()
    u = f["upload_latency_ms"]
    print(
        f"Sustained uploads: {f['uploads_per_minute']:.0f} per minute ({f['uploads_stored']} "
        f"stored, each answered 201 with its result; upload latency p50 {u['p50']:.0f} ms, "
        f"p95 {u['p95']:.0f} ms, p99 {u['p99']:.0f} ms). Answers by status: {f['statuses']}; "
        f"5xx: {f['server_errors']}."
    )
    print()
    print("| read | idle p50 / p95 / p99 (ms) | during uploads p50 / p95 / p99 (ms) | n |")
    print("|---|---|---|---|")
    for kind, s in f["under_load_ms"].items():
        i = f["idle_ms"][kind]
        print(
            f"| {kind} | {i['p50']:.1f} / {i['p95']:.1f} / {i['p99']:.1f} | "
            f"{s['p50']:.1f} / {s['p95']:.1f} / {s['p99']:.1f} | {s['n']} |"
        )


if __name__ == "__main__":
    main()
