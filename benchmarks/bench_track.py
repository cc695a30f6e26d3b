"""Track intelligence benchmark: 50 runs of 10 km on one track, register and profile reads.

    python benchmarks/bench_track.py [--runs 50] [--length-km 10] [--repeats 40]

1. A fresh SQLite database (migrated like the app does) gets one track and ``--runs`` runs of
   ``--length-km`` each, stored through the service's own storage function
   (``app.services.run_lifecycle.processing.store_result``: profile rows, soft spots, then
   alignment to the
   track's aggregate and the incremental aggregate update), one transaction per run. The
   processed results are generated rather than inverted from 50 simulated 10 km logs (that
   would take hours of forward simulation), with realistic content: a fixed track "fingerprint"
   (band-limited irregularity, 0.03 mm RMS) plus 6 dips per km at fixed chainages (3-8 m wide,
   0.08-0.6 mm deep, a fifth of them deepening over the campaign), per-run measurement noise,
   run-to-run scatter of the dips (depth +-10 %, detection 90 %, peak +-0.3 m), five false
   alarms per run, and start-chainage errors of up to +-5 m that the alignment has to undo.
2. The app is started on that database (Starlette's TestClient: the full ASGI stack, in
   process) and ``GET /api/v1/tracks/{id}/defects`` and ``GET /api/v1/tracks/{id}/profile?
   from_m=&to_m=`` for a 2 km window at random places are timed ``--repeats`` times each;
   median and 95th percentile. The service functions behind them are timed too.
3. Also reported: the time to store one more run (alignment + aggregate update of its 10 km)
   and to delete one (aggregate recomputed without it), and how well the offsets were found.
"""

from __future__ import annotations

import argparse
import hashlib
import statistics
import sys
import tempfile
import time
import warnings
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import database_with_track, machine, median_p95  # noqa: E402

from app.db.models import Run  # noqa: E402
from app.db.session import Database  # noqa: E402
from app.services.run_lifecycle.processing import Processed, store_result  # noqa: E402
from engine.results import ProcessResult, Quality, SoftSpot  # noqa: E402

STEP_M = 0.25
T0 = datetime(2026, 1, 1, 6, 0, tzinfo=UTC)


class Line:
    """The simulated line: a fixed irregularity and fixed soft zones (true chainage, m)."""

    def __init__(self, length_m: float, zones_per_km: float = 6.0, seed: int = 0) -> None:
        rng = np.random.default_rng(seed)
        n_zones = max(1, round(zones_per_km * length_m / 1000.0))
        self.length_m = length_m
        self.x = np.arange(-20.0, length_m + 20.0, STEP_M)
        # band-limited noise: white noise smoothed over ~3 m, 0.03 mm RMS
        raw = rng.standard_normal(self.x.size)
        k = np.hanning(25)
        smooth = np.convolve(raw, k / k.sum(), mode="same")
        self.base = 0.03 * smooth / smooth.std()
        self.zone_x = np.sort(rng.uniform(200.0, length_m - 200.0, n_zones))
        self.zone_w = rng.uniform(3.0, 8.0, n_zones)
        self.zone_d = rng.uniform(0.08, 0.6, n_zones)
        self.zone_growth = np.where(rng.random(n_zones) < 0.2, rng.uniform(0.3, 1.0, n_zones), 0)

    def depth(self, run: int, n_runs: int) -> np.ndarray:
        """Depth of every zone in run ``run`` (deepening zones grow over the campaign), mm."""
        return self.zone_d * (1.0 + self.zone_growth * run / max(n_runs - 1, 1))

    def result(
        self, run: int, n_runs: int, err_m: float, rng: np.random.Generator
    ) -> ProcessResult:
        """A processed run as the engine returns it, in the run's logged chainage."""
        depth = self.depth(run, n_runs) * rng.normal(1.0, 0.1, self.zone_x.size)
        level = self.base + rng.normal(0.0, 0.01, self.x.size)
        for xc, w, d in zip(self.zone_x, self.zone_w, depth, strict=True):
            near = np.abs(self.x - xc) < 2 * w
            level[near] -= d * np.exp(-0.5 * ((self.x[near] - xc) / (w / 4)) ** 2)
        keep = (self.x >= 0) & (self.x <= self.length_m)
        # logged chainage = true + error, on the engine's grid (multiples of 0.25 m)
        shift = round(err_m / STEP_M) * STEP_M
        chain = self.x[keep] + shift
        lv = np.interp(self.x[keep] - (err_m - shift), self.x, level)
        spots = []
        seen = rng.random(self.zone_x.size) < 0.9
        for xc, w, d in zip(self.zone_x[seen], self.zone_w[seen], depth[seen], strict=True):
            p = xc + err_m + rng.normal(0.0, 0.3)
            loss = float(min(90.0, 15.0 + 80.0 * d))
            spots.append(SoftSpot(p - w / 2, p + w / 2, p, float(d), loss))
        for p in rng.uniform(0.0, self.length_m, 5):
            spots.append(SoftSpot(p - 1.5 + err_m, p + 1.5 + err_m, p + err_m,
                                  float(rng.uniform(0.05, 0.1)), 20.0))  # fmt: skip
        spots.sort(key=lambda s: s.start_m)
        nan = np.full(chain.size, np.nan)
        quality = Quality(0.02, 1e-4, 0.01, float(self.length_m), 29.0, 31.0, 1000.0)
        return ProcessResult(chain, lv, lv, lv, nan, spots, quality, "spectral")


