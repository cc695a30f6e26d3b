"""Ingestion scaling with worker processes on PostgreSQL: 1, 2 and 4 ``python -m app worker``.

    python benchmarks/bench_workers.py [--runs 16] [--workers 1,2,4] [--tracks 4]
                                       [--log-minutes 10] [--port 8061] [--pg-port 5461]
                                       [--database-url postgresql+psycopg://USER@HOST:PORT/DB]

Everything stays on this machine. A throwaway PostgreSQL server is started on 127.0.0.1
(``scripts/pg_server.sh``: Debian's PostgreSQL, fsync off like the tests' server) unless
``--database-url`` names one (its user must be allowed to create databases).

1. The runs: ``--runs`` logs of ``--log-minutes`` at 1 kHz (30 m/s, 18 km for 10 minutes), cut
   at different start times from one physics-simulated log (``common.hour_log``: the engine's
   forward model over a track with a soft zone every 2 km, realistic sensor noise and bias;
   simulated once and cached), so that each is a distinct log over its own, overlapping
   stretch; spread over ``--tracks`` tracks (a network's lines: runs on one track store one
   after the other, under the track's lock).
2. Queueing: the API server (``uvicorn app.main:app``) runs in enqueue-only mode
   (``TRACKPROFILE_START_WORKER=false``, ``TRACKPROFILE_INLINE_MAX_SAMPLES=0``): every upload
   is checked, stored and answered 202, nothing is processed. Then the server is stopped, and
   the queued database is the template of one fresh copy per worker count (``CREATE DATABASE
   ... TEMPLATE``): every configuration starts from the same queue.
3. For each worker count N: N separate ``python -m app worker`` processes (one processing
   thread each, BLAS/FFT single-threaded), the database their only shared state, process the
   queue; the time from their start to the last run done gives runs per hour and run-km per
   second. Then every run is checked to have been processed exactly once: status ``done``,
   claimed once (``attempts`` = 1: a second claim would count), its profile blocks and soft
   spots stored once, and as many of them as in the other configurations.
4. Database size per run-km (``pg_total_relation_size`` of every table) after processing.

The load average is printed with every configuration: the machine's cores are shared, and
on a loaded machine more processes also take a larger share of it from the other users.
The CPU time each run costs (the worker processes' and the database server's) does not
depend on that share: runs per core-hour come from it.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_year import table_bytes  # noqa: E402
from common import CACHE, hour_log, machine  # noqa: E402
from load_test import Server, upload  # noqa: E402
from sqlalchemy import create_engine, text  # noqa: E402
from sqlalchemy.engine import make_url  # noqa: E402

from app.db.session import Database  # noqa: E402

SPEED = 30.0  # m/s of common.hour_log
SINGLE_THREAD = {v: "1" for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}


def run_csvs(n: int, minutes: float) -> list[tuple[bytes, float]]:
    """``n`` distinct logs of ``minutes`` (CSV bytes, start chainage m), cached."""
    from engine.logio import write_run_csv
    from engine.runlog import RunLog

    span = minutes * 60.0
    total = max(2 * span, span + 30.0 * n)
    log, start = hour_log(total)
    step = (total - span - 1.0) / max(n - 1, 1)
    out = []
    for k in range(n):
        path = CACHE / f"workers_{int(total)}s_{minutes:g}min_{k}_of_{n}.csv"
        t0 = k * step
        i0, i1 = int(t0 * 1000), int((t0 + span) * 1000)
        if not path.exists():
            t = log.time_s[i0:i1]
            part = RunLog(t - t[0], log.accel_z_mps2[i0:i1], log.pitch_rate_radps[i0:i1],
                          log.speed_mps[i0:i1])  # fmt: skip
            write_run_csv(part, path, digits=8)
        out.append((path.read_bytes(), start + SPEED * float(log.time_s[i0])))
    return out


def with_db(url: str, name: str) -> str:
    """The URL of database ``name`` on the server of ``url``."""
    return make_url(url).set(database=name).render_as_string(hide_password=False)


def admin(url: str, *statements: str) -> None:
    """Run statements outside a transaction on the server's ``postgres`` database."""
    eng = create_engine(with_db(url, "postgres"), isolation_level="AUTOCOMMIT")
    with eng.connect() as conn:
        for st in statements:
            conn.execute(text(st))
    eng.dispose()


