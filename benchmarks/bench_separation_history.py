"""Separation history benchmark: what keeping successive separations costs a long line.

    python benchmarks/bench_separation_history.py [--spots 2000] [--separations 5] [--runs 10]

A fresh SQLite database (migrated like the app does) gets one track of 100 km, ``--runs`` done
runs of two wheel loads (50 and 80 kN, one a month) and ``--spots`` separated soft spots spread
along it. Each of ``--separations`` successive separations stores the spots again with two
more passes (a new light and heavy pair: each opens an entry) through
``record_separation``, as ``recompute_stiffness`` does after writing its spots; the time of
each is printed (what the history adds to a separation of the whole line). Then the register
(``track_register``: every sighting of the track merged, trended, ranked) is timed with the
history and with it emptied (the current spots alone), best of three.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import best_of, machine  # noqa: E402
from sqlalchemy import delete, insert, select  # noqa: E402

from app.db.migrate import upgrade  # noqa: E402
from app.db.models import (  # noqa: E402
    Run,
    Track,
    TrackSeparationHistory,
    TrackStiffnessSpot,
    Vehicle,
)
from app.db.session import Database  # noqa: E402
from app.services.track.register import track_register  # noqa: E402
from app.services.track.separation_history import record_separation  # noqa: E402

LENGTH_M = 100_000.0
LOADS = (50_000.0, 80_000.0)
T0 = datetime(2026, 1, 5, 7, 0, tzinfo=UTC)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--spots", type=int, default=2000)
    ap.add_argument("--separations", type=int, default=5)
    ap.add_argument("--runs", type=int, default=10)
    args = ap.parse_args()
    runs_needed = 2 * args.separations
    n_runs = max(args.runs, runs_needed)
    print(f"machine: {machine()}")
    with tempfile.TemporaryDirectory() as tmp:
        db = Database(f"sqlite:///{Path(tmp) / 'bench.db'}")
        upgrade(db)
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
                    recorded_at=T0 + timedelta(days=30 * i), static_wheel_load_n=LOADS[i % 2],
                )  # fmt: skip
                s.add(run)
                s.flush()
                ids.append(run.id)
            s.commit()
            tid = track.id
        step = LENGTH_M / args.spots
        for k in range(args.separations):
            support = [{"kind": "run", "id": ids[i], "force_n": LOADS[i % 2]}
                       for i in range(2 * k + 2)]  # fmt: skip
            spots = [
                {"track_id": tid, "start_m": a, "end_m": a + 6.0, "peak_m": a + 3.0,
                 "loss_pct": 40.0 + k, "loss_lo_pct": 35.0 + k, "loss_hi_pct": 45.0 + k,
                 "confidence": 0.9, "depth_mm": 0.2 + 0.01 * k, "support": support}
                for a in (j * step + 10.0 for j in range(args.spots))
            ]  # fmt: skip
            with db.session() as s:
                s.execute(delete(TrackStiffnessSpot).where(TrackStiffnessSpot.track_id == tid))
                s.execute(insert(TrackStiffnessSpot), spots)
                t0 = time.perf_counter()
                record_separation(s, tid, spots)
                s.commit()
                took = time.perf_counter() - t0
            print(f"separation {k + 1}: history of {args.spots} spots written in {took:.2f} s")

        def register() -> int:
            with db.session() as s:
                return len(track_register(s, tid))

        with_s, n = best_of(register)
        with db.session() as s:
            entries = len(s.scalars(select(TrackSeparationHistory.id)).all())
            s.execute(delete(TrackSeparationHistory))
            s.commit()
        without_s, _ = best_of(register)
        print(f"register of {n} defects: {with_s:.2f} s with {entries} history entries, "
              f"{without_s:.2f} s with the current spots alone")  # fmt: skip


if __name__ == "__main__":
    main()
