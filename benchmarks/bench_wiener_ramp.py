"""Processing cost of the Wiener axle tie that follows the speed, against one tie per run.

Run: ``python benchmarks/bench_wiener_ramp.py [--repeat 9]`` (about a minute). One 1 km
track (three zones, supports +-5 %), table1 at 24 m/s and on a +-10 % ramp (21.6 -> 26.4 m/s),
logged at 1 kHz by the tactical-MEMS grade; for each log the best of ``--repeat`` calls of
``process_run`` (everything a pass costs) and of the ``wiener`` inversion step alone, with the
tie evaluated at the run's delays (now) and at one delay for the whole run
(``engine.spectral.TIE_NODES_MAX`` set to 1: the former tie), interleaved so that a busy
machine slows both alike. Prints a markdown table.
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

from engine import spectral  # noqa: E402
from engine.methods import METHODS, MethodInput  # noqa: E402
from engine.pipeline import ProcessConfig, process_run  # noqa: E402
from engine.sensor import sensor_for_grade  # noqa: E402
from engine.setup import RunSetup, prepare_run  # noqa: E402
from engine.synthetic import make_run, make_track, to_runlog  # noqa: E402
from engine.track import SoftZone  # noqa: E402
from engine.vehicle import TABLE1  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--repeat", type=int, default=9)
    ns = p.parse_args()
    zones = [SoftZone(200, 203, 0.4), SoftZone(500, 506, 0.35), SoftZone(760, 770, 0.5)]
    track = make_track(1000.0, zones=zones, jitter=0.05, seed=2)
    nodes_max = spectral.TIE_NODES_MAX
    rows = []
    for name, speed in (("steady 24 m/s", 24.0), ("ramp 21.6 -> 26.4 m/s", (21.6, 26.4))):
        run = make_run(track=track, seed=2, speed=speed)
        log = to_runlog(run.sim, sensor_for_grade("tactical-mems", 1000.0, seed=1), seed=2)
        setup = RunSetup(start_chainage_m=run.start_chainage_m, config=ProcessConfig())
        chk = prepare_run(log, setup)
        cfg, pos = setup.config, chk.positions
        lo, hi = min(pos.front.min(), pos.rear.min()), max(pos.front.max(), pos.rear.max())
        step = cfg.grid_step_m
        grid = np.arange(np.ceil(lo / step) * step, hi + 1e-9, step)
        given = MethodInput(
            log=log, positions=pos, grid=grid, step_m=step, vehicle=TABLE1,
            f_lo_hz=chk.f_lo_hz, f_hi_hz=chk.f_hi_hz, lambda_min_m=cfg.lambda_min_m,
            lambda_max_m=cfg.lambda_max_m, taper=cfg.taper,
        )  # fmt: skip
        best = {k: [np.inf, np.inf] for k in ("one tie", "tie follows the speed")}
        for _ in range(ns.repeat + 1):  # the first round warms the caches
            for label, most in (("one tie", 1), ("tie follows the speed", nodes_max)):
                spectral.TIE_NODES_MAX = most
                t0 = time.perf_counter()
                process_run(prepare_run(log, setup))
                t1 = time.perf_counter()
                METHODS["wiener"](given)
                t2 = time.perf_counter()
                b = best[label]
                b[0], b[1] = min(b[0], t1 - t0), min(b[1], t2 - t1)
        spectral.TIE_NODES_MAX = nodes_max
        one, now = best["one tie"], best["tie follows the speed"]
        rows.append(
            f"| {name} | {1e3 * one[0]:.1f} | {1e3 * now[0]:.1f} | {now[0] / one[0]:.2f}x "
            f"| {1e3 * one[1]:.1f} | {1e3 * now[1]:.1f} |"
        )
    print(f"Machine: {machine()}. Best of {ns.repeat}, ms.\n")
    print("| run | pass, one tie | pass, tie follows the speed | ratio | inversion, one tie "
          "| inversion, follows |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
