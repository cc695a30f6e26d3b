"""Benchmark: calibrating a vehicle from 20 runs of 10 minutes (target <= 60 s on one core).

Command: ``python benchmarks/bench_calibration.py [--rate HZ] [--runs N] [--minutes M]``.

The logs (1 kHz by default) are the half-car's exact linear response, through its frequency
response ``H(ω)`` (:func:`engine.spectral.vehicle_response`), to a random German-low-
disturbance rail profile with a soft dip every ~250 m, ridden at 21-30 m/s with a slow ±3 %
speed wobble; realistic sensor noise and biases are added. (Generating 200 minutes with the
coupled FE forward model would take ~15 minutes; the calibration's cost depends only on the
log's length and rate.) The logging vehicle is the issue's coach (pitch inertia +30 %,
suspension -25 %, body +10 %); the registered one is Table 1. Single-threaded BLAS/FFT.
"""

from __future__ import annotations

import argparse
import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
import scipy.fft as sfft  # noqa: E402
from common import machine  # noqa: E402

from engine.calibration import CalibrationRun, calibrate  # noqa: E402
from engine.irregularity import random_profile  # noqa: E402
from engine.runlog import RunLog  # noqa: E402
from engine.spectral import vehicle_response  # noqa: E402
from engine.synthetic import REALISTIC_SENSOR  # noqa: E402
from engine.vehicle import TABLE1, VehicleParams  # noqa: E402

REAL = TABLE1.replace(Is=TABLE1.Is * 1.3, ks1=TABLE1.ks1 * 0.75, ks2=TABLE1.ks2 * 0.75,
                      ms=TABLE1.ms * 1.1)  # fmt: skip


def linear_run(
    vehicle: VehicleParams, minutes: float, rate_hz: float, speed: float, seed: int
) -> CalibrationRun:
    """A log of the half-car's exact linear response to a random rail (see module doc)."""
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate_hz
    n = int(minutes * 60 * rate_hz)
    t = np.arange(n) * dt
    v = speed * (1 + 0.03 * np.sin(2 * np.pi * t / 97.0 + rng.uniform(0, 6.28)))
    s = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt)])
    start = 20.0
    length = float(s[-1]) + 60.0
    prof = random_profile("german-low", length, seed=seed)
    dips = np.arange(150.0, length - 50.0, 250.0)

    def level(x: np.ndarray) -> np.ndarray:
        y = prof(x)
        for c in dips:  # a 0.3 mm Gaussian dip ~5 m long
            y = y - 3e-4 * np.exp(-0.5 * ((x - c) / 1.5) ** 2)
        return y

    y1 = level(start + s + vehicle.d1)
    y2 = level(start + s - vehicle.d2)
    nfft = sfft.next_fast_len(2 * n, real=True)
    w = 2 * np.pi * sfft.rfftfreq(nfft, dt)
    Y = np.stack([sfft.rfft(y1 - y1.mean(), nfft), sfft.rfft(y2 - y2.mean(), nfft)], axis=-1)
    H = vehicle_response(vehicle, np.maximum(w, 1e-6))
    AQ = np.einsum("mij,mj->mi", H, Y)
    a = sfft.irfft(AQ[:, 0], nfft)[:n]
    q = sfft.irfft(AQ[:, 1], nfft)[:n]
    sen = REALISTIC_SENSOR
    a = a + sen.accel_bias + rng.normal(0, sen.accel_noise, n)
    q = q + sen.gyro_bias + rng.normal(0, sen.gyro_noise, n)
    return CalibrationRun(RunLog(t, a, q, v), start, label=f"run {seed}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, default=1000.0, help="log sample rate, Hz")
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--minutes", type=float, default=10.0)
    ns = ap.parse_args()
    print(f"machine: {machine()} (BLAS/FFT single-threaded)")
    t0 = time.perf_counter()
    speeds = np.linspace(21.0, 30.0, ns.runs)
    runs = [linear_run(REAL, ns.minutes, ns.rate, float(v), i) for i, v in enumerate(speeds)]
    n_samples = sum(r.log.n for r in runs)
    print(f"generated {ns.runs} runs x {ns.minutes:g} min at {ns.rate:g} Hz "
          f"({n_samples / 1e6:.1f} M samples) in {time.perf_counter() - t0:.1f} s")  # fmt: skip
    t0 = time.perf_counter()
    res = calibrate(runs, TABLE1)
    took = time.perf_counter() - t0
    p = res.params
    errs = {
        "Is/ms": (p.Is / p.ms) / (REAL.Is / REAL.ms) - 1,
        "ks1/ms": (p.ks1 / p.ms) / (REAL.ks1 / REAL.ms) - 1,
        "ks2/ms": (p.ks2 / p.ms) / (REAL.ks2 / REAL.ms) - 1,
    }
    print(f"calibration of {ns.runs} runs x {ns.minutes:g} min: {took:.1f} s "
          f"({res.n_evaluations} objective evaluations; target <= 60 s)")  # fmt: skip
    print(res.message)
    print("fitted ratio errors vs truth: " + ", ".join(f"{k} {v:+.1%}" for k, v in errs.items()))


if __name__ == "__main__":
    main()
