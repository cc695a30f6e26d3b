"""Shared pieces of the benchmarks: machine description, timing, the long synthetic log."""

from __future__ import annotations

import os
import platform
import re
import statistics
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


def median_p95(ms: list[float]) -> str:
    """Median and 95th percentile (linear interpolation) of latencies in ms, for a report line."""
    return f"median {statistics.median(ms):.1f} ms, p95 {float(np.percentile(ms, 95)):.1f} ms"


def publish_section(lines: list[str], out: Path | None, heading: str = "") -> None:
    """Print a Markdown section and put it into the file ``out`` (None: print only).

    ``lines``' first and last line are the markers that delimit the section in the file: what
    stands between them there is replaced, else the section is appended (after ``heading``,
    when given, as the section is new to the file)."""
    block = "\n".join(lines)
    print(block)
    if out is None:
        return
    start, end = lines[0], lines[-1]
    text = out.read_text() if out.exists() else ""
    if start in text:
        text = re.sub(re.escape(start) + ".*?" + re.escape(end), lambda _: block, text, flags=re.S)
    else:
        text = text.rstrip("\n") + "\n\n" + heading + block + "\n"
    out.write_text(text)


def database_with_track(url: str, track_name: str) -> tuple[Any, int, int]:
    """A migrated service database at ``url`` with one UIC60 track named ``track_name``
    added: the database, the track's id and the id of its first (seeded) vehicle."""
    from app.db.migrate import upgrade
    from app.db.models import Track, Vehicle
    from app.db.session import Database

    db = Database(url)
    upgrade(db)
    with db.session() as s:
        vehicle = s.query(Vehicle).order_by(Vehicle.id).first()
        assert vehicle is not None
        track = Track(name=track_name, rail="UIC60", k_nominal=8e7, spacing=0.6,
                      EI=6.4155e6, mass_per_m=60.21, c_support=5e4)  # fmt: skip
        s.add(track)
        s.commit()
        return db, track.id, vehicle.id


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


SEPARATION_ONLY = ("separation.py", "matched_dips.py")
"""Engine modules that act only after the passes are processed (the separation and its
detector): a change to them leaves processed passes valid."""


def engine_digest(exclude: tuple[str, ...] = SEPARATION_ONLY) -> str:
    """SHA-256 (16 hex digits) of every engine source but ``exclude``: what a cached result
    computed by the engine depends on."""
    import hashlib

    root = Path(__file__).resolve().parents[1] / "engine"
    h = hashlib.sha256()
    for p in sorted(root.rglob("*.py")):
        if p.name not in exclude:
            h.update(str(p.relative_to(root)).encode())
            h.update(p.read_bytes())
    return h.hexdigest()[:16]


def cached(name: str, key: str, make: Callable[[], Any]) -> Any:
    """``make()``, kept under ``benchmarks/.cache/<name>/`` by ``key`` and the engine's
    digest (:func:`engine_digest`, the separation's modules left out) so that a change to
    the engine before the separation recomputes it. Set ``BENCH_NO_CACHE=1`` to recompute."""
    import hashlib
    import pickle

    folder = CACHE / name
    path = folder / (hashlib.sha256(f"{key}|{engine_digest()}".encode()).hexdigest()[:24] + ".pkl")
    if path.exists() and not os.environ.get("BENCH_NO_CACHE"):
        with path.open("rb") as f:
            return pickle.load(f)
    out = make()
    folder.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    with tmp.open("wb") as f:
        pickle.dump(out, f)
    tmp.replace(path)
    return out
