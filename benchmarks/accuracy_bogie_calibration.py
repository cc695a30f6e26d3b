"""What calibration recovers of a bogie vehicle's registration error, and from how many passes.

Run: ``python benchmarks/accuracy_bogie_calibration.py [--seed 6000] [--passes 2,4,8]``

The machinery of ``accuracy_bogie_separation.py``: per vehicle (the coach and the wagon
presets) and per parameter of ``separation_false_alarms.OFF_FIELDS`` (and none, the control)
the true vehicle is the preset with that parameter ×0.9 or ×1.1; it drives passes over a
zone-free track of German low-disturbance rail (550 m, 5 % support scatter; one track per
vehicle, parameter and factor, drawn from the seed) at random speeds (coach 24-35 m/s, wagon
15-25 m/s), MEMS sensor at 500 Hz, logged starts off by up to 1.8 m. The preset is calibrated
on the first N of those passes (``engine.calibration.calibrate``) with the default fit
(body pitch inertia and secondary stiffness) and with the primary stiffness fitted too
(``fit=("Is", "ks", "kp")``). Reported per row: each fitted parameter as a factor on the
preset (``*`` significant, else not), whether the result is applied (the service applies a
significant result, every fitted parameter of it), and the front/rear disagreement before
and after.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from benchmarks.accuracy_bogie_separation import _off  # noqa: E402
from benchmarks.separation_false_alarms import OFF_FIELDS  # noqa: E402
from engine.bogie import FREIGHT_WAGON, PASSENGER_COACH  # noqa: E402
from engine.calibration import (  # noqa: E402
    CalibrationConfig,
    CalibrationResult,
    CalibrationRun,
    calibrate,
)
from engine.synthetic import REALISTIC_SENSOR, make_run, make_track  # noqa: E402

PRESETS = {"coach": (PASSENGER_COACH, (24.0, 35.0)), "wagon": (FREIGHT_WAGON, (15.0, 25.0))}
"""Per vehicle: its preset and the speed range of its passes, m/s."""

FITS = {"default": CalibrationConfig(), "with kp": CalibrationConfig(fit=("Is", "ks", "kp"))}

SHORT = {
    "body_pitch_inertia_kgm2": "Is",
    "secondary_k_n_per_m": "ks",
    "primary_k_n_per_m": "kp",
}


def cell(cal: CalibrationResult) -> str:
    """Fitted factors (``*``: significant), those applied, disagreement before -> after."""
    parts = [
        f"{SHORT.get(name, name)} ×{value / before:.2f}{'*' if f.significant else ''}"
        for f in cal.fitted
        for (name, value), before in zip(f.after.items(), f.before.values(), strict=True)
    ]
    applied = (
        "applied " + "+".join(f.name for f in cal.fitted if f.applied) if cal.significant else "not"
    )
    return f"{', '.join(parts)} ({applied}; {cal.objective_before:.1%} → {cal.objective_after:.1%})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=6000)
    ap.add_argument("--passes", default="2,4,8")
    args = ap.parse_args()
    counts = [int(n) for n in args.passes.split(",")]
    sensor = dataclasses.replace(REALISTIC_SENSOR, sample_rate_hz=500.0)
    heads = [f"{n} passes, {fit}" for fit in FITS for n in counts]
    print("| vehicle | true (× preset) | " + " | ".join(heads) + " |")
    print("|---|---|" + "---|" * len(heads))
    seed = args.seed
    for kind, (preset, (v_lo, v_hi)) in PRESETS.items():
        for field in ("none", *OFF_FIELDS):
            for factor in (0.9, 1.1) if field != "none" else (1.0,):
                seed += 1
                rng = np.random.default_rng(seed)
                true = preset if field == "none" else _off(preset, {field: factor})
                track = make_track(550.0, jitter=0.05, irregularity="german-low", seed=seed)
                runs = [
                    make_run(track=track, vehicle=true, speed=float(rng.uniform(v_lo, v_hi)),
                             sensor=sensor, sim_rate_hz=500.0, seed=seed * 100 + i,
                             start_chainage_m=12.0, start_error_m=float(rng.uniform(-1.8, 1.8)))
                    for i in range(max(counts))
                ]  # fmt: skip
                cal_runs = [
                    CalibrationRun(r.log, r.logged_start_chainage_m, label=f"pass {i}")
                    for i, r in enumerate(runs)
                ]
                cells = [
                    cell(calibrate(cal_runs[:n], preset, cfg))
                    for cfg in FITS.values()
                    for n in counts
                ]
                true_text = "as preset" if field == "none" else f"{field} ×{factor:.1f}"
                print(f"| {kind} | {true_text} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
