"""Wheel forces of the spectral methods against the forward model's true contact forces.

Run: ``python benchmarks/accuracy_wheel_force.py [--seeds 101 102 103] [--speed 42]``

Each run: 600 m of track with a 40 % soft zone over 6 m, +-5 % support scatter, rough
(German low-disturbance geometry) or smooth rail, Table 1's half car at 42 m/s, logged at
500 Hz by a sensor grade of :data:`engine.sensor.SENSOR_GRADES` (noise, bias and its wander,
resolution and jitter drawn per seed), start chainage logged 1.5 m off. Each method's wheel
forces are the pipeline's (its band spectrum through :func:`engine.wheel_force.force_spectrum`,
static load added) per sample; the error is their RMS difference from the simulated contact
force of each axle (both axles pooled) away from the log's first and last 40 m, kN.
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

from engine.methods import METHODS, MethodInput  # noqa: E402
from engine.sensor import sensor_for_grade  # noqa: E402
from engine.setup import PreparedRun, RunSetup, prepare_run  # noqa: E402
from engine.synthetic import SyntheticRun, make_run, make_track  # noqa: E402
from engine.track import SoftZone  # noqa: E402
from engine.vehicle import TABLE1  # noqa: E402
from engine.wheel_force import force_spectrum  # noqa: E402

GRADES = ("fibre-optic", "tactical-mems", "industrial-mems")
RAILS = {"rough": "german-low", "smooth": None}
METHOD_NAMES = ("wiener", "spectral")
TRIM_M = 40.0


def method_input(p: PreparedRun) -> MethodInput:
    """What the pipeline gives a method for this prepared run."""
    cfg = p.setup.config
    return MethodInput(
        log=p.log, positions=p.positions, grid=p.grid, step_m=cfg.grid_step_m,
        vehicle=p.setup.vehicle, f_lo_hz=p.f_lo_hz, f_hi_hz=p.f_hi_hz,
        lambda_min_m=cfg.lambda_min_m, lambda_max_m=cfg.lambda_max_m, taper=cfg.taper,
    )  # fmt: skip


def force_errors_kn(run: SyntheticRun, methods: tuple[str, ...] = METHOD_NAMES) -> dict[str, float]:
    """RMS error of each method's wheel forces against the truth, kN (both axles pooled)."""
    vehicle, log, sim = run.vehicle, run.log, run.sim
    p = prepare_run(log, RunSetup(start_chainage_m=run.logged_start_chainage_m, vehicle=vehicle))
    given = method_input(p)
    t = np.arange(log.n) * log.dt
    static = vehicle.static_axle_loads()
    truth, keep = [], []
    for x, contact in ((sim.x_front, sim.contact_front), (sim.x_rear, sim.contact_rear)):
        truth.append(np.interp(t, sim.t, contact))
        pos = np.interp(t, sim.t, x)
        keep.append((pos > pos.min() + TRIM_M) & (pos < pos.max() - TRIM_M))
    out = {}
    for name in methods:
        inv = METHODS[name](given)
        assert inv.band is not None
        dyn = force_spectrum(inv.band, vehicle).to_time()
        err = np.concatenate([(static[a] + dyn[a] - truth[a])[keep[a]] for a in range(2)])
        out[name] = float(np.sqrt(np.mean(err**2))) / 1e3
    return out


def make(grade: str, rail: str, seed: int, speed: float) -> SyntheticRun:
    track = make_track(600.0, zones=(SoftZone(300.0, 306.0, 0.4),), jitter=0.05,
                       irregularity=RAILS[rail], seed=seed)  # fmt: skip
    return make_run(track=track, vehicle=TABLE1, speed=speed, seed=seed, sim_rate_hz=500.0,
                    sensor=sensor_for_grade(grade, 500.0, seed), start_chainage_m=15.0,
                    start_error_m=1.5)  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[101, 102, 103])
    ap.add_argument("--speed", type=float, default=42.0)
    ap.add_argument("--grades", nargs="+", default=list(GRADES))
    args = ap.parse_args()
    t0 = time.perf_counter()
    print(f"speed {args.speed:g} m/s, seeds {args.seeds}; {machine()}")
    print(
        "| grade | rail | "
        + " | ".join(f"{m}, kN RMS" for m in METHOD_NAMES)
        + " | worst seed "
        + " / ".join(METHOD_NAMES)
        + ", kN | truth dynamic std, kN |"
    )
    print("|---|---|" + "---|" * (len(METHOD_NAMES) + 2))
    for grade in args.grades:
        for rail in RAILS:
            errs = {m: [] for m in METHOD_NAMES}
            spread = []
            for seed in args.seeds:
                run = make(grade, rail, seed, args.speed)
                for m, e in force_errors_kn(run).items():
                    errs[m].append(e)
                spread.append(float(np.std(run.sim.contact_front)) / 1e3)
            rms = [np.sqrt(np.mean(np.square(errs[m]))) for m in METHOD_NAMES]
            worst = [max(errs[m]) for m in METHOD_NAMES]
            print(f"| {grade} | {rail} | " + " | ".join(f"{r:.2f}" for r in rms)
                  + " | " + " / ".join(f"{w:.2f}" for w in worst)
                  + f" | {np.mean(spread):.2f} |", flush=True)  # fmt: skip
    print(f"total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
