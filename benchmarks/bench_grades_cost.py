"""Processing cost per pass, inversion methods side by side on every IMU grade.

Run: ``python benchmarks/bench_grades_cost.py [--methods spectral,wiener] [--repeat 15]
[--passes 12]`` (about a minute). One 1 km track (three zones, supports +-5 %), table1 at
24 m/s, logged at 1 kHz by each grade of ``engine.sensor.SENSOR_GRADES``; for each log and
method the best of
``--repeat`` calls of ``process_run`` (everything a pass costs: checks, inversion, wheel forces,
detection, stiffness fits, detection limit) and of the inversion step alone, methods
interleaved so that a busy machine slows them alike. Then what integrating a pass adds since
the combined passes' soft spots are kept per chunk: one detection on the combination of
``--passes`` industrial-MEMS passes (``engine.accumulate.detect_on_aggregate``, the 1 km unit
and its 250 m margins as ``app.services.track.aggregate.detect_combined`` reads them), timed
afresh and as integration runs it (the unit's spots only, the earlier passes' residuals kept
from their arrival), so the cost per pass before (the first method) and now (the last method
plus that detection) stand side by side. Prints markdown tables. The whole pass as the service
does it: ``bench_pass_service.py``.
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
    ResidualCache,
    accumulate,
    detect_on_aggregate,
    residuals,
)
from engine.detect import DetectionConfig  # noqa: E402
from engine.methods import METHODS, MethodInput  # noqa: E402
from engine.pipeline import ProcessConfig, process_run  # noqa: E402
from engine.sensor import SENSOR_GRADES, sensor_for_grade  # noqa: E402
from engine.setup import RunSetup, prepare_run  # noqa: E402
from engine.synthetic import make_run, make_track, to_runlog  # noqa: E402
from engine.track import SoftZone  # noqa: E402
from engine.vehicle import TABLE1  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--methods", default="spectral,wiener")
    p.add_argument("--repeat", type=int, default=15)
    p.add_argument("--passes", type=int, default=12, help="passes combined per detection")
    ns = p.parse_args()
    methods = ns.methods.split(",")
    zones = [SoftZone(200, 203, 0.4), SoftZone(500, 506, 0.35), SoftZone(760, 770, 0.5)]
    run = make_run(track=make_track(1000.0, zones=zones, jitter=0.05, seed=2), seed=2, speed=24.0)
    best: dict[tuple[str, str], list[float]] = {}
    for grade in SENSOR_GRADES:
        log = to_runlog(run.sim, sensor_for_grade(grade, 1000.0, seed=1), seed=2)
        inputs = {}
        for m in methods:
            cfg = ProcessConfig(method=m)  # type: ignore[arg-type]
            process_run(
                prepare_run(log, RunSetup(start_chainage_m=run.start_chainage_m, config=cfg))
            )  # warm
            chk = prepare_run(log, RunSetup(start_chainage_m=run.start_chainage_m, config=cfg))
            pos, step = chk.positions, cfg.grid_step_m
            lo, hi = min(pos.front.min(), pos.rear.min()), max(pos.front.max(), pos.rear.max())
            grid = np.arange(np.ceil(lo / step) * step, hi + 1e-9, step)
            inputs[m] = (cfg, MethodInput(
                log=log, positions=pos, grid=grid, step_m=step, vehicle=TABLE1,
                f_lo_hz=chk.f_lo_hz, f_hi_hz=chk.f_hi_hz, lambda_min_m=cfg.lambda_min_m,
                lambda_max_m=cfg.lambda_max_m, taper=cfg.taper,
            ))  # fmt: skip
            best[(grade, m)] = [np.inf, np.inf]
        for _ in range(ns.repeat):
            for m in methods:
                cfg, given = inputs[m]
                t0 = time.perf_counter()
                process_run(
                    prepare_run(log, RunSetup(start_chainage_m=run.start_chainage_m, config=cfg))
                )
                t1 = time.perf_counter()
                METHODS[m](given)
                t2 = time.perf_counter()
                b = best[(grade, m)]
                b[0], b[1] = min(b[0], t1 - t0), min(b[1], t2 - t1)
    print(f"Machine: {machine()}. Best of {ns.repeat}, ms.\n")
    print("| grade | " + " | ".join(f"{m}: pass | {m}: inversion" for m in methods) + " |")
    print("|---|" + "---|---|" * len(methods))
    for grade in SENSOR_GRADES:
        cells = [f"{1e3 * v:.1f}" for m in methods for v in best[(grade, m)]]
        print(f"| {grade} | " + " | ".join(cells) + " |")
    tot = {m: sum(best[(g, m)][0] for g in SENSOR_GRADES) for m in methods}
    ratio = [f"{m} {1e3 * tot[m]:.1f} ms ({tot[m] / tot[methods[0]]:.2f}x)" for m in methods]
    print("\nPer pass, summed over the grades: " + ", ".join(ratio))

    cfg = ProcessConfig(method=methods[-1])  # type: ignore[arg-type]
    got = []
    for i in range(ns.passes):
        log = to_runlog(run.sim, sensor_for_grade("industrial-mems", 1000.0, seed=10 + i), seed=i)
        setup = RunSetup(run.start_chainage_m + 0.1 * i, config=cfg)
        res = process_run(prepare_run(log, setup))
        got.append((res.chainage_m, res.level_mm))
    grid, levels, _ = accumulate([c for c, _ in got], [lv for _, lv in got])
    # the unit and its margins: 1.5 km of grid, the passes covering their 1 km of it
    wide = np.arange(grid[0] - 250.0, grid[0] + 1250.0, grid[1] - grid[0])
    lv = np.full((levels.shape[0], wide.size), np.nan)
    lv[:, 1000 : 1000 + levels.shape[1]] = levels[:, : max(0, wide.size - 1000)]
    load = float(np.mean(TABLE1.static_axle_loads()))
    unit = (float(wide[1000]), float(wide[1000]) + 1000.0)
    window = DetectionConfig().baseline_window_m
    t_det, t_int = np.inf, np.inf
    for _ in range(ns.repeat):
        t0 = time.perf_counter()
        detect_on_aggregate(wide, lv, load_n=load)
        t_det = min(t_det, time.perf_counter() - t0)
        # as integration runs it: the unit's spots only, the earlier passes' residuals kept
        # from their own arrival
        cache = ResidualCache()
        residuals(lv[:-1], grid[1] - grid[0], window, cache=cache)
        t0 = time.perf_counter()
        detect_on_aggregate(wide, lv, load_n=load, peaks_in_m=unit, cache=cache)
        t_int = min(t_int, time.perf_counter() - t0)
    before = {g: best[(g, methods[0])][0] for g in SENSOR_GRADES}
    after = {g: best[(g, methods[-1])][0] + t_int for g in SENSOR_GRADES}
    print(f"\nCombined detection of {ns.passes} passes over one unit and its margins: "
          f"{1e3 * t_det:.1f} ms everything detected afresh, {1e3 * t_int:.1f} ms as a pass's "
          "integration runs it (the unit's spots, earlier passes' residuals kept).\n")  # fmt: skip
    print(f"| grade | before: {methods[0]} pass, ms | now: {methods[-1]} pass + combined "
          "detection, ms | ratio |")  # fmt: skip
    print("|---|---|---|---|")
    for g in SENSOR_GRADES:
        print(f"| {g} | {1e3 * before[g]:.1f} | {1e3 * after[g]:.1f} | "
              f"{after[g] / before[g]:.2f}x |")  # fmt: skip


if __name__ == "__main__":
    main()