def queue_runs(url: str, csvs: list[tuple[bytes, float]], tracks: int, port: int,
               tmp: Path) -> list[int]:  # fmt: skip
    """Upload every log through the API in enqueue-only mode; the queued run ids."""
    settings = {"TRACKPROFILE_START_WORKER": "false", "TRACKPROFILE_INLINE_MAX_SAMPLES": "0"}
    server = Server(port, tmp, url, 1, settings)
    ids = []
    try:
        with httpx.Client(base_url=server.url, timeout=600) as c:
            for k, (data, start) in enumerate(csvs):
                t = time.perf_counter()
                r = upload(c, data, f"line-{k % tracks + 1}", start)
                assert r.status_code == 202, f"upload {k}: {r.status_code} {r.text[:300]}"
                ids.append(int(r.json()["id"]))
                dt = time.perf_counter() - t
                print(f"  queued run {ids[-1]} ({len(data) / 1e6:.0f} MB CSV) on line-"
                      f"{k % tracks + 1} in {dt:.1f} s", flush=True)  # fmt: skip
    finally:
        server.stop()
    return ids


def pg_cpu_s(pg_dir: str | None) -> float:
    """CPU time (s) the PostgreSQL server in ``pg_dir`` has used: the postmaster's own and
    its finished children's, plus its live children's (backends); NaN when unknown."""
    if pg_dir is None:
        return float("nan")
    try:
        pid = int((Path(pg_dir) / "data" / "postmaster.pid").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return float("nan")

    def fields(p: Path) -> list[str]:
        return p.read_text().rsplit(")", 1)[1].split()

    tick = os.sysconf("SC_CLK_TCK")
    own = fields(Path(f"/proc/{pid}/stat"))
    total = sum(int(v) for v in own[11:15])  # utime, stime, cutime, cstime
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            f = fields(stat)
        except OSError:
            continue
        if int(f[1]) == pid:
            total += int(f[11]) + int(f[12])
    return total / tick


def process(url: str, n_workers: int, n_runs: int, tmp: Path,
            pg_dir: str | None) -> dict[str, Any]:  # fmt: skip
    """Start ``n_workers`` worker processes on ``url``, wait until no run is queued, stop
    them; timings (s), the CPU time of the workers and of the database server (s) and the
    load average."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("TRACKPROFILE_")}
    env |= SINGLE_THREAD | {
        "DATABASE_URL": url, "TRACKPROFILE_WORKERS": "1", "TRACKPROFILE_DATA_DIR": str(tmp),
        "TRACKPROFILE_POLL_INTERVAL_S": "0.2", "PYTHONPATH": str(REPO),
    }  # fmt: skip
    eng = create_engine(url)
    load0 = os.getloadavg()
    cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    pg0 = pg_cpu_s(pg_dir)
    t0 = time.time()
    logs = [open(tmp / f"worker-{n_workers}-{i}.log", "wb") for i in range(n_workers)]  # noqa: SIM115
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "app", "worker"],
            cwd=REPO,
            env=env,
            stdout=f,
            stderr=subprocess.STDOUT,
        )  # fmt: skip
        for f in logs
    ]
    loads = []
    ready = None
    try:
        while True:
            time.sleep(0.5)
            loads.append(os.getloadavg()[0])
            if ready is None and all(
                b"thread(s)" in (tmp / f"worker-{n_workers}-{i}.log").read_bytes()
                for i in range(n_workers)
            ):
                ready = time.time() - t0
            with eng.connect() as conn:
                left = conn.execute(
                    text("SELECT count(*) FROM runs WHERE status = 'processing'")
                ).scalar_one()
            if left == 0:
                break
            dead = [p.pid for p in procs if p.poll() is not None]
            if dead:
                raise SystemExit(f"worker process(es) {dead} exited: see {tmp}")
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            try:
                p.wait(30)
            except subprocess.TimeoutExpired:
                p.kill()
        cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        pg1 = pg_cpu_s(pg_dir)
        for f in logs:
            f.close()
    with eng.connect() as conn:
        first, last = conn.execute(
            text(
                "SELECT extract(epoch FROM min(processed_at)), extract(epoch FROM "
                "max(processed_at)) FROM runs"
            )  # fmt: skip
        ).one()
    eng.dispose()
    wall = float(last) - t0
    return {"worker_cpu_s": cpu1.ru_utime + cpu1.ru_stime - cpu0.ru_utime - cpu0.ru_stime,
            "pg_cpu_s": pg1 - pg0, "wall_s": wall,
            "startup_s": ready if ready is not None else float("nan"),
            "span_s": wall - (ready if ready is not None else 0.0), "load_before": load0,
            "load_max": max(loads), "load_mean": float(np.mean(loads)),
            "first_done_s": float(first) - t0}  # fmt: skip


def census(url: str) -> dict[int, tuple[Any, ...]]:
    """Per run: status, attempts, chainage span (m), profile blocks, distinct blocks, spots."""
    eng = create_engine(url)
    with eng.connect() as conn:
        rows = conn.execute(
            text(
                "SELECT r.id, r.status, r.attempts, r.chainage_max_m - r.chainage_min_m, "
                "(SELECT count(*) FROM run_profile_blocks b WHERE b.run_id = r.id), "
                "(SELECT count(DISTINCT b.block) FROM run_profile_blocks b WHERE b.run_id = r.id),"
                " (SELECT count(*) FROM soft_spots s WHERE s.run_id = r.id) FROM runs r"
            )
        ).all()
    eng.dispose()
    return {int(r[0]): tuple(r[1:]) for r in rows}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=16)
    ap.add_argument("--workers", default="1,2,4", help="worker process counts, comma-separated")
    ap.add_argument("--tracks", type=int, default=4)
    ap.add_argument("--log-minutes", type=float, default=10.0)
    ap.add_argument("--port", type=int, default=8061, help="the API server's (127.0.0.1)")
    ap.add_argument("--pg-port", type=int, default=5461, help="the throwaway server's")
    ap.add_argument("--database-url", default=None, help="a PostgreSQL server to use instead")
    a = ap.parse_args()
    counts = [int(w) for w in a.workers.split(",")]
    print(f"machine: {machine()}; load average {os.getloadavg()}", flush=True)
    t = time.perf_counter()
    csvs = run_csvs(a.runs, a.log_minutes)
    print(f"{a.runs} logs of {a.log_minutes:g} min ready in {time.perf_counter() - t:.0f} s",
          flush=True)  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="bench-workers-") as tmp_s:
        tmp = Path(tmp_s)
        if a.database_url:
            return bench(a, counts, csvs, a.database_url, tmp, None)
        # a directory of its own: pg_server.sh hands it to the postgres user
        pg_dir = tempfile.mkdtemp(prefix="bench-workers-pg-")
        try:
            base = subprocess.run(
                ["bash", "scripts/pg_server.sh", "start", pg_dir, str(a.pg_port)],
                cwd=REPO, check=True, capture_output=True, text=True,
            ).stdout.strip()  # fmt: skip
            return bench(a, counts, csvs, base, tmp, pg_dir)
        finally:
            subprocess.run(["bash", "scripts/pg_server.sh", "stop", pg_dir], cwd=REPO,
                           check=False, capture_output=True)  # fmt: skip
            shutil.rmtree(pg_dir, ignore_errors=True)


def bench(a: argparse.Namespace, counts: list[int], csvs: list[tuple[bytes, float]], base: str,
          tmp: Path, pg_dir: str | None) -> int:  # fmt: skip
    admin(base, "DROP DATABASE IF EXISTS bench_queued", "CREATE DATABASE bench_queued")
    queued_url = with_db(base, "bench_queued")
    ids = queue_runs(queued_url, csvs, a.tracks, a.port, tmp)
    queued_tables = sizes(queued_url)
    results = {}
    censuses = {}
    for n in counts:
        name = f"bench_workers_{n}"
        admin(base, f"DROP DATABASE IF EXISTS {name}",
              f"CREATE DATABASE {name} TEMPLATE bench_queued")  # fmt: skip
        url = with_db(base, name)
        print(f"{n} worker process(es): processing {len(ids)} queued runs ...", flush=True)
        r = process(url, n, len(ids), tmp, pg_dir)
        censuses[n] = census(url)
        r["tables"] = sizes(url)
        results[n] = r
        run_km = sum(c[2] for c in censuses[n].values()) / 1e3
        print(f"  started in {r['startup_s']:.1f} s, processed in {r['span_s']:.1f} s: "
              f"{3600 * len(ids) / r['span_s']:.0f} runs/h, "
              f"{run_km / r['span_s']:.2f} run-km/s (load average {r['load_before'][0]:.1f} "
              f"before, mean {r['load_mean']:.1f}, max {r['load_max']:.1f})",
              flush=True)  # fmt: skip

    # exactly once: every queued run done, claimed once, its rows stored once, the same rows
    # whatever the number of workers
    problems = []
    for n, c in censuses.items():
        if sorted(c) != sorted(ids):
            problems.append(f"{n} workers: runs {sorted(set(c) ^ set(ids))} lost or added")
        for rid, (status, attempts, _span, blocks, distinct, spots) in c.items():
            if status != "done" or attempts != 1 or blocks != distinct:
                problems.append(f"{n} workers: run {rid} status {status}, claimed {attempts} "
                                f"times, {blocks} blocks ({distinct} distinct)")  # fmt: skip
            ref = censuses[counts[0]][rid]
            if (blocks, spots) != (ref[3], ref[5]):
                problems.append(f"{n} workers: run {rid} has {blocks} blocks and {spots} "
                                f"spots, {ref[3]} and {ref[5]} with {counts[0]}")  # fmt: skip

    c0 = censuses[counts[0]]
    run_km = sum(c[2] for c in c0.values()) / 1e3
    print()
    print(f"machine: {machine()}")
    print(f"{len(ids)} runs of {a.log_minutes:g} min at 1 kHz ({run_km:.0f} run-km) on "
          f"{a.tracks} tracks, PostgreSQL {pg_version(base)}")  # fmt: skip
    print()
    print("| worker processes | start-up (imports, connect) | processing (all started -> last "
          "run done) | runs per hour | run-km per s | speed-up | CPU per run: workers + "
          "PostgreSQL | runs per core-hour | load average (before / mean / max) |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    base_rate = len(ids) / results[counts[0]]["span_s"]
    for n, r in results.items():
        rate = len(ids) / r["span_s"]
        load = f"{r['load_before'][0]:.1f} / {r['load_mean']:.1f} / {r['load_max']:.1f}"
        w_cpu, pg_cpu = r["worker_cpu_s"] / len(ids), r["pg_cpu_s"] / len(ids)
        per_core = 3600 / (w_cpu + (pg_cpu if np.isfinite(pg_cpu) else 0.0))
        print(f"| {n} | {r['startup_s']:.1f} s | {r['span_s']:.1f} s | {3600 * rate:.0f} | "
              f"{run_km / r['span_s']:.2f} | {rate / base_rate:.2f}x | {w_cpu:.2f} + "
              f"{pg_cpu:.2f} s | {per_core:.0f} | {load} |")  # fmt: skip
    print(
        "(CPU: the worker processes' user + system time, start-up and idle polling included,"
        " and the database server's; runs per core-hour = 3600 s / their sum per run)"
    )
    print()
    tables = results[counts[-1]]["tables"]
    print(
        f"database size per run-km after processing ({counts[-1]} workers; "
        "pg_total_relation_size: table + indexes + TOAST):"
    )
    for t_name, b in tables.items():
        if b / run_km > 100:
            print(f"  {t_name}: {b / 1e3 / run_km:.1f} kB ({b / 1e6:.1f} MB)")
    per_run = ("run_profile_blocks", "track_run_levels", "run_signals", "soft_spots", "runs")
    own = sum(tables.get(t, 0) for t in per_run)
    print(f"  growth per run-km, everything per run, log aside ({', '.join(per_run)}): "
          f"{own / 1e3 / run_km:.1f} kB")  # fmt: skip
    print(f"  the queued logs (run_inputs, compressed): "
          f"{queued_tables.get('run_inputs', 0) / 1e3 / run_km:.1f} kB per run-km")  # fmt: skip
    if problems:
        print("NOT exactly once:\n  " + "\n  ".join(problems))
        return 1
    print(
        f"exactly once: each of the {len(ids)} runs done, claimed once, its blocks and spots "
        f"stored once and the same with {', '.join(map(str, counts))} worker processes"
    )
    return 0


def sizes(url: str) -> dict[str, int]:
    """Bytes per table of the database at ``url`` (its connections closed after: it may be
    the template of the next copy)."""
    db = Database(url)
    try:
        return table_bytes(db)
    finally:
        db.dispose()


def pg_version(url: str) -> str:
    eng = create_engine(url)
    with eng.connect() as conn:
        v = str(conn.execute(text("SHOW server_version")).scalar_one())
    eng.dispose()
    return v


if __name__ == "__main__":
    raise SystemExit(main())
