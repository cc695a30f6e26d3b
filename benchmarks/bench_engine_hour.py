"""The engine's processing of the service benchmark's 1-hour log, in process.

    python benchmarks/bench_engine_hour.py [--repeats 3] [--engine-from DIR] [--duration S]

``engine.pipeline.process_run`` (spectral method, detection, stiffness-loss fits, wheel
forces) on the cached 1-hour 1 kHz log of ``benchmarks/common.py`` (3.6 M samples, 30 m/s,
55 soft zones; simulated once and cached), after one warm-up call; every call's wall time is
printed, each from the log to the result (``prepare_run``, then ``process_run``).
``--engine-from DIR`` imports the ``engine`` package of another checkout (a before/after side
by side on the same log and the same interpreter; a checkout from before ``engine.setup``
is called as it was, ``process_run(log, start_chainage_m=...)``). ``--duration`` takes a
shorter log (s), simulated and cached the same way.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--engine-from", type=Path, default=HERE.parent)
    p.add_argument("--duration", type=float, default=3600.0)
    ns = p.parse_args()
    sys.path.insert(0, str(HERE))
    sys.path.insert(0, str(ns.engine_from.resolve()))
    from common import hour_log, machine

    log, start = hour_log(ns.duration)
    process = _processing(start)
    process(log)
    times = []
    for _ in range(ns.repeats):
        t0 = time.perf_counter()
        res = process(log)
        times.append(time.perf_counter() - t0)
    print(f"machine: {machine()}; engine from {ns.engine_from}")
    print(f"process_run, {ns.duration:g} s log ({log.n} samples, {len(res.soft_spots)} zones): "
          + ", ".join(f"{t:.2f}" for t in times) + " s")  # fmt: skip
    return 0


def _processing(start: float) -> Callable[[Any], Any]:
    """The engine's way from a log to its result, as the imported checkout has it."""
    from engine.pipeline import process_run

    try:
        from engine.setup import RunSetup, prepare_run
    except ImportError:  # a checkout from before engine.setup
        return lambda log: process_run(log, start_chainage_m=start)
    return lambda log: process_run(prepare_run(log, RunSetup(start_chainage_m=start)))


if __name__ == "__main__":
    raise SystemExit(main())