def store_run(db: Database, track_id: int, vehicle_id: int, line: Line, k: int, n_runs: int,
              err: float, rng: np.random.Generator) -> tuple[int, float, float]:  # fmt: skip
    """Store run ``k`` through the service; its id, the offset found (m) and the time (s)."""
    res = line.result(k, n_runs, err, rng)
    with db.session() as s:
        run = Run(
            track_id=track_id, vehicle_id=vehicle_id, source="upload",
            original_filename=f"run-{k:02d}.csv", recorded_at=T0 + timedelta(days=k),
            start_chainage_m=err, direction="increasing", sample_rate_hz=1000.0,
            n_samples=int(line.length_m / 30.0 * 1000), duration_s=line.length_m / 30.0,
            speed_min_mps=29.0, speed_max_mps=31.0, chainage_offset_m=0.0, status="processing",
            stage="storing", options={}, attempts=1,
            content_hash=hashlib.sha256(f"bench-{k}-{err}".encode()).hexdigest(),
        )  # fmt: skip
        s.add(run)
        s.flush()
        t0 = time.perf_counter()
        # the generated level stands for the run's long level too (every run keeps one)
        store_result(s, run, Processed(res, 0.0, res.level_mm), 1)
        s.commit()
        return run.id, float(run.chainage_offset_m), time.perf_counter() - t0


