"""Separation benchmark: geometry vs stiffness over 50 runs of 10 km.

    python benchmarks/bench_separation.py [--runs 50] [--length-km 10] [--repeats 3]

The passes are generated, not inverted from 50 simulated 10 km logs (hours of forward
simulation), with the content the estimator works on: German low-disturbance geometry
(band-passed to 3-40 m like the product's levels), the beam-on-supports deflection of a track
with 5 soft zones per km (3-10 m, 30-60 % loss, each zone's dip computed with the static beam
model and added), per-pass wheel forces (70 % coaches at 88 kN +-20 % passenger load, 30 %
heavy vehicles at 196 kN, with a dynamic part along chainage), level noise 0.03 mm. Timed:
``separate()`` on the aligned passes (best of ``--repeats``), ``align_passes()`` once, and a
2 km ``SeparationResult.window()`` read. Also reported: zones found / false against the truth.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

# like the other engine benchmarks: one BLAS thread (set before numpy is imported)
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import machine  # noqa: E402

from engine.chainage import bandpass_distance  # noqa: E402
from engine.irregularity import random_profile  # noqa: E402
from engine.separation import Pass, align_passes, separate  # noqa: E402
from engine.stiffness import QuasiStaticModel  # noqa: E402
from engine.track import TrackParams  # noqa: E402

STEP = 0.25


def unit_deflection(grid: np.ndarray, zones: list[tuple[float, float, float]]) -> np.ndarray:
    """Extra level (mm per N, negative = down) of the soft zones against nominal track."""
    trk = TrackParams()
    out = np.zeros(grid.size)
    for a, b, loss in zones:
        i0, i1 = np.searchsorted(grid, [a - 40.0, b + 40.0])
        g = grid[i0:i1]
        m = QuasiStaticModel(trk, g[0], g[-1], g, 1.0)
        out[i0:i1] += (m.level(m.factors(a, b, loss)) - m.level(np.ones(m.node_x.size))) * 1e3
    return out


def make_passes(n_runs: int, length_m: float, seed: int = 0):
    rng = np.random.default_rng(seed)
    grid = np.arange(0.0, length_m, STEP)
    geom = random_profile("german-low", length_m, seed=seed)(grid) * 1e3
    zones = []
    x = 100.0
    while x < length_m - 100.0:
        ln = float(rng.choice([3.0, 4.0, 6.0, 8.0, 10.0]))
        zones.append(
            (round(x / 0.6) * 0.6, round((x + ln) / 0.6) * 0.6, float(rng.uniform(0.3, 0.6)))
        )
        x += ln + float(rng.uniform(120.0, 280.0))
    dw = unit_deflection(grid, zones)
    passes = []
    for j in range(n_runs):
        heavy = j % 10 in (3, 6, 9)
        f0 = 196.2e3 if heavy else 88.3e3 * float(rng.uniform(0.85, 1.2))
        dyn = bandpass_distance(rng.normal(0, 1, grid.size), STEP, 3.0, 40.0)
        force = f0 * (1 + 0.01 * dyn / dyn.std())
        y = geom + force * dw + rng.normal(0, 0.03, grid.size)
        lv = bandpass_distance(y, STEP, 3.0, 40.0)
        off = float(rng.uniform(-2, 2))
        lo, hi = rng.integers(0, 40), grid.size - rng.integers(0, 40)
        passes.append(Pass(grid[lo:hi] + off, lv[lo:hi], force[lo:hi], "run", f"r{j}"))
    return passes, zones


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--runs", type=int, default=50)
    p.add_argument("--length-km", type=float, default=10.0)
    p.add_argument("--repeats", type=int, default=3)
    ns = p.parse_args()
    passes, zones = make_passes(ns.runs, ns.length_km * 1e3)
    t0 = time.perf_counter()
    aligned, offsets = align_passes(passes)
    t_align = time.perf_counter() - t0
    times, cpu = [], []
    for _ in range(ns.repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        res = separate(aligned)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    reads = []
    rng = np.random.default_rng(1)
    for _ in range(20):
        a = float(rng.uniform(0, ns.length_km * 1e3 - 2000))
        t0 = time.perf_counter()
        res.window(a, a + 2000.0)
        reads.append(time.perf_counter() - t0)
    found = sum(
        any(s.end_m >= a - 2 and s.start_m <= b + 2 for s in res.soft_spots) for a, b, _ in zones
    )
    false = sum(
        not any(s.end_m >= a - 2 and s.start_m <= b + 2 for a, b, _ in zones)
        for s in res.soft_spots
    )
    print(f"machine: {machine()}")
    print(f"{ns.runs} passes x {ns.length_km:g} km ({res.chainage_m.size} grid points)")
    print(f"separate(): best {min(times):.3f} s, median {statistics.median(times):.3f} s wall; "
          f"best {min(cpu):.3f} s CPU (load average {os.getloadavg()[0]:.1f})")  # fmt: skip
    print(f"align_passes(): {t_align:.3f} s")
    print(f"window(2 km): median {1e3 * statistics.median(reads):.2f} ms, "
          f"max {1e3 * max(reads):.2f} ms")  # fmt: skip
    print(f"zones found {found}/{len(zones)}, false {false}, separable "
          f"{100 * res.separable[res.n_passes > 0].mean():.1f} % of covered points")  # fmt: skip


if __name__ == "__main__":
    main()
