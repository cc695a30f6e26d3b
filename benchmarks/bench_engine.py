"""Engine speed benchmarks. Run: ``python benchmarks/bench_engine.py``.

1. Forward simulation of a 1 km track at 30 m/s, 1 kHz (~32 000 steps).
2. Direct inverse of a 1-hour 1 kHz log (3.6 M samples), vectorised vs per-sample loop.
3. Robust inversion + soft-spot detection of a 1-hour 1 kHz log; peak memory against the
   log's own size for half an hour and one hour (proportionality).

Each timing is the best of several runs on one core (numpy's threads limited to one).
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
from common import best_of, hour_log, machine  # noqa: E402

from engine.direct import direct_inverse, direct_inverse_loop  # noqa: E402
from engine.pipeline import process_run  # noqa: E402
from engine.setup import RunSetup, prepare_run
from engine.simulate import simulate  # noqa: E402
from engine.track import SoftZone, Track  # noqa: E402


def bench_forward() -> None:
    track = Track(1000.0, zones=[SoftZone(500, 505, 0.5)])
    dofs = 2 * track.n_supports + 4
    t, sim = best_of(
        lambda: simulate(track, speed=30.0, duration=31.9, start_chainage_m=10.0), repeat=3
    )
    print(f"forward 1 km ({dofs} DOF) 30 m/s 1 kHz, {sim.t.size} steps: {t:.2f} s "
          f"(target <= 3 s)")  # fmt: skip


def bench_direct(loop_samples: int) -> None:
    rng = np.random.default_rng(0)
    n = 3_600_000
    a = rng.normal(0, 0.01, n)
    q = rng.normal(0, 1e-4, n)
    t_vec, _ = best_of(lambda: direct_inverse(a, q, 1e-3), repeat=3)
    m = min(n, loop_samples)
    t0 = time.perf_counter()
    direct_inverse_loop(a[:m], q[:m], 1e-3)
    t_loop = (time.perf_counter() - t0) * n / m
    note = "" if m == n else f" (loop timed on {m} samples, scaled)"
    print(f"direct inverse 3.6 M samples: vectorised {t_vec:.2f} s, per-sample loop "
          f"{t_loop:.1f} s, ratio {t_loop / t_vec:.0f}x{note} (target <= 2 s)")  # fmt: skip


def bench_pipeline() -> None:
    for dur in (1800.0, 3600.0):
        log, start = hour_log(dur)
        t, res = best_of(
            lambda log=log, start=start: process_run(
                prepare_run(log, RunSetup(start_chainage_m=start))
            ),
            3,
        )
        tracemalloc.start()
        process_run(prepare_run(log, RunSetup(start_chainage_m=start)))
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        size = 4 * log.n * 8
        print(f"robust inversion + detection, {dur / 3600:.1f} h at 1 kHz ({log.n} samples, "
              f"{res.chainage_m.size} grid points, {len(res.soft_spots)} zones): {t:.2f} s; "
              f"peak memory {peak / 1e6:.0f} MB = {peak / size:.1f}x the log's arrays "
              f"({size / 1e6:.0f} MB)")  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--loop-samples", type=int, default=3_600_000,
                   help="samples for the per-sample loop (scaled to 3.6 M)")  # fmt: skip
    p.add_argument("--skip-pipeline", action="store_true")
    ns = p.parse_args()
    print(f"machine: {machine()}")
    bench_forward()
    bench_direct(ns.loop_samples)
    if not ns.skip_pipeline:
        bench_pipeline()


if __name__ == "__main__":
    main()
