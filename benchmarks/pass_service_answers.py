"""What the service answers for a track's passes, from checkouts side by side: the same or not.

Run: ``python benchmarks/pass_service_answers.py --trees DIR,DIR [--seeds 71,72,73]``
(a few minutes). For a change meant to leave the answers as they are (a cheaper pass):
each checkout (e.g. a ``git archive`` of the commit before beside this one) uploads the same
passes one after the other to a fresh SQLite database through its own app, in a process of
its own, and records after every upload the run's stored soft spots
(``GET /runs/{id}/soft-spots``) and the combined passes' spots kept per chunk
(``track_profile_chunks.spots``), and after the last the track's register
(``GET /tracks/{t}/defects``) and stiffness separation (``GET /tracks/{t}/stiffness``).
The sets: ``bench_pass_service.py``'s 12 industrial-MEMS passes (its cached logs), and per
seed of ``--seeds`` a 1 km track of five zones (3-10 m, 30-60 % loss, drawn from the seed;
supports scattered 5 %) passed at 18-28 m/s by six industrial-MEMS, one tactical and one
fibre-optic logger, start chainages off by up to +-1 m (logs made with this checkout's
engine, cached under ``benchmarks/.cache``). Prints, per set, how many numbers were compared,
how many differ and the largest difference; exits 1 when any differs by more than ``--tol``.
"""

from __future__ import annotations

import argparse
import io
import json
import math
import os
import sqlite3
import subprocess
import sys
import tempfile
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
LOGS = HERE / ".cache" / "pass_service_answers"
RATE_HZ = 1000.0
T0 = datetime(2026, 4, 6, 7, 0, tzinfo=UTC)
GRADES = ("industrial-mems",) * 6 + ("tactical-mems", "fibre-optic")


def seed_logs(seed: int) -> list[tuple[Path, float]]:
    """Seed ``seed``'s passes (CSV) and their logged start chainages (m), made once."""
    folder = LOGS / f"seed_{seed}"
    manifest = folder / "passes.json"
    if manifest.exists():
        return [(folder / n, s) for n, s in json.loads(manifest.read_text())]
    sys.path.insert(0, str(REPO))
    import numpy as np

    from engine.logio import write_run_csv
    from engine.sensor import sensor_for_grade
    from engine.synthetic import make_run, make_track, to_runlog
    from engine.track import SoftZone

    rng = np.random.default_rng(seed)
    starts = np.sort(rng.choice(np.arange(60, 920, 20), 5, replace=False))
    zones = [SoftZone(float(a), float(a + rng.uniform(3, 10)), float(rng.uniform(0.3, 0.6)))
             for a in starts]  # fmt: skip
    track = make_track(1000.0, zones=zones, jitter=0.05, seed=seed)
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for i, grade in enumerate(GRADES):
        speed = float(rng.uniform(18.0, 28.0))
        run = make_run(track=track, speed=speed, sim_rate_hz=RATE_HZ, seed=seed * 100 + i)
        sensor = sensor_for_grade(grade, RATE_HZ, seed=seed * 1000 + i)
        buf = io.StringIO()
        write_run_csv(to_runlog(run.sim, sensor, seed=seed * 1000 + 500 + i), buf, digits=8)
        name = f"pass_{i:02d}.csv"
        (folder / name).write_text(buf.getvalue(), encoding="utf-8")
        out.append((name, run.start_chainage_m + float(rng.uniform(-1.0, 1.0))))
    manifest.write_text(json.dumps(out))
    return [(folder / n, s) for n, s in out]


def bench_logs() -> list[tuple[Path, float]]:
    """``bench_pass_service.py``'s passes (made there once), the warm-up pass left out."""
    sys.path.insert(0, str(HERE))
    import bench_pass_service as bench

    return [(p, s + 12600.0) for p, s in bench.write_logs(12)[1:]]


