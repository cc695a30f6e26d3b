"""A simulated year of a fleet on one 200 km line, scaled to this machine.

    python benchmarks/bench_year.py [--line-km 200] [--run-km 20000] [--scale 0.1]
                                    [--run-length-km 20] [--database-url URL]

1. A fresh database (SQLite file by default, or ``--database-url``) gets one line of
   ``--line-km`` and ``--scale x --run-km`` run-km of runs of ``--run-length-km`` each, spread
   over 12 months (recording times uniform over the year), each covering a random stretch of
   the line. The processed results are generated, not inverted (bench_track.Line: a fixed
   track fingerprint, 6 dips per km, a fifth of them deepening over the year, per-run noise,
   scatter and start-chainage errors), with each axle's level, the baseline and each axle's
   wheel force (static 60 kN + a dynamic part), and display signals as the upload path stores
   them. Each run goes through the service's own storage (``store_result``: profile blocks,
   soft spots, alignment, aggregate update, geometry/stiffness separation), one transaction.
2. At every tenth of the runs: database size (SQLite file after a WAL checkpoint, or
   ``pg_database_size``), bytes per run-km since the start, the storing rate, and timed reads
   through the ASGI app: a 2 km window of a run's profile and of the aggregate (medians of
   10), the register (``/defects``) and alerts of the whole line (read once: seconds each).
3. Then a year's retention: detail kept 90 days; the sweep's time per run and the size after
   (SQLite: after VACUUM, which a deployment runs from time to time).

Logs are not stored here (bench_service.py measures a compressed 1-hour log); the extrapolation
to a fleet is printed at the end from the measured figures.
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

from bench_track import STEP_M, Line  # noqa: E402
from common import database_with_track, machine  # noqa: E402
from sqlalchemy import text  # noqa: E402

from app.db.models import Run, RunSignals  # noqa: E402
from app.db.session import Database  # noqa: E402
from app.services.run_lifecycle.processing import Processed, store_result  # noqa: E402
from app.services.storage.retention import RetentionPolicy, sweep  # noqa: E402
from app.services.views.signals import pack_signals  # noqa: E402
from engine.decimate import minmax_indices  # noqa: E402
from engine.results import ProcessResult, Quality, SoftSpot  # noqa: E402

T0 = datetime(2026, 1, 1, 6, 0, tzinfo=UTC)
SPEED_MPS = 22.0
STATIC_N = 60_000.0


def db_bytes(db: Database) -> int:
    """Size of the database now, bytes."""
    with db.engine.connect() as conn:
        if db.is_sqlite:
            conn.exec_driver_sql("PRAGMA wal_checkpoint(TRUNCATE)")
            page = conn.exec_driver_sql("PRAGMA page_size").scalar_one()
            count = conn.exec_driver_sql("PRAGMA page_count").scalar_one()
            free = conn.exec_driver_sql("PRAGMA freelist_count").scalar_one()
            return int(page * (count - free))
        return int(conn.execute(text("SELECT pg_database_size(current_database())")).scalar_one())


def table_bytes(db: Database) -> dict[str, int]:
    """Bytes per table, largest first: with its indexes, TOAST and free space on PostgreSQL
    (``pg_total_relation_size``); tables and indexes apart on SQLite (``dbstat``; empty where
    it is not compiled in)."""
    with db.engine.connect() as conn:
        if not db.is_sqlite:
            rows = conn.execute(
                text(
                    "SELECT relname, pg_total_relation_size(relid) FROM pg_stat_user_tables "
                    "ORDER BY 2 DESC"
                )
            ).all()
            return {str(n): int(b) for n, b in rows}
        try:
            rows = conn.exec_driver_sql(
                "SELECT name, SUM(pgsize) FROM dbstat GROUP BY name ORDER BY 2 DESC"
            ).all()
        except Exception:
            return {}
    return {str(n): int(b) for n, b in rows}


def line_window(
    line: Line, k: int, n: int, a_m: float, length_m: float, err_m: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, list[SoftSpot]]:
    """Run ``k``'s level over ``[a_m, a_m + length_m]`` of the line in its logged chainage
    (start error ``err_m``), m and mm, and its soft-spot sightings.

    The same content as ``bench_track.Line.result`` (the line's fingerprint, per-run noise,
    each zone's dip with its run-to-run depth scatter and deepening, 90 % detection, peaks
    +-0.3 m, false alarms at the same density), generated over the run's stretch only: the
    whole-line version costs every run the whole line (zones x line points), which made the
    year benchmark's generation slower than the storage it measures.
    """
    i0 = int(np.searchsorted(line.x, a_m - 30.0))
    i1 = int(np.searchsorted(line.x, a_m + length_m + 30.0))
    xs = line.x[i0:i1]
    level = line.base[i0:i1] + rng.normal(0.0, 0.01, xs.size)
    sel = np.flatnonzero((line.zone_x > xs[0] - 20.0) & (line.zone_x < xs[-1] + 20.0))
    depth = line.depth(k, n)[sel] * rng.normal(1.0, 0.1, sel.size)
    for xc, w, d in zip(line.zone_x[sel], line.zone_w[sel], depth, strict=True):
        j0, j1 = np.searchsorted(xs, [xc - 2 * w, xc + 2 * w])
        level[j0:j1] -= d * np.exp(-0.5 * ((xs[j0:j1] - xc) / (w / 4)) ** 2)
    # logged chainage = true + error, on the engine's grid (multiples of 0.25 m)
    shift = round(err_m / STEP_M) * STEP_M
    chain = xs + shift
    lv = np.interp(xs - (err_m - shift), xs, level)
    keep = (chain >= a_m + err_m) & (chain <= a_m + length_m + err_m)
    lo, hi = a_m + err_m, a_m + length_m + err_m
    spots = []
    seen = rng.random(sel.size) < 0.9
    for xc, w, d in zip(line.zone_x[sel][seen], line.zone_w[sel][seen], depth[seen], strict=True):
        p = xc + err_m + rng.normal(0.0, 0.3)
        loss = float(min(90.0, 15.0 + 80.0 * d))
        spots.append(SoftSpot(p - w / 2, p + w / 2, p, float(d), loss))
    for p in rng.uniform(a_m, a_m + length_m, rng.poisson(5.0 * length_m / line.length_m)):
        spots.append(SoftSpot(p - 1.5 + err_m, p + 1.5 + err_m, p + err_m,
                              float(rng.uniform(0.05, 0.1)), 20.0))  # fmt: skip
    spots = sorted((s for s in spots if lo <= s.peak_m <= hi), key=lambda s: s.start_m)
    return chain[keep], lv[keep], spots


def make_result(line: Line, a_m: float, length_m: float, k: int, n: int,
                rng: np.random.Generator) -> tuple[ProcessResult, float]:  # fmt: skip
    """Run ``k`` over ``[a_m, a_m + length_m]`` of the line (logged chainage, start error)."""
    err = float(rng.uniform(-5.0, 5.0))
    x, lv, spots = line_window(line, k, n, a_m, length_m, err, rng)
    front = lv + rng.normal(0.0, 0.005, x.size)
    rear = 2 * lv - front
    dyn = np.convolve(rng.normal(0, 1.0, x.size), np.hanning(41) / 20.5, mode="same")
    f_front = STATIC_N + 800.0 * dyn - 3000.0 * lv
    f_rear = STATIC_N - 800.0 * dyn - 3000.0 * lv
    base = np.convolve(lv, np.ones(81) / 81, mode="same")
    quality = Quality(0.02, 1e-4, 0.01, float(length_m), 29.0, 31.0, 1000.0)
    res = ProcessResult(x, lv, front, rear, base, spots, quality, "spectral",
                        front_force_n=f_front, rear_force_n=f_rear)  # fmt: skip
    return res, err


def signals(length_m: float, rng: np.random.Generator) -> dict[str, list[float | None]]:
    """Display signals as the upload path keeps them (min/max envelope, <= 5000 points)."""
    n = int(length_m / SPEED_MPS * 1000)
    t = np.arange(n) / 1000.0
    a = rng.normal(0, 0.3, n)
    idx = minmax_indices(a, 5000)
    return {"time_s": t[idx].tolist(), "accel_z_mps2": a[idx].tolist(),
            "pitch_rate_radps": (a[idx] * 0.01).tolist(),
            "speed_mps": [SPEED_MPS] * idx.size}  # fmt: skip


def store(db: Database, track_id: int, vehicle_id: int, line: Line, k: int, n: int,
          when: datetime, length_m: float,
          rng: np.random.Generator) -> tuple[int, float]:  # fmt: skip
    a_m = float(rng.uniform(0.0, line.length_m - length_m))
    a_m = round(a_m / STEP_M) * STEP_M
    res, err = make_result(line, a_m, length_m, k, n, rng)
    sig = signals(length_m, rng)
    with db.session() as s:
        run = Run(
            track_id=track_id, vehicle_id=vehicle_id, source="upload",
            original_filename=f"run-{k:05d}.csv", recorded_at=when,
            start_chainage_m=a_m + err, direction="increasing", sample_rate_hz=1000.0,
            n_samples=int(length_m / SPEED_MPS * 1000), duration_s=length_m / SPEED_MPS,
            speed_min_mps=SPEED_MPS, speed_max_mps=SPEED_MPS, chainage_offset_m=0.0,
            status="processing", stage="storing", options={}, attempts=1,
            content_hash=hashlib.sha256(f"year-{k}".encode()).hexdigest(),
        )  # fmt: skip
        s.add(run)
        s.flush()
        s.add(RunSignals(run_id=run.id, n_points=len(sig["time_s"]), decimated=True,
                         packed=pack_signals(sig)))  # fmt: skip
        t0 = time.perf_counter()
        store_result(s, run, Processed(res, 0.0), 1)
        s.commit()
        return run.id, time.perf_counter() - t0


def timed(fn, repeats: int = 20) -> float:  # type: ignore[no-untyped-def]
    """Median time of ``fn()``, ms."""
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        out.append(1e3 * (time.perf_counter() - t))
    return statistics.median(out)


def reads(client, track_id: int, run_ids: list[int], line_m: float,
          rng: np.random.Generator) -> dict[str, float]:  # type: ignore[no-untyped-def]  # fmt: skip
    def run_window() -> None:
        rid = int(rng.choice(run_ids))
        run = client.get(f"/api/v1/runs/{rid}").json()
        a = float(rng.uniform(run["chainage_min_m"], run["chainage_max_m"] - 2000.0))
        r = client.get(f"/api/v1/runs/{rid}/profile", params={"from_m": a, "to_m": a + 2000})
        assert r.status_code == 200 and r.json()["n"] == 8000, r.text[:200]

    def agg_window() -> None:
        a = float(rng.uniform(0.0, line_m - 2000.0))
        r = client.get(f"/api/v1/tracks/{track_id}/profile", params={"from_m": a, "to_m": a + 2000})
        assert r.status_code == 200, r.text[:200]

    def register() -> None:
        assert client.get(f"/api/v1/tracks/{track_id}/defects").status_code == 200

    def alerts() -> None:
        r = client.get(
            f"/api/v1/tracks/{track_id}/alerts", params={"since": "2025-01-01T00:00:00Z"}
        )
        assert r.status_code == 200, r.text[:200]

    return {
        "run window": timed(run_window, 10), "aggregate window": timed(agg_window, 10),
        "register": timed(register, 1), "alerts": timed(alerts, 1),
    }  # fmt: skip


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--line-km", type=float, default=200.0)
    ap.add_argument("--run-km", type=float, default=20_000.0, help="run-km of the full year")
    ap.add_argument("--scale", type=float, default=0.1, help="fraction of the year stored")
    ap.add_argument("--run-length-km", type=float, default=20.0)
    ap.add_argument("--keep-days", type=float, default=90.0, help="detail retention (sweep)")
    ap.add_argument("--database-url", default=None)
    args = ap.parse_args()
    warnings.simplefilter("ignore", RuntimeWarning)
    from starlette.testclient import TestClient

    from app.core.config import Settings
    from app.main import create_app

    length_m = args.run_length_km * 1000.0
    n_runs = max(10, round(args.scale * args.run_km / args.run_length_km))
    rng = np.random.default_rng(0)
    line = Line(args.line_km * 1000.0, seed=0)
    when = sorted(T0 + timedelta(days=float(d)) for d in rng.uniform(0.0, 365.0, n_runs))
    with tempfile.TemporaryDirectory(prefix="bench-year-") as tmp:
        url = args.database_url or f"sqlite:///{Path(tmp) / 'year.db'}"
        db, track_id, vehicle_id = database_with_track(url, "Year line")
        size0 = db_bytes(db)
        settings = Settings(data_dir=Path(tmp), database_url=url, start_worker=False,
                            run_migrations=False)  # fmt: skip
        ids: list[int] = []
        store_s: list[float] = []
        rows = []
        t_start = time.perf_counter()
        with TestClient(create_app(settings)) as client:
            for k in range(n_runs):
                rid, dt = store(db, track_id, vehicle_id, line, k, n_runs, when[k], length_m, rng)
                ids.append(rid)
                store_s.append(dt)
                if (k + 1) % max(1, n_runs // 10) == 0 or k + 1 == n_runs:
                    size = db_bytes(db)
                    run_km = (k + 1) * args.run_length_km
                    prev_size, prev_km = (rows[-1][2], rows[-1][1]) if rows else (size0, 0.0)
                    growth = (size - prev_size) / 1e3 / (run_km - prev_km)
                    r = reads(client, track_id, ids, line.length_m, rng)
                    rate = args.run_length_km / statistics.median(store_s[-10:])
                    rows.append((k + 1, run_km, size, growth, rate, r))
                    print(f"{k + 1:5d} runs {run_km:8.0f} run-km  db {size / 1e6:8.1f} MB  "
                          f"growth {growth:5.1f} kB/run-km  storing {rate:5.1f} run-km/s  "
                          + "  ".join(f"{n} {v:.0f} ms" for n, v in r.items()),
                          flush=True)  # fmt: skip
            tables = table_bytes(db)
            wall = time.perf_counter() - t_start
            before = db_bytes(db)
            policy = RetentionPolicy(detail_days=args.keep_days)
            now = T0 + timedelta(days=365)
            t0 = time.perf_counter()
            expired = 0
            while True:
                res = sweep(db, policy, now=now)
                expired += res.expired_runs
                if not res.removed:
                    break
            t_sweep = time.perf_counter() - t0
        if db.is_sqlite:
            with db.engine.connect() as conn:
                conn.exec_driver_sql("VACUUM")
        after = db_bytes(db)
        kept_runs = n_runs - expired
        db.dispose()
    growth = [r[3] for r in rows[1:]] or [rows[-1][3]]
    per_km = statistics.median(growth)
    kept_km = (after - size0) / 1e3 / (n_runs * args.run_length_km)
    print()
    print(f"machine: {machine()}")
    print(f"{n_runs} runs x {args.run_length_km:g} km = {n_runs * args.run_length_km:.0f} run-km "
          f"on a {args.line_km:g} km line (scale {args.scale:g} of {args.run_km:g} run-km a year);"
          f" stored in {wall:.0f} s")  # fmt: skip
    if tables:
        total_km = n_runs * args.run_length_km
        print(
            "bytes per run-km by table (before the sweep): "
            + ", ".join(
                f"{n} {b / 1e3 / total_km:.1f} kB" for n, b in tables.items() if b / total_km > 100
            )
        )
    print(
        f"storage: growth {per_km:.1f} kB per run-km with detail (median of the tenths); "
        "after the sweep "
        f"({expired} runs older than {args.keep_days:g} days lost their detail, {kept_runs} "
        f"kept) {kept_km:.1f} kB per run-km ({before / 1e6:.1f} -> {after / 1e6:.1f} MB)"
    )
    per_run_ms = 1e3 * t_sweep / max(expired, 1)
    print(f"sweep: {t_sweep:.1f} s for {expired} runs ({per_run_ms:.0f} ms per run, one "
          "transaction each)")  # fmt: skip
    print(
        f"storing: median {statistics.median(store_s) * 1e3:.0f} ms per {args.run_length_km:g} km"
        f" run ({args.run_length_km / statistics.median(store_s):.1f} run-km/s on one core)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
