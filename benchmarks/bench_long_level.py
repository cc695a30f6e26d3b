"""What the long level adds to a run's processing, the 1-hour log, in process.

    python benchmarks/bench_long_level.py [--repeats 3] [--duration S]

The service's worker inverts a queued run (``app.services.run_lifecycle.processing.invert``)
and, since the long level went off the path to done, inverts the long level
(``engine.track_quality.long_level``) after the run is answered done. This times the two
parts on the cached 1-hour 1 kHz log of ``benchmarks/common.py`` (prepared once, after one
warm-up of each), alternating: ``invert(..., long_level_at="later")`` (the path to done) and
``long_level`` (after it). CPU seconds of the process (``time.process_time``: both cores'
FFT threads counted) besides wall seconds: on a loaded machine the CPU is what compares.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--duration", type=float, default=3600.0)
    ns = p.parse_args()
    sys.path.insert(0, str(HERE))
    from common import hour_log, machine

    from app.services.run_lifecycle.processing import invert
    from engine.setup import RunSetup, prepare_run
    from engine.track_quality import long_level

    log, start = hour_log(ns.duration)
    run = prepare_run(log, RunSetup(start_chainage_m=start))
    parts = {
        "to done (invert, long level later)": lambda: invert(run, long_level_at="later"),
        "long level (after done)": lambda: long_level(run),
    }
    for work in parts.values():
        work()
    times: dict[str, list[tuple[float, float]]] = {k: [] for k in parts}
    for _ in range(ns.repeats):
        for name, work in parts.items():
            c0, t0 = time.process_time(), time.perf_counter()
            work()
            times[name].append((time.process_time() - c0, time.perf_counter() - t0))
    print(f"machine: {machine()}; {ns.duration:g} s log ({log.n} samples)")
    for name, tt in times.items():
        cpu = sorted(c for c, _ in tt)
        wall = sorted(w for _, w in tt)
        print(f"{name}: CPU {' '.join(f'{c:.2f}' for c in cpu)} s (best {cpu[0]:.2f}), "
              f"wall {' '.join(f'{w:.2f}' for w in wall)} s (best {wall[0]:.2f})")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
