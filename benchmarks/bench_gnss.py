"""A 20-minute 1 kHz log with a GNSS fix on every row through the service.

    python benchmarks/bench_gnss.py [--before REV] [--rounds 2] [--port 8013]

The log (1.2 M rows, 30 m/s over 36 km, soft zones every 2 km, realistic sensor noise) comes
from ``benchmarks/common.py`` (simulated once, then cached). Its fixes lie on a winding 40 km
centerline (``bench_positioning.winding_line``) at the body's chainage, with 1.5 m white noise
per axis on every row and a 0.7 m bias wandering over 10 s; written as a CSV with ``lat``/``lon``
columns (9 decimals). The same log without those columns is the reference, uploaded with its
start chainage to a track without a centerline.

Against a real uvicorn process on a fresh SQLite database (default settings: one processing
slot), timed from the start of the upload until the run is ``done``:

1. sequentially, ``--rounds`` times: the log without fixes, then with fixes (best of each);
2. three uploads with fixes in parallel (three tracks): each one's time, and the server's peak
   resident memory (psutil, every 10 ms), beside three without fixes in parallel.

Targets: with fixes <= 1.5x without; the parallel peak within the service's 1.5 GB.
``--before REV`` runs everything on git revision ``REV`` too (``git archive`` into a temporary
directory, the same Python environment), side by side in one run.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import psutil

sys.path.insert(0, str(Path(__file__).resolve().parent))
REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))

from bench_positioning import export, winding_line  # noqa: E402
from bench_service import PeakRss, wait_healthy  # noqa: E402
from common import CACHE, hour_log, machine  # noqa: E402
from scipy.signal import lfilter  # noqa: E402

DURATION_S = 1200.0
LINE_START_M = 0.0
RUN_ON_LINE_M = 100.0
"""The log's chainage 0 is this far along the line, m."""


def inputs() -> tuple[Path, Path, dict[str, Any], float]:
    """The CSVs without and with fixes (cached), the centerline GeoJSON and the start
    chainage of the log without fixes, m."""
    import dataclasses

    from engine.logio import write_run_csv
    from engine.positioning import Centerline, geodesic_chainage
    from support.gnss import csv_with_fixes

    log, start = hour_log(DURATION_S)
    lon_v, lat_v = winding_line(40_000.0, 4000)
    line = Centerline(lon_v, lat_v, geodesic_chainage(lon_v, lat_v, LINE_START_M))
    feature = {
        "type": "Feature",
        "properties": {"start_chainage_m": LINE_START_M},
        "geometry": {
            "type": "LineString",
            "coordinates": [[round(a, 9), round(b, 9)] for a, b in zip(lon_v, lat_v, strict=True)],
        },
    }
    start_on_line = LINE_START_M + RUN_ON_LINE_M + start
    plain = CACHE / "gnss_20min_plain.csv"
    fixes = CACHE / "gnss_20min_every_row.csv"
    if not plain.exists():
        with open(plain, "w", encoding="utf-8", newline="\n") as fh:
            write_run_csv(log, fh, digits=8)
    if not fixes.exists():
        rng = np.random.default_rng(5)
        x, y = line.point_at(start_on_line + log.distance())
        phi = np.exp(-0.001 / 10.0)
        bias = lfilter([1.0], [1.0, -phi], rng.normal(0, 0.7 * np.sqrt(1 - phi**2), (2, log.n)))
        lon, lat = line._to_plane.transform(
            x + bias[0] + rng.normal(0, 1.5, log.n),
            y + bias[1] + rng.normal(0, 1.5, log.n),
            direction="INVERSE",
        )
        fixed = dataclasses.replace(log, lat_deg=np.asarray(lat), lon_deg=np.asarray(lon))
        fixes.write_bytes(csv_with_fixes(fixed))
    return plain, fixes, feature, start_on_line


def upload_until_done(base: str, path: Path, track: str, start: float | None) -> float:
    """Seconds from the start of the upload until the run is done."""
    data = {"track": track} | ({"start_chainage_m": str(start)} if start is not None else {})
    with httpx.Client(base_url=base, timeout=900) as c:
        t0 = time.perf_counter()
        with open(path, "rb") as fh:
            r = c.post("/api/v1/runs", files={"file": (path.name, fh, "text/csv")}, data=data)
        if r.status_code not in (200, 201, 202):
            raise RuntimeError(f"upload to {track}: {r.status_code} {r.text[:300]}")
        run = r.json()
        while run["status"] == "processing":
            time.sleep(0.05)
            run = c.get(f"/api/v1/runs/{run['id']}").json()
        if run["status"] != "done":
            raise RuntimeError(f"run on {track} ended {run['status']}: {run.get('error')}")
        return time.perf_counter() - t0


