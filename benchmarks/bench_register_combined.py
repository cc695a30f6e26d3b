"""The register's cost with the combined passes' soft spots kept per chunk, against detecting
on every request (what a database from before migration 0020 still does).

Run: ``python benchmarks/bench_register_combined.py [--runs 12] [--length 800] [--repeat 5]``
(about half a minute). A SQLite database with one track and ``--runs`` merged runs whose
aligned levels (0.25 m grid over ``--length`` m) are four 0.3 mm soft-zone dips plus each
run's own 0.03 mm noise, stored as the service stores them; the aggregate rebuilt run by run
(:func:`app.services.track.aggregate.recompute_aggregate`, which now also detects). Timed, best of
``--repeat``: ``app.services.track.register.track_register`` with the spots kept, then with them
cleared (NULL: detected on the request, as before), and the cost a run's integration adds.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import tempfile
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
from common import machine  # noqa: E402
from sqlalchemy import select, update  # noqa: E402

from app.db.migrate import upgrade  # noqa: E402
from app.db.models import Run, Track, TrackProfileChunk, Vehicle  # noqa: E402
from app.db.session import Database  # noqa: E402
from app.services.track.aggregate import (  # noqa: E402
    CHUNK_POINTS,
    recompute_aggregate,
    store_combined_spots,
    store_run_levels,
)
from app.services.track.register import track_register  # noqa: E402
from engine.chainage import GRID_STEP_M  # noqa: E402
from engine.track import TrackParams  # noqa: E402


def best(fn, repeat: int) -> float:  # type: ignore[no-untyped-def]
    out = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out = min(out, time.perf_counter() - t0)
    return float(out)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--runs", type=int, default=12)
    p.add_argument("--length", type=float, default=800.0, help="m")
    p.add_argument("--repeat", type=int, default=5)
    ns = p.parse_args()
    rng = np.random.default_rng(3)
    n = int(ns.length / GRID_STEP_M)
    x = np.arange(n) * GRID_STEP_M
    truth = np.zeros(n)
    for c in (0.2, 0.4, 0.6, 0.8):
        truth -= 0.3 * np.exp(-0.5 * ((x - c * ns.length) / 2.0) ** 2)
    with tempfile.TemporaryDirectory() as tmp:
        db = Database(f"sqlite:///{Path(tmp) / 'bench.db'}")
        upgrade(db)
        t0 = datetime(2026, 3, 1, tzinfo=UTC)
        integrate = []
        with db.session() as s:
            vehicle_id = s.scalar(select(Vehicle.id).order_by(Vehicle.id).limit(1))
            # the nominal UIC60 track on 80 kN/mm supports
            track = Track(name="B", **TrackParams().to_dict())
            s.add(track)
            s.flush()
            for i in range(ns.runs):
                run = Run(
                    track_id=track.id, vehicle_id=vehicle_id, source="upload",
                    recorded_at=t0 + timedelta(days=i), start_chainage_m=0.0,
                    direction="increasing", sample_rate_hz=1000.0, n_samples=1000,
                    duration_s=1.0, speed_min_mps=25.0, speed_max_mps=25.0, status="done",
                    options={}, attempts=1, alignment_status="aligned", chainage_offset_m=0.0,
                    chainage_min_m=0.0, chainage_max_m=float(x[-1]),
                    content_hash=hashlib.sha256(f"bench-{i}".encode()).hexdigest(),
                )  # fmt: skip
                s.add(run)
                s.flush()
                level = truth + rng.normal(0.0, 0.03, n)
                chunks = store_run_levels(s, track.id, run.id, 0, level, np.full(n, 60e3))
                assert chunks is not None
                a = time.perf_counter()
                recompute_aggregate(s, track.id, *chunks)
                b = time.perf_counter()
                store_combined_spots(s, track.id, *chunks)
                integrate.append((b - a, time.perf_counter() - b))
            s.commit()
            tid = track.id
            kept = best(lambda: track_register(s, tid), ns.repeat)
            found = len(track_register(s, tid))
            s.execute(update(TrackProfileChunk).values(spots=None))
            on_request = best(lambda: track_register(s, tid), ns.repeat)
            s.rollback()
        db.dispose()
    last_total, last_detect = integrate[-1]
    print(f"Machine: {machine()}. {ns.runs} runs over {ns.length:.0f} m "
          f"({-(-n // CHUNK_POINTS)} chunks), best of {ns.repeat}.\n")  # fmt: skip
    print("| what | time, s |")
    print("|---|---|")
    print(f"| register request, spots kept per chunk ({found} defects) | {kept:.4f} |")
    print(f"| register request, detected on the request (before) | {on_request:.4f} |")
    print(f"| integrating the last run: aggregate rebuilt incl. detection | {last_total:.4f} |")
    print(f"| of which the detection (measured again alone) | {last_detect:.4f} |")


if __name__ == "__main__":
    main()
