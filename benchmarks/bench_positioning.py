"""Placing a run by its GNSS fixes: a 1-hour run with 36 000 fixes on a 100 km,
10 000-vertex centerline. Target: <= 1 s.

Run: ``python benchmarks/bench_positioning.py [--before REV]``

Second part: the same hour logged at 1 kHz with a fix on *every row* (3.6 M fixes,
each with noise of its own), placed as the service does (:func:`place_run`, then the fitted
chainage of every row). Target: <= 1 s with bounded memory. Each case runs in a fresh process
(wall time, CPU time, and the resident memory the placement adds at its peak, sampled every
10 ms); ``--before REV`` runs the same case on the engine of git revision ``REV`` too (exported
with ``git archive`` to a temporary directory), side by side in one run.

The line winds (curves of 1.5-5 km radius) through a local plane and is written as WGS84
lon/lat; the run drives 27.8 m/s for an hour (100 km) with its odometer 0.6 % long and fixes
at 10 Hz with 1.5 m noise per axis and an 0.7 m wandering bias (tau 10 s), 1 % outliers.
Timed: :func:`engine.positioning.place_run` (projection of every fix, robust and piecewise fit)
and the centerline's construction (validation, projection, STR-tree) separately; wall and CPU.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
# the engine under test: this tree's, or an exported revision's (--src, the child processes)
SRC = sys.argv[sys.argv.index("--src") + 1] if "--src" in sys.argv else str(REPO)
sys.path.insert(0, SRC)
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
import psutil  # noqa: E402
from common import machine  # noqa: E402
from pyproj import CRS, Transformer  # noqa: E402
from scipy.signal import lfilter  # noqa: E402

from engine.positioning import Centerline, geodesic_chainage, place_run  # noqa: E402

TO_LL = Transformer.from_crs(
    CRS.from_proj4("+proj=tmerc +lat_0=50 +lon_0=10 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m"),
    CRS.from_epsg(4326),
    always_xy=True,
)


def winding_line(length_m: float = 100_000.0, n: int = 10_000) -> tuple[np.ndarray, np.ndarray]:
    s = np.linspace(0.0, length_m, n)
    curvature = (1 / 1500.0) * np.sin(2 * np.pi * s / 9000.0) * (np.sin(s / 7000.0) > 0)
    heading = np.concatenate(
        [[0.0], np.cumsum(0.5 * (curvature[1:] + curvature[:-1]) * np.diff(s))]
    )
    x = np.concatenate([[0.0], np.cumsum(np.cos(heading[:-1]) * np.diff(s))])
    y = np.concatenate([[0.0], np.cumsum(np.sin(heading[:-1]) * np.diff(s))])
    lon, lat = TO_LL.transform(x - x.mean(), y - y.mean())
    return np.asarray(lon), np.asarray(lat)


def main() -> None:
    print("machine:", machine())
    lon_v, lat_v = winding_line()
    t0, c0 = time.perf_counter(), time.process_time()
    line = Centerline(lon_v, lat_v, geodesic_chainage(lon_v, lat_v, 11_900.0))
    build = (time.perf_counter() - t0, time.process_time() - c0)
    rng = np.random.default_rng(0)
    t = np.arange(0.0, 3600.0, 0.1)  # the fix times: 36 000 fixes
    true = line.start_chainage_m + 50.0 + 27.7 * t
    x, y = line.point_at(true)
    bias = np.zeros((t.size, 2))
    phi = np.exp(-0.1 / 10.0)
    kick = rng.normal(0, 0.7 * np.sqrt(1 - phi**2), (t.size, 2))
    for i in range(1, t.size):
        bias[i] = phi * bias[i - 1] + kick[i]
    err = rng.normal(0, 1.5, (t.size, 2)) + bias
    out = rng.random(t.size) < 0.01
    err[out] += rng.normal(0, 40.0, (int(out.sum()), 2))
    lon, lat = line._to_plane.transform(x + err[:, 0], y + err[:, 1], direction="INVERSE")
    odo = 1.006 * 27.7 * t
    times = []
    for _ in range(3):
        w0, p0 = time.perf_counter(), time.process_time()
        fit = place_run(line, t, odo, lat, lon)
        times.append((time.perf_counter() - w0, time.process_time() - p0))
    wall, cpu = min(times)
    e = np.abs(fit.chainage(odo) - true)
    print(
        f"centerline: {line.n_vertices} vertices, {line.length_m / 1000:.1f} km: built in "
        f"{build[0]:.3f} s wall ({build[1]:.3f} s CPU)"
    )
    print(
        f"place_run, {t.size} fixes: best of 3 {wall:.3f} s wall, {cpu:.3f} s CPU (target <= 1 s)"
    )
    print(
        f"fit: scale {fit.scale:.5f} (true {1 / 1.006:.5f}), {len(fit.knots_m) + 1} piece(s), "
        f"residual {fit.residual_rms_m:.2f} m RMS, {fit.n_used} used / {fit.n_rejected} "
        f"rejected; chainage error max {e.max():.2f} m, median {np.median(e):.2f} m"
    )


def every_row_child() -> None:
    """One placement of the 1-hour, 1 kHz, fix-on-every-row log; prints JSON figures."""
    lon_v, lat_v = winding_line()
    line = Centerline(lon_v, lat_v, geodesic_chainage(lon_v, lat_v, 11_900.0))
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 3600.0, 0.001)
    true = line.start_chainage_m + 50.0 + 27.7 * t
    x, y = line.point_at(true)
    phi = np.exp(-0.001 / 10.0)  # the wandering bias, tau 10 s, 0.7 m
    kick = rng.normal(0, 0.7 * np.sqrt(1 - phi**2), (2, t.size))
    bias = lfilter([1.0], [1.0, -phi], kick, axis=1)
    lon, lat = line._to_plane.transform(
        x + bias[0] + rng.normal(0, 1.5, t.size),
        y + bias[1] + rng.normal(0, 1.5, t.size),
        direction="INVERSE",
    )
    lon, lat = np.asarray(lon), np.asarray(lat)
    odo = 1.006 * 27.7 * t
    del x, y, bias, kick
    proc = psutil.Process()
    before = proc.memory_info().rss
    peak = [before]
    stop = threading.Event()

    def sample() -> None:
        while not stop.is_set():
            peak[0] = max(peak[0], proc.memory_info().rss)
            time.sleep(0.01)

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    w0, c0 = time.perf_counter(), time.process_time()
    fit = place_run(line, t, odo, lat, lon)
    chainage = fit.chainage(odo)  # what place_log writes into the log
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    stop.set()
    sampler.join()
    e = np.abs(chainage - true)
    print(json.dumps({
        "wall_s": wall, "cpu_s": cpu, "added_mb": (max(peak) - before) / 1e6,
        "n_fixes": fit.n_fixes, "n_considered": getattr(fit, "n_considered", fit.n_fixes),
        "err_max_m": float(e.max()), "err_median_m": float(np.median(e)),
        "scale": fit.scale,
    }))  # fmt: skip


def every_row(src: str) -> dict[str, float]:
    out = subprocess.run(
        [sys.executable, __file__, "--child", "--src", src],
        check=True, capture_output=True, text=True, env={**os.environ, "PYTHONPATH": src},
    )  # fmt: skip
    return dict(json.loads(out.stdout.strip().splitlines()[-1]))


def export(rev: str, into: str) -> str:
    """The tree of git revision ``rev`` under ``into`` (``git archive``)."""
    tar = Path(into) / "src.tar"
    with open(tar, "wb") as fh:
        subprocess.run(["git", "archive", rev], cwd=REPO, check=True, stdout=fh)
    with tarfile.open(tar) as tf:
        tf.extractall(Path(into) / "src", filter="data")
    return str(Path(into) / "src")


def every_row_report(before_rev: str | None) -> None:
    cases = [("this tree", str(REPO))]
    with tempfile.TemporaryDirectory(prefix="bench-positioning-") as tmp:
        if before_rev:
            cases.insert(0, (f"before ({before_rev})", export(before_rev, tmp)))
        print("1-hour 1 kHz log, a fix on every row (3.6 M fixes), placed and its chainage "
              "written; target <= 1 s")  # fmt: skip
        for name, src in cases:
            r = every_row(src)
            print(
                f"  {name:>20}: {r['wall_s']:6.2f} s wall, {r['cpu_s']:6.2f} s CPU, "
                f"+{r['added_mb']:5.0f} MB peak RSS; {r['n_considered']} of {r['n_fixes']} "
                f"fixes projected; scale {r['scale']:.5f}, chainage error max "
                f"{r['err_max_m']:.2f} m, median {r['err_median_m']:.2f} m"
            )


if __name__ == "__main__":
    if "--child" in sys.argv:
        every_row_child()
    else:
        ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
        ap.add_argument("--before", help="git revision to run the every-row case on too")
        ns = ap.parse_args()
        main()
        every_row_report(ns.before)