def answers(tree: Path, logs: list[tuple[Path, float]]) -> dict[str, Any]:
    """Upload ``logs`` through ``tree``'s app to one track; what it answered (see above)."""
    sys.path.insert(0, str(tree))
    from starlette.testclient import TestClient

    import app
    from app.core.config import Settings
    from app.main import create_app

    if not Path(app.__file__).resolve().is_relative_to(tree):
        raise SystemExit(f"app imported from {app.__file__}, not from {tree}")
    out: dict[str, Any] = {"runs": [], "chunks": []}
    with tempfile.TemporaryDirectory() as tmp:
        db = Path(tmp) / "a.db"
        settings = Settings(data_dir=Path(tmp), database_url=f"sqlite:///{db}")
        with TestClient(create_app(settings)) as client:
            for i, (path, start) in enumerate(logs):
                form = {"track": "answers", "start_chainage_m": str(start),
                        "recorded_at": (T0 + timedelta(days=i)).isoformat()}  # fmt: skip
                r = client.post("/api/v1/runs", files={"file": ("p.csv", path.read_bytes(),
                                "text/csv")}, data=form)  # fmt: skip
                if r.status_code != 201:
                    raise SystemExit(f"{tree}: upload {i} answered {r.status_code}: {r.text}")
                rid = r.json()["id"]
                out["runs"].append(client.get(f"/api/v1/runs/{rid}/soft-spots").json())
                with sqlite3.connect(db) as con:
                    rows = con.execute(
                        "SELECT chunk, spots FROM track_profile_chunks ORDER BY chunk"
                    ).fetchall()
                out["chunks"].append([[c, json.loads(s) if s else s] for c, s in rows])
            out["defects"] = client.get("/api/v1/tracks/answers/defects").json()
            out["stiffness"] = client.get("/api/v1/tracks/answers/stiffness").json()
    return out


def compare(a: Any, b: Any, path: str = "") -> tuple[int, int, float, list[str]]:
    """Numbers compared, numbers that differ, the largest difference and where the two
    differ in shape or text (numbers compared absolutely; NaN and null equal themselves)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return 0, 0, 0.0, [f"{path}: keys {sorted(a)} != {sorted(b)}"]
        parts = [compare(a[k], b[k], f"{path}.{k}") for k in a]
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return 0, 0, 0.0, [f"{path}: {len(a)} items != {len(b)}"]
        parts = [compare(x, y, f"{path}[{i}]") for i, (x, y) in enumerate(zip(a, b, strict=True))]
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        fa, fb = float(a), float(b)
        if math.isnan(fa) and math.isnan(fb) or fa == fb:
            return 1, 0, 0.0, []
        return 1, 1, abs(fa - fb), []
    else:
        return 0, 0, 0.0, [] if a == b else [f"{path}: {a!r} != {b!r}"]
    n = sum(p[0] for p in parts)
    bad = sum(p[1] for p in parts)
    worst = max((p[2] for p in parts), default=0.0)
    return n, bad, worst, [m for p in parts for m in p[3]]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--trees", required=True, help="two checkouts, comma-separated")
    p.add_argument("--seeds", default="71,72,73", help="seeds of the other sets ('' for none)")
    p.add_argument("--tol", type=float, default=1e-12, help="largest difference allowed")
    p.add_argument("--one", help=argparse.SUPPRESS)
    p.add_argument("--set", help=argparse.SUPPRESS)
    ns = p.parse_args()
    if ns.one:
        logs = bench_logs() if ns.set == "bench" else seed_logs(int(ns.set))
        print(json.dumps(answers(Path(ns.one).resolve(), logs)))
        return
    trees = [Path(t).resolve() for t in ns.trees.split(",")]
    if len(trees) != 2:
        raise SystemExit("--trees takes two checkouts")
    sets = ["bench"] + [s for s in ns.seeds.split(",") if s]
    failed = False
    for name in sets:
        bench_logs() if name == "bench" else seed_logs(int(name))  # made here, read there
        got = []
        for t in trees:
            cmd = [sys.executable, __file__, "--one", str(t), "--set", name, "--trees", ns.trees]
            env = {**os.environ, "PYTHONPATH": str(t)}
            done = subprocess.run(cmd, check=True, capture_output=True, cwd=t, env=env, text=True)
            got.append(json.loads(done.stdout.splitlines()[-1]))
        n, bad, worst, shape = compare(*got)
        spots = sum(len(r) for r in got[0]["runs"])
        kept = sum(len(s or ()) for _, s in got[0]["chunks"][-1])
        print(f"set {name}: {spots} run soft spots, {kept} combined spots kept at the end, "
              f"{len(got[0]['defects'])} defects; {n} numbers compared, {bad} differ, largest "
              f"difference {worst:.3g}; {len(shape)} differences of shape or text")  # fmt: skip
        for m in shape[:10]:
            print("  ", m)
        failed |= bool(shape) or worst > ns.tol
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
