"""A 1-hour log of a bogie vehicle processed side by side with a half car's.

    python benchmarks/bench_bogie_hour.py [--repeats 3] [--piece-s 300]

Each vehicle (the passenger-coach preset, the Table 1 half car) runs ``--piece-s`` seconds at
30 m/s over a track with a 40 % soft zone every 2 km and 5 % support scatter, written by the
realistic sensor (simulated once, cached under ``benchmarks/.cache``); the piece is repeated
to one hour (3.6 M samples: simulating a whole hour of a four-wheel vehicle takes half an
hour, and the processing cost does not depend on what the samples hold). Then
``engine.pipeline.process_run`` (spectral method, detection, stiffness fits, wheel forces)
runs on each log with its own vehicle, alternately, after one warm-up each; every wall time
and the bogie/half-car ratio of the best times are printed.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

from common import CACHE, machine  # noqa: E402

from engine.bogie import PASSENGER_COACH  # noqa: E402
from engine.pipeline import process_run  # noqa: E402
from engine.runlog import RunLog  # noqa: E402
from engine.sensor import SensorModel  # noqa: E402
from engine.setup import RunSetup, prepare_run  # noqa: E402
from engine.simulate import simulate  # noqa: E402
from engine.synthetic import to_runlog  # noqa: E402
from engine.track import SoftZone, Track  # noqa: E402
from engine.vehicle import TABLE1  # noqa: E402
from engine.vehicle_kinds import Vehicle  # noqa: E402

SPEED = 30.0
START = 30.0


def piece(vehicle: Vehicle, name: str, duration_s: float) -> RunLog:
    CACHE.mkdir(exist_ok=True)
    path = CACHE / f"piece_{name}_{int(duration_s)}s.npz"
    if path.exists():
        d = np.load(path)
        return RunLog(d["t"], d["a"], d["q"], d["v"])
    length = SPEED * duration_s + 60.0
    zones = [SoftZone(x, x + 5.0, 0.4) for x in np.arange(1000.0, length - 100.0, 2000.0)]
    rng = np.random.default_rng(0)
    base = Track(length, zones=zones)
    k = base.k * np.clip(1 + 0.05 * rng.standard_normal(base.n_supports), 0.5, 1.5)
    sim = simulate(Track(length, support_stiffness=k), vehicle=vehicle, speed=SPEED,
                   duration=duration_s - 1e-3, start_chainage_m=START)  # fmt: skip
    sensor = SensorModel(accel_noise=0.005, gyro_noise=1e-4, accel_bias=0.02, gyro_bias=2e-4,
                         digits=8)  # fmt: skip
    log = to_runlog(sim, sensor, seed=1)
    np.savez(path, t=log.time_s, a=log.accel_z_mps2, q=log.pitch_rate_radps, v=log.speed_mps)
    return log


def hour(p: RunLog) -> RunLog:
    reps = int(np.ceil(3600.0 / (p.n * p.dt)))
    a = np.tile(p.accel_z_mps2, reps)[: int(3600 / p.dt)]
    q = np.tile(p.pitch_rate_radps, reps)[: a.size]
    t = np.arange(a.size) * p.dt
    return RunLog(t, a, q, np.full(a.size, SPEED))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--piece-s", type=float, default=300.0)
    ns = ap.parse_args()
    logs = {
        "half car (table1)": (hour(piece(TABLE1, "table1", ns.piece_s)), TABLE1),
        "bogie (passenger_coach)": (hour(piece(PASSENGER_COACH, "coach", ns.piece_s)),
                                    PASSENGER_COACH),
    }  # fmt: skip
    times: dict[str, list[float]] = {k: [] for k in logs}
    zones: dict[str, int] = {}
    for log, vehicle in logs.values():
        process_run(prepare_run(log, RunSetup(start_chainage_m=START, vehicle=vehicle)))  # warm-up
    for _ in range(ns.repeats):
        for name, (log, vehicle) in logs.items():
            t0 = time.perf_counter()
            res = process_run(prepare_run(log, RunSetup(start_chainage_m=START, vehicle=vehicle)))
            times[name].append(time.perf_counter() - t0)
            zones[name] = len(res.soft_spots)
    print(f"machine: {machine()}")
    for name, ts in times.items():
        n = logs[name][0].n
        print(f"{name}: 1-hour log ({n} samples, {zones[name]} zones): "
              + ", ".join(f"{t:.2f}" for t in ts) + " s")  # fmt: skip
    best = [min(ts) for ts in times.values()]
    print(f"bogie / half car (best of {ns.repeats}): {best[1] / best[0]:.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