def quality_memory(db: Database, track_id: int) -> None:
    """Time and peak traced memory of the whole track's quality answer (no window: every
    pass over the whole track), through its service function."""
    import tracemalloc

    from app.db.models import Track
    from app.services.track.quality import track_quality

    with db.session() as s:
        track = s.get(Track, track_id)
        assert track is not None
        track_quality(s, track)  # warm: imports, caches
        t0 = time.perf_counter()
        track_quality(s, track)
        dt = time.perf_counter() - t0
        tracemalloc.start()
        track_quality(s, track)
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
    print(
        f"quality answer of the whole track (no window): {dt:.2f} s, peak traced memory "
        f"{peak / 2**20:.1f} MiB"
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--length-km", type=float, default=10.0)
    ap.add_argument("--repeats", type=int, default=40)
    ap.add_argument("--window-km", type=float, default=2.0)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    print(f"machine: {machine()}")
    length = args.length_km * 1000.0
    rng = np.random.default_rng(args.seed)
    with tempfile.TemporaryDirectory(prefix="bench-track-") as tmp:
        url = f"sqlite:///{Path(tmp) / 'trackprofile.db'}"
        db, track_id, vehicle_id = database_with_track(url, "Bench line")
        line = Line(length, seed=args.seed)
        errors = rng.uniform(-5.0, 5.0, args.runs + 1)
        t_build = time.perf_counter()
        store_s, misfit = [], []
        for k in range(args.runs):
            _, off, dt = store_run(db, track_id, vehicle_id, line, k, args.runs, errors[k], rng)
            store_s.append(dt)
            if k:
                misfit.append(abs(off - (errors[0] - errors[k])))
        build = time.perf_counter() - t_build
        print(f"stored {args.runs} runs x {args.length_km:g} km through store_result in "
              f"{build:.1f} s (per run: median {statistics.median(store_s):.2f} s, last "
              f"{store_s[-1]:.2f} s, including alignment and the aggregate update)")  # fmt: skip
        print(f"alignment: start-chainage errors up to +-5 m undone to within "
              f"{max(misfit):.3f} m (median {statistics.median(misfit):.3f} m)")  # fmt: skip

        from app.core.config import Settings
        from app.main import create_app
        from app.services.track.aggregate import read_track_profile
        from app.services.track.register import track_register

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            from starlette.testclient import TestClient

        settings = Settings(data_dir=Path(tmp), database_url=url)
        with TestClient(create_app(settings)) as client:
            base = f"/api/v1/tracks/{track_id}"
            defects = client.get(f"{base}/defects").json()
            levels = {lv: sum(1 for d in defects if d["level"] == lv)
                      for lv in ("immediate", "intervention", "alert")}  # fmt: skip
            worsening = sum(1 for d in defects if d["status"] == "worsening")
            print(f"register: {len(defects)} defects ({len(line.zone_x)} real zones), "
                  f"{worsening} worsening ({int((line.zone_growth > 0).sum())} deepening "
                  f"zones), levels {levels}")  # fmt: skip
            reg_ms, prof_ms, n_points = [], [], []
            win = args.window_km * 1000.0
            for _ in range(args.repeats):
                t0 = time.perf_counter()
                r = client.get(f"{base}/defects")
                reg_ms.append(1000 * (time.perf_counter() - t0))
                assert r.status_code == 200
                a = float(rng.uniform(0.0, length - win))
                t0 = time.perf_counter()
                r = client.get(f"{base}/profile", params={"from_m": a, "to_m": a + win})
                prof_ms.append(1000 * (time.perf_counter() - t0))
                n_points.append(r.json()["n"])
            print(f"GET defects ({len(defects)} defects from "
                  f"{sum(d['runs_seen'] for d in defects)} sightings), {args.repeats} times: "
                  f"{median_p95(reg_ms)} (target <= 200 ms)")  # fmt: skip
            pts = statistics.median(n_points)
            print(f"GET profile, {args.window_km:g} km window ({pts:.0f} points), "
                  f"{args.repeats} times: {median_p95(prof_ms)} (target <= 200 ms)")  # fmt: skip
            fn_reg, fn_prof = [], []
            with db.session() as s:
                for _ in range(max(10, args.repeats // 4)):
                    t0 = time.perf_counter()
                    track_register(s, track_id)
                    fn_reg.append(1000 * (time.perf_counter() - t0))
                    a = float(rng.uniform(0.0, length - win))
                    t0 = time.perf_counter()
                    read_track_profile(s, track_id, a, a + win)
                    fn_prof.append(1000 * (time.perf_counter() - t0))
            print(f"service functions alone: register {median_p95(fn_reg)}; profile window "
                  f"{median_p95(fn_prof)}")  # fmt: skip
            quality_memory(db, track_id)

            k = args.runs
            run_id, _, dt = store_run(db, track_id, vehicle_id, line, k, k + 1, errors[k], rng)
            print(
                f"one more {args.length_km:g} km run stored onto {k} runs: {dt:.2f} s "
                "(profile rows, soft spots, alignment, aggregate update)"
            )
            t0 = time.perf_counter()
            assert client.delete(f"/api/v1/runs/{run_id}").status_code == 204
            print(f"DELETE that run (aggregate recomputed without it): "
                  f"{time.perf_counter() - t0:.2f} s")  # fmt: skip
        db.dispose()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
