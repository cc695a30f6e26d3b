"""Shared pieces of the benchmarks: machine description, timing, the long synthetic log."""

from __future__ import annotations

import os
import platform
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

CACHE = Path(__file__).resolve().parent / ".cache"


def machine() -> str:
    """One line describing the machine the numbers come from."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (
        f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}"
    )


def best_of(fn: Callable[[], Any], repeat: int = 3) -> tuple[float, Any]:
    """Smallest wall time of ``repeat`` calls (s) and the last result."""
    best = float("inf")
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def hour_log(duration_s: float = 3600.0, speed: float = 30.0, seed: int = 0):
    """A 1 kHz log of ``duration_s`` seconds over a long track with a soft zone every 2 km.

    Simulated with the engine's forward model (realistic sensor) once and cached under
    ``benchmarks/.cache`` (it takes a few minutes for one hour).
    """
    from engine.runlog import RunLog
    from engine.sensor import SensorModel
    from engine.simulate import simulate
    from engine.synthetic import to_runlog
    from engine.track import SoftZone, Track

    CACHE.mkdir(exist_ok=True)
    path = CACHE / f"log_{int(duration_s)}s_{speed:g}mps_{seed}.npz"
    if path.exists():
        d = np.load(path)
        return RunLog(d["t"], d["a"], d["q"], d["v"]), float(d["start"])
    length = speed * duration_s + 60.0
    zones = [SoftZone(x, x + 5.0, 0.4) for x in np.arange(1000.0, length - 100.0, 2000.0)]
    rng = np.random.default_rng(seed)
    base = Track(length, zones=zones)
    k = base.k * np.clip(1 + 0.05 * rng.standard_normal(base.n_supports), 0.5, 1.5)
    track = Track(length, support_stiffness=k)
    start = 20.0
    sim = simulate(track, speed=speed, duration=duration_s - 1e-3, start_chainage_m=start)
    sensor = SensorModel(accel_noise=0.005, gyro_noise=1e-4, accel_bias=0.02, gyro_bias=2e-4,
                         digits=8)  # fmt: skip
    log = to_runlog(sim, sensor, seed=seed + 1)
    np.savez(path, t=log.time_s, a=log.accel_z_mps2, q=log.pitch_rate_radps,
             v=log.speed_mps, start=start)  # fmt: skip
    return log, start
