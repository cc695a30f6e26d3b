"""A whole pass as the service does it, timed per upload: checkouts side by side.

Run: ``python benchmarks/bench_pass_service.py [--trees DIR,DIR] [--passes 12] [--rounds 3]
[--at-m 12600]`` (a few minutes). ``--passes`` industrial-MEMS passes of one 1 km track (four
zones, supports scattered 5 %, table1 at 24 m/s logged at 1 kHz, start chainages off by up to
+-1 m, a day apart) are written as CSV once (this checkout's engine; cached under
``benchmarks/.cache``) and uploaded at ``--at-m`` m on, where a pass straddles two of the
aggregate's chunks groups as it does on a line.
Each checkout of ``--trees`` (default: this one; e.g. a ``git archive`` of an older commit
beside it) then uploads them one after the other to one track of a fresh SQLite database
through its own app in a process of its own (``POST /api/v1/runs``: upload, parse, checks,
inversion, detection, storing, alignment, the aggregate's rebuild and whatever that
checkout does on integration), after one warm-up pass to another track. Rounds alternate
the checkouts so that a busy machine slows them alike; per pass the best of ``--rounds``.
Each upload is timed on the wall clock and in process CPU time (``time.process_time``: every
thread of the checkout's process, the app's worker threads included), which a machine loaded
by other work inflates far less. Prints a markdown table of each.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
LOGS = HERE / ".cache" / "pass_service"
SPEED_MPS = 24.0
RATE_HZ = 1000.0
T0 = datetime(2026, 3, 2, 6, 0, tzinfo=UTC)


def write_logs(passes: int) -> list[tuple[Path, float]]:
    """The passes' CSV logs and the start chainage each is uploaded with (m), made with this
    checkout's engine once and cached; the list is also kept in ``LOGS/passes.json``."""
    manifest = LOGS / "passes.json"
    if manifest.exists():
        cached = json.loads(manifest.read_text())
        if len(cached) >= passes + 1:
            return [(LOGS / name, start) for name, start in cached[: passes + 1]]
    sys.path.insert(0, str(REPO))
    import numpy as np

    from engine.logio import write_run_csv
    from engine.sensor import sensor_for_grade
    from engine.synthetic import make_run, make_track, to_runlog
    from engine.track import SoftZone

    zones = [SoftZone(150, 156, 0.45), SoftZone(300, 304, 0.35), SoftZone(480, 490, 0.3),
             SoftZone(760, 765, 0.5)]  # fmt: skip
    track = make_track(1000.0, zones=zones, jitter=0.05, seed=21)
    run = make_run(track=track, speed=SPEED_MPS, sim_rate_hz=RATE_HZ, seed=21)
    errors = np.random.default_rng(5).uniform(-1.0, 1.0, passes + 1)
    LOGS.mkdir(parents=True, exist_ok=True)
    out = []
    for i in range(passes + 1):
        sensor = sensor_for_grade("industrial-mems", RATE_HZ, seed=300 + i)
        buf = io.StringIO()
        write_run_csv(to_runlog(run.sim, sensor, seed=400 + i), buf, digits=8)
        name = f"pass_{i:02d}.csv"
        (LOGS / name).write_text(buf.getvalue(), encoding="utf-8")
        out.append((name, run.start_chainage_m + float(errors[i])))
    manifest.write_text(json.dumps(out))
    return [(LOGS / name, start) for name, start in out]


def read_logs(passes: int) -> list[tuple[Path, float]]:
    """The logs :func:`write_logs` made (without importing any checkout's engine)."""
    cached = json.loads((LOGS / "passes.json").read_text())
    return [(LOGS / name, start) for name, start in cached[: passes + 1]]


def one_tree(tree: Path, logs: list[tuple[Path, float]], at_m: float) -> list[tuple[float, float]]:
    """Upload the logs through ``tree``'s app (the first as a warm-up on its own track),
    ``at_m`` m further on than logged; each upload's wall time and process CPU time, s."""
    sys.path.insert(0, str(tree))
    from starlette.testclient import TestClient

    import app
    from app.core.config import Settings
    from app.main import create_app

    if not Path(app.__file__).resolve().is_relative_to(tree):
        raise SystemExit(f"app imported from {app.__file__}, not from {tree}")

    times = []
    with tempfile.TemporaryDirectory() as tmp:
        settings = Settings(data_dir=Path(tmp), database_url=f"sqlite:///{Path(tmp) / 'b.db'}")
        with TestClient(create_app(settings)) as client:
            for i, (path, start) in enumerate(logs):
                data = path.read_bytes()
                form = {"track": "warm" if i == 0 else "bench",
                        "start_chainage_m": str(start + at_m),
                        "recorded_at": (T0 + timedelta(days=i)).isoformat()}  # fmt: skip
                t0, c0 = time.perf_counter(), time.process_time()
                r = client.post("/api/v1/runs", files={"file": ("p.csv", data, "text/csv")},
                                data=form)  # fmt: skip
                times.append((time.perf_counter() - t0, time.process_time() - c0))
                if r.status_code != 201:
                    raise SystemExit(f"{tree}: upload {i} answered {r.status_code}: {r.text}")
    return times[1:]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--trees", default=str(REPO), help="checkouts, comma-separated")
    p.add_argument("--passes", type=int, default=12)
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--at-m", type=float, default=12600.0, help="chainage offset, m")
    p.add_argument("--one", help=argparse.SUPPRESS)
    ns = p.parse_args()
    if ns.one:
        print(json.dumps(one_tree(Path(ns.one).resolve(), read_logs(ns.passes), ns.at_m)))
        return
    write_logs(ns.passes)
    trees = [Path(t).resolve() for t in ns.trees.split(",")]
    inf = (float("inf"), float("inf"))
    best: dict[Path, list[tuple[float, float]]] = {t: [inf] * ns.passes for t in trees}
    for _ in range(ns.rounds):
        for t in trees:
            cmd = [sys.executable, __file__, "--one", str(t), "--passes", str(ns.passes),
                   "--at-m", str(ns.at_m)]  # fmt: skip
            env = {**os.environ, "PYTHONPATH": str(t)}
            got = json.loads(subprocess.run(cmd, check=True, capture_output=True, cwd=t, env=env,
                                            text=True).stdout.splitlines()[-1])  # fmt: skip
            best[t] = [(min(a[0], b[0]), min(a[1], b[1]))
                       for a, b in zip(best[t], got, strict=True)]  # fmt: skip
    sys.path.insert(0, str(HERE))
    from common import machine

    print(f"Machine: {machine()}. {ns.passes} passes of 1 km, per pass the best of "
          f"{ns.rounds} rounds, ms.\n")  # fmt: skip
    for k, clock in enumerate(("wall", "process CPU")):
        print(f"| checkout ({clock}) | first pass | passes 2-{ns.passes}: mean | median | "
              "whole track |")  # fmt: skip
        print("|---|---|---|---|---|")
        base = None
        for t in trees:
            ms = [1e3 * v[k] for v in best[t]]
            later = sorted(ms[1:])
            mean = sum(later) / len(later)
            base = base or sum(ms)
            print(f"| {t} | {ms[0]:.0f} | {mean:.0f} | {later[len(later) // 2]:.0f} | "
                  f"{sum(ms):.0f} ({sum(ms) / base:.2f}x) |")  # fmt: skip
        print()


if __name__ == "__main__":
    main()
