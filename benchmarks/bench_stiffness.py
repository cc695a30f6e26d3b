"""Track stiffness benchmark: 50 runs of 10 km with two wheel loads, separation and reads.

    python benchmarks/bench_stiffness.py [--runs 50] [--length-km 10] [--repeats 40]

1. A fresh SQLite database (migrated like the app does) gets one track and ``--runs`` runs,
   each with its aligned level and wheel force on the track grid (``track_run_levels``, the
   rows the service keeps for every merged run). The levels are generated rather than
   inverted from 50 simulated 10 km logs (hours of forward simulation): a fixed rail geometry
   (band-limited, 1 mm SD) plus the wheel force times the track's compliance (nominal, with a
   40 % soft zone every 500 m), plus 0.04 mm of per-run noise; three of every five runs are
   coaches (88 kN), two heavy (196 kN), each run's force varying +-3 % along the track.
2. The separation of the whole track is timed
(``app.services.track.separation_store.recompute_all``:
   what the worker pays when a 10 km run joins a track of ``--runs`` runs, since its chunks
   are the whole track), then ``GET /api/v1/tracks/{id}/stiffness?from_m=&to_m=`` for a
   2 km window at random places ``--repeats`` times through the full ASGI stack (Starlette's
   TestClient), and the service function behind it; median and 95th percentile.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import machine, median_p95  # noqa: E402
from sqlalchemy import insert  # noqa: E402

from app.db.migrate import upgrade  # noqa: E402
from app.db.models import Run, Track, TrackRunLevels, Vehicle  # noqa: E402
from app.db.session import Database  # noqa: E402
from app.services.storage.packing import pack_f4  # noqa: E402
from app.services.track.aggregate import chunked  # noqa: E402
from app.services.track.separation_store import read_stiffness, recompute_all  # noqa: E402
from engine.chainage import GRID_STEP_M, bandpass_distance  # noqa: E402

C_NOM_MM_PER_N = 0.49 / 88e3
"""Nominal compliance under a coach (0.49 mm at 88 kN), mm/N."""


def make_levels(n_runs: int, length_m: float, seed: int = 0):
    """Per run: (force N, level mm) on the track grid from 0 to ``length_m``."""
    rng = np.random.default_rng(seed)
    x = np.arange(0.0, length_m, GRID_STEP_M)
    geometry = bandpass_distance(rng.standard_normal(x.size), GRID_STEP_M, 3.0, 40.0)
    geometry *= 1.0 / geometry.std()
    comp = np.full(x.size, C_NOM_MM_PER_N)
    for c in np.arange(250.0, length_m - 100.0, 500.0):
        comp[(x >= c) & (x < c + 6.0)] *= 0.6**-0.75
    runs = []
    for k in range(n_runs):
        load = 196e3 if k % 5 in (1, 3) else 88e3
        force = load * (1.0 + 0.03 * np.sin(x / 37.0 + k))
        level = geometry + bandpass_distance(force * comp, GRID_STEP_M, 3.0, 40.0)
        runs.append((force, level + rng.normal(0.0, 0.04, x.size)))
    return runs


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--length-km", type=float, default=10.0)
    ap.add_argument("--repeats", type=int, default=40)
    args = ap.parse_args()
    length_m = args.length_km * 1000.0
    print(f"machine: {machine()}")
    with tempfile.TemporaryDirectory() as tmp:
        url = f"sqlite:///{Path(tmp) / 'bench.db'}"
        db = Database(url)
        upgrade(db)
        t0 = time.perf_counter()
        with db.session() as s:
            track = Track(name="bench", rail="UIC60", k_nominal=80e6, spacing=0.6, EI=6.42e6,
                          mass_per_m=60.34, c_support=50e3)  # fmt: skip
            s.add(track)
            s.flush()
            vehicle_id = s.query(Vehicle.id).filter(Vehicle.name == "table1").scalar()
            for k, (force, level) in enumerate(make_levels(args.runs, length_m)):
                run = Run(
                    track_id=track.id, vehicle_id=vehicle_id, source="json", direction="increasing",
                    sample_rate_hz=1000.0, n_samples=1, duration_s=1.0, speed_min_mps=25.0,
                    speed_max_mps=25.0, status="done", alignment_status="aligned",
                    content_hash=f"bench-{k}", chainage_min_m=0.0, chainage_max_m=length_m,
                )  # fmt: skip
                s.add(run)
                s.flush()
                _, _, lv = chunked(0, level)
                _, _, fv = chunked(0, force)
                s.execute(insert(TrackRunLevels), [
                    {"run_id": run.id, "chunk": c, "track_id": track.id,
                     "levels": pack_f4(lv[c]), "force_n": pack_f4(fv[c])}
                    for c in lv
                ])  # fmt: skip
            s.commit()
            track_id = track.id
        print(f"stored {args.runs} runs x {args.length_km:g} km of levels and forces in "
              f"{time.perf_counter() - t0:.1f} s")  # fmt: skip
        with db.session() as s:
            t0 = time.perf_counter()
            points = recompute_all(s, track_id)
            s.commit()
            sep_s = time.perf_counter() - t0
        print(f"separation of the whole track ({points} grid points, {args.runs} passes): "
              f"{sep_s:.2f} s (what storing one more 10 km run adds)")  # fmt: skip
        rng = np.random.default_rng(1)
        starts = rng.uniform(0.0, max(0.0, length_m - 2000.0), args.repeats)
        ms = []
        with db.session() as s:
            w = read_stiffness(s, track_id, 0.0, 2000.0)
            print(f"window 0-2000 m: {w.n} points, {len(w.spots)} soft spots, "
                  f"{100 * w.separable_fraction:.0f} % separable")  # fmt: skip
            for a in starts:
                t0 = time.perf_counter()
                read_stiffness(s, track_id, float(a), float(a) + 2000.0)
                ms.append(1e3 * (time.perf_counter() - t0))
        print(f"read_stiffness, 2 km window: {median_p95(ms)}")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            from starlette.testclient import TestClient

            from app.core.config import Settings
            from app.main import create_app

        settings = Settings(data_dir=Path(tmp), database_url=url)
        with TestClient(create_app(settings)) as client:
            ms = []
            for a in starts:
                t0 = time.perf_counter()
                r = client.get(
                    f"/api/v1/tracks/{track_id}/stiffness",
                    params={"from_m": float(a), "to_m": float(a) + 2000.0},
                )
                ms.append(1e3 * (time.perf_counter() - t0))
                assert r.status_code == 200, r.text
            print(f"GET /tracks/{{id}}/stiffness, 2 km window (JSON, {r.json()['n']} points): "
                  f"{median_p95(ms)}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
