"""What telling provisional separated results costs a read (the register and the stiffness).

    PYTHONPATH=$PWD python benchmarks/bench_provisional_reads.py [--spots 2000] [--runs 10]

A fresh SQLite database (migrated like the app does) gets one track of 100 km with ``--runs``
done runs (half of them declaring their load, so every separated spot is provisional and its
reason is written), the separation's chunks over the whole line and ``--spots`` separated soft
spots spread along it, each supported by every run. Timed in process CPU time
(``time.process_time``), interleaved, median of ``--repeats``:

- the defects answer's service work (``track_register`` and ``stiffness_notes``) without and
  with ``provisional_notes``;
- the stiffness answer over a 2 km window and over the whole line: ``read_stiffness`` with
  the contributors' vehicle names (what the answer read before) against
  ``stiffness_with_vehicles`` (the names, the window's and each spot's verdict);
- ``provisional_notes`` alone on the register's defects.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
from common import machine  # noqa: E402
from sqlalchemy import insert, select  # noqa: E402

from app.db.migrate import upgrade  # noqa: E402
from app.db.models import Run, Track, TrackStiffness, TrackStiffnessSpot, Vehicle  # noqa: E402
from app.db.session import Database  # noqa: E402
from app.services.track.register import (  # noqa: E402
    provisional_notes,
    stiffness_notes,
    track_register,
)
from app.services.track.separation_history import record_separation  # noqa: E402
from app.services.track.separation_store import (  # noqa: E402
    CHUNK_POINTS,
    GRID_STEP_M,
    STIFFNESS_ARRAYS,
    read_stiffness,
    stiffness_with_vehicles,
)

LENGTH_M = 100_000.0
LOADS = (60e3, 100e3)
T0 = datetime(2026, 1, 5, 7, 0, tzinfo=UTC)


def build(db: Database, n_spots: int, n_runs: int) -> tuple[int, list[int]]:
    """The track, its runs, its separation's chunks and spots; (track id, run ids)."""
    with db.session() as s:
        track = Track(name="bench", rail="UIC60", k_nominal=80e6, spacing=0.6, EI=6.42e6,
                      mass_per_m=60.34, c_support=50e3)  # fmt: skip
        s.add(track)
        s.flush()
        vid = s.scalar(select(Vehicle.id).where(Vehicle.name == "table1"))
        ids = []
        for i in range(n_runs):
            run = Run(
                track_id=track.id, vehicle_id=vid, source="json", direction="increasing",
                sample_rate_hz=1000.0, n_samples=1, duration_s=1.0, speed_min_mps=25.0,
                speed_max_mps=25.0, status="done", alignment_status="aligned",
                content_hash=f"bench-{i}", chainage_min_m=0.0, chainage_max_m=LENGTH_M,
                recorded_at=T0 + timedelta(days=30 * i), mean_wheel_force_n=LOADS[i % 2],
                static_wheel_load_n=LOADS[i % 2] if i % 2 else None,
            )  # fmt: skip
            s.add(run)
            s.flush()
            ids.append(run.id)
        support = [{"kind": "run", "id": r, "force_n": LOADS[i % 2]} for i, r in enumerate(ids)]
        step = LENGTH_M / n_spots
        spots = [
            {"track_id": track.id, "start_m": a, "end_m": a + 6.0, "peak_m": a + 3.0,
             "loss_pct": 40.0, "loss_lo_pct": 35.0, "loss_hi_pct": 45.0, "confidence": 0.9,
             "depth_mm": 0.2, "support": support}
            for a in (j * step + 10.0 for j in range(n_spots))
        ]  # fmt: skip
        s.execute(insert(TrackStiffnessSpot), spots)
        record_separation(s, track.id, spots)
        block = np.zeros((len(STIFFNESS_ARRAYS), CHUNK_POINTS), dtype="<f4")
        block[STIFFNESS_ARRAYS.index("n_passes")] = n_runs
        block[STIFFNESS_ARRAYS.index("separable")] = 1
        contributors = [
            {"kind": "run", "id": r, "label": f"run {r}", "mean_force_n": LOADS[i % 2],
             "points": CHUNK_POINTS}
            for i, r in enumerate(ids)
        ]  # fmt: skip
        chunks = int(LENGTH_M / GRID_STEP_M) // CHUNK_POINTS
        s.execute(
            insert(TrackStiffness),
            [{"track_id": track.id, "chunk": c, "data": block.tobytes(),
              "meta": {"contributors": contributors}} for c in range(chunks)],
        )  # fmt: skip
        s.commit()
        return track.id, ids


def interleaved(a: Callable[[], Any], b: Callable[[], Any], repeats: int) -> tuple[float, float]:
    """Median CPU time (s) of ``a`` and ``b``, called in turn ``repeats`` times each."""
    a()
    b()
    ta: list[float] = []
    tb: list[float] = []
    for _ in range(repeats):
        for f, t in ((a, ta), (b, tb)):
            t0 = time.process_time()
            f()
            t.append(time.process_time() - t0)
    return statistics.median(ta), statistics.median(tb)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--spots", type=int, default=2000)
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=9)
    args = ap.parse_args()
    print(f"machine: {machine()}")
    with tempfile.TemporaryDirectory() as tmp:
        db = Database(f"sqlite:///{Path(tmp) / 'bench.db'}")
        upgrade(db)
        tid, ids = build(db, args.spots, args.runs)

        def defects(flag: bool) -> Callable[[], Any]:
            def read() -> Any:
                with db.session() as s:
                    found = track_register(s, tid)
                    stiffness_notes(s, tid, found)
                    if flag:
                        marks = provisional_notes(s, tid, found)
                        assert all(m.provisional for m, d in zip(marks, found, strict=True)
                                   if d.source == "separated")  # fmt: skip
                    return found

            return read

        def stiffness(window: tuple[float | None, float | None], flag: bool) -> Callable[[], Any]:
            def read() -> Any:
                with db.session() as s:
                    if flag:
                        return stiffness_with_vehicles(s, tid, *window)
                    out = read_stiffness(s, tid, *window)
                    s.execute(
                        select(Run.id, Vehicle.name)
                        .join(Vehicle, Vehicle.id == Run.vehicle_id)
                        .where(Run.id.in_(ids))
                    ).all()
                    return out

            return read

        cases = [
            (f"defects ({args.spots} separated spots)", defects(False), defects(True)),
            ("stiffness, 2 km window", stiffness((0.0, 2000.0), False),
             stiffness((0.0, 2000.0), True)),
            ("stiffness, whole line", stiffness((None, None), False),
             stiffness((None, None), True)),
        ]  # fmt: skip
        for name, without, with_flag in cases:
            a, b = interleaved(without, with_flag, args.repeats)
            print(f"{name}: {1e3 * a:.1f} ms without the flag, {1e3 * b:.1f} ms with it, "
                  f"ratio {b / a:.3f}")  # fmt: skip
        # the flag's own work, steadier than the difference of two noisy totals
        with db.session() as s:
            found = track_register(s, tid)
            times = []
            for _ in range(args.repeats):
                t0 = time.process_time()
                provisional_notes(s, tid, found)
                times.append(time.process_time() - t0)
        print(f"provisional_notes alone on {len(found)} defects: "
              f"{1e3 * statistics.median(times):.1f} ms")  # fmt: skip


if __name__ == "__main__":
    main()
