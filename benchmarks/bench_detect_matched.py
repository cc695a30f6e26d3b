"""What the detector's running means (``DetectionConfig.matched_m``) cost, side by side.

Run: ``python benchmarks/bench_detect_matched.py [--repeat 7] [--passes 12]`` (about a minute).
One 1 km track (one zone, supports +-5 %), table1 at 22 m/s, logged at 1 kHz by an
industrial-MEMS sensor: ``process_run`` (everything a pass costs) with the residual alone
(``matched_m=()``) and with the default widths, interleaved so a busy machine slows both
alike; then one detection on the combination of ``--passes`` such passes
(``engine.accumulate.detect_on_aggregate``) both ways. CPU seconds (all threads), median and
best of ``--repeat``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
from common import machine  # noqa: E402

from engine.accumulate import (  # noqa: E402
    COMBINED_NOISE_FACTOR,
    accumulate,
    detect_on_aggregate,
)
from engine.detect import DetectionConfig  # noqa: E402
from engine.pipeline import ProcessConfig, process_run  # noqa: E402
from engine.sensor import sensor_for_grade  # noqa: E402
from engine.setup import RunSetup, prepare_run  # noqa: E402
from engine.synthetic import make_run, to_runlog  # noqa: E402
from engine.track import SoftZone  # noqa: E402
from engine.vehicle import TABLE1  # noqa: E402


def cpu(f: object, repeat: int) -> list[float]:
    """CPU seconds of ``repeat`` calls of ``f``."""
    out = []
    for _ in range(repeat):
        t0 = time.process_time()
        f()  # type: ignore[operator]
        out.append(time.process_time() - t0)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--repeat", type=int, default=7)
    p.add_argument("--passes", type=int, default=12)
    ns = p.parse_args()
    run = make_run(length=1000.0, zones=[SoftZone(300.0, 306.0, 0.4)], jitter=0.05, speed=22.0,
                   seed=3)  # fmt: skip
    logs = [
        to_runlog(run.sim, sensor_for_grade("industrial-mems", 1000.0, seed=s), seed=s + 50)
        for s in range(ns.passes)
    ]
    ways = {
        "residual alone": DetectionConfig(matched_m=()),
        "with running means (default)": DetectionConfig(),
    }

    def one(det: DetectionConfig, log: object = logs[0]) -> object:
        setup = RunSetup(start_chainage_m=run.start_chainage_m, config=ProcessConfig(detection=det))
        return process_run(prepare_run(log, setup))  # type: ignore[arg-type]

    results = [one(ways["residual alone"], lg) for lg in logs]
    grid, levels, _ = accumulate([r.chainage_m for r in results], [r.level_mm for r in results])
    load = float(np.mean(TABLE1.static_axle_loads()))
    agg = {
        "residual alone": DetectionConfig(matched_m=(), noise_factor=COMBINED_NOISE_FACTOR),
        "with running means (default)": None,
    }
    t_pass: dict[str, list[float]] = {k: [] for k in ways}
    t_agg: dict[str, list[float]] = {k: [] for k in ways}
    for k in ways:  # warm the caches (depth curves, FFT plans)
        one(ways[k])
    for _ in range(ns.repeat):
        for k in ways:
            t_pass[k] += cpu(lambda k=k: one(ways[k]), 1)
            t_agg[k] += cpu(
                lambda k=k: detect_on_aggregate(grid, levels, load_n=load, config=agg[k]), 1
            )
    print(f"Machine: {machine()}. CPU s, median (best) of {ns.repeat}.\n")
    print(f"| detector | one 1 km pass, process_run | detection on {ns.passes} passes |")
    print("|---|---|---|")
    for k in ways:
        a, b = t_pass[k], t_agg[k]
        print(f"| {k} | {np.median(a):.3f} ({min(a):.3f}) | {np.median(b):.3f} ({min(b):.3f}) |")


if __name__ == "__main__":
    main()
