"""The engine's processing of the service benchmark's 1-hour log, in process.

    python benchmarks/bench_engine_hour.py [--repeats 3] [--engine-from DIR]

``engine.pipeline.process_run`` (spectral method, detection, stiffness-loss fits, wheel
forces) on the cached 1-hour 1 kHz log of ``benchmarks/common.py`` (3.6 M samples, 30 m/s,
55 soft zones; simulated once and cached), after one warm-up call; every call's wall time is
printed. ``--engine-from DIR`` imports the ``engine`` package of another checkout (a
before/after side by side on the same log and the same interpreter).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--engine-from", type=Path, default=HERE.parent)
    ns = p.parse_args()
    sys.path.insert(0, str(HERE))
    sys.path.insert(0, str(ns.engine_from.resolve()))
    from common import hour_log, machine

    from engine.pipeline import process_run
    from engine.setup import RunSetup, prepare_run

    log, start = hour_log()
    process_run(prepare_run(log, RunSetup(start_chainage_m=start)))
    times = []
    for _ in range(ns.repeats):
        t0 = time.perf_counter()
        res = process_run(prepare_run(log, RunSetup(start_chainage_m=start)))
        times.append(time.perf_counter() - t0)
    print(f"machine: {machine()}; engine from {ns.engine_from}")
    print(f"process_run, 1-hour log ({log.n} samples, {len(res.soft_spots)} zones): "
          + ", ".join(f"{t:.2f}" for t in times) + " s")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