def measure(
    src: str, port: int, rounds: int, plain: Path, fixes: Path, feature: dict[str, Any],
    start: float,
) -> dict[str, Any]:  # fmt: skip
    """Every figure for the service of source tree ``src``."""
    with tempfile.TemporaryDirectory(prefix="bench-gnss-") as data_dir:
        env = {**os.environ, "TRACKPROFILE_DATA_DIR": data_dir,
               "TRACKPROFILE_MAX_UPLOAD_MB": "1000", "PYTHONPATH": src}  # fmt: skip
        env.pop("DATABASE_URL", None)
        base = f"http://127.0.0.1:{port}"
        server = subprocess.Popen(
            [sys.executable, "-m", "uvicorn", "app.main:app", "--host", "127.0.0.1", "--port",
             str(port), "--log-level", "warning"],
            cwd=src, env=env,
        )  # fmt: skip
        try:
            wait_healthy(base)
            with httpx.Client(base_url=base, timeout=60) as c:
                for k in range(1, rounds + 4):
                    c.post("/api/v1/tracks", json={"name": f"gnss-{k}"}).raise_for_status()
                    r = c.put(
                        f"/api/v1/tracks/gnss-{k}/centerline",
                        content=json.dumps(feature),
                        headers={"Content-Type": "application/geo+json"},
                    )
                    r.raise_for_status()
            plain_s, fix_s = [], []
            for k in range(1, rounds + 1):
                plain_s.append(upload_until_done(base, plain, f"plain-{k}", start))
                fix_s.append(upload_until_done(base, fixes, f"gnss-{k}", None))
            idle = psutil.Process(server.pid).memory_info().rss
            parallel = {}
            for name, path, tracks, st in (
                ("plain", plain, [f"plain-p{k}" for k in (1, 2, 3)], start),
                ("fixes", fixes, [f"gnss-{k}" for k in range(rounds + 1, rounds + 4)], None),
            ):
                time.sleep(2.0)
                with PeakRss(server.pid) as mem, ThreadPoolExecutor(3) as pool:
                    times = list(pool.map(lambda t: upload_until_done(base, path, t, st), tracks))  # noqa: B023
                parallel[name] = {"times": times, "peak_mb": mem.peak / 1e6}
        finally:
            server.terminate()
            try:
                server.wait(timeout=30)
            except subprocess.TimeoutExpired:  # busy with a request: not left behind
                server.kill()
                server.wait()
    return {"plain": plain_s, "fixes": fix_s, "idle_mb": idle / 1e6, "parallel": parallel}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--before", help="git revision to measure too, side by side")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--port", type=int, default=8013)
    ns = ap.parse_args()
    # stopped from outside: the servers' finally blocks still run
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    plain, fixes, feature, start = inputs()
    print(f"machine: {machine()}")
    print(
        f"log: {DURATION_S / 60:.0f} min at 1 kHz; CSV without fixes "
        f"{plain.stat().st_size / 1e6:.0f} MB, with a fix on every row "
        f"{fixes.stat().st_size / 1e6:.0f} MB; centerline "
        f"{len(feature['geometry']['coordinates'])} vertices"
    )
    cases = [("this tree", str(REPO))]
    with tempfile.TemporaryDirectory(prefix="bench-gnss-src-") as tmp:
        if ns.before:
            cases.insert(0, (f"before ({ns.before})", export(ns.before, tmp)))
        for name, src in cases:
            m = measure(src, ns.port, ns.rounds, plain, fixes, feature, start)
            p, f = min(m["plain"]), min(m["fixes"])
            par = m["parallel"]
            print(f"{name}:")
            print(
                f"  upload -> done, best of {ns.rounds}: without fixes {p:.2f} s, with a fix on "
                f"every row {f:.2f} s = {f / p:.2f}x (target <= 1.5x); all: "
                f"{', '.join(f'{x:.2f}' for x in m['plain'])} / "
                f"{', '.join(f'{x:.2f}' for x in m['fixes'])} s"
            )
            for k, label in (("plain", "without fixes"), ("fixes", "with fixes")):
                print(
                    f"  three in parallel {label}: "
                    f"{', '.join(f'{x:.1f}' for x in par[k]['times'])} s; server peak RSS "
                    f"{par[k]['peak_mb']:.0f} MB (idle before: {m['idle_mb']:.0f} MB; target "
                    "<= 1500 MB)"
                )
            sys.stdout.flush()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
