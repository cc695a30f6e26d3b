"""Chart views' profile reads: a run's decimated profile and a track's window.

    PYTHONPATH=$PWD python benchmarks/bench_view_reads.py [--data-dir DIR] [--repeats 100]

A run of 4 km (30 m/s, realistic sensor noise, a 40 % soft zone every 500 m) is simulated
with the engine's forward model, uploaded through the app (``TestClient``) into the SQLite
database of ``--data-dir`` and processed, unless that database holds it already: give the
same directory to two checkouts (``PYTHONPATH`` each checkout's own root) to compare them on
one stored run in one sitting. Then ``app.services.views.charts.run_profile_view`` (the whole
run, 4 000 points) and ``track_window`` (1 km, 2 000 points a run) are called ``--repeats``
times in process: median and fastest CPU time of the service call (``time.process_time``,
less sensitive than the wall clock to other processes on a shared machine).
"""

from __future__ import annotations

import argparse
import io
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import machine  # noqa: E402

TRACK = "views"


def store_run(data_dir: Path) -> int:
    """The id of the benchmark's run in ``data_dir``'s database, uploaded and processed first
    if it is not there."""
    from fastapi.testclient import TestClient

    from app.core.config import Settings
    from app.main import create_app
    from engine.logio import write_run_csv
    from engine.synthetic import REALISTIC_SENSOR, make_run
    from engine.track import SoftZone

    with TestClient(create_app(Settings(data_dir=data_dir))) as c:
        stored = c.get("/api/v1/runs", params={"track": TRACK}).json().get("data", [])
        if stored:
            return int(stored[0]["id"])
        zones = [SoftZone(x, x + 5.0, 0.4) for x in range(250, 3990, 500)]
        run = make_run(
            length=4000.0, zones=zones, speed=30.0, start_chainage_m=20.0,
            sensor=REALISTIC_SENSOR, seed=5,
        )  # fmt: skip
        buf = io.StringIO()
        write_run_csv(run.log, buf, digits=8)
        r = c.post(
            "/api/v1/runs",
            files={"file": ("run.csv", buf.getvalue().encode(), "text/csv")},
            data={"track": TRACK, "start_chainage_m": "20"},
        )
        assert r.status_code in (200, 201, 202), r.text
        run_id = int(r.json()["id"])
        while c.get(f"/api/v1/runs/{run_id}").json()["status"] not in ("done", "failed"):
            time.sleep(0.2)
        return run_id


def cpu_ms(call: Callable[[], object], repeats: int) -> str:
    """Median and fastest CPU time of ``call``, ms."""
    call()
    ms = []
    for _ in range(repeats):
        t = time.process_time()
        call()
        ms.append(1e3 * (time.process_time() - t))
    return f"CPU median {statistics.median(ms):.2f} ms, fastest {min(ms):.2f} ms"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data-dir", type=Path, default=None)
    ap.add_argument("--repeats", type=int, default=100)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        data_dir = args.data_dir or Path(tmp)
        run_id = store_run(data_dir)

        from app.core.config import Settings
        from app.db.session import Database
        from app.services.lookup import get_track
        from app.services.views import charts
        from app.services.views.window import Window

        db = Database(Settings(data_dir=data_dir).sqlalchemy_url)
        print(f"machine: {machine()}")
        with db.session() as s:
            trk = get_track(s, TRACK)
            whole, km = Window(), Window(1500.0, 2500.0)
            profile = cpu_ms(lambda: charts.run_profile_view(s, run_id, whole, 4000), args.repeats)
            window = cpu_ms(
                lambda: charts.track_window(s, trk, km, max_points=2000, max_runs=200),
                args.repeats,
            )
        db.dispose()
        print(f"run_profile_view (4 km run, 4 000 points): {profile}")
        print(f"track_window (1 km, 2 000 points a run): {window}")


if __name__ == "__main__":
    main()
