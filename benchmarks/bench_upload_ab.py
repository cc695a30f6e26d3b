"""A queued upload -> done, two source trees side by side in one sitting (before/after).

    python benchmarks/bench_upload_ab.py --before DIR --after DIR [--minutes 10] [--rounds 3]

``DIR`` is a checkout of the service (e.g. ``git archive <commit> | tar -x -C DIR``). The log
is the forward-model simulation of ``benchmarks/common.py`` (1 kHz, 30 m/s; ``--minutes 60``
is the 1-hour log of ``bench_service.py``), written as a canonical CSV with 8 significant
digits and cached under ``benchmarks/.cache``. Each round starts a fresh uvicorn process of
each tree on a fresh SQLite file (the order alternates between rounds), uploads the log
(multipart; queued: longer than ``TRACKPROFILE_INLINE_MAX_SAMPLES``) and polls the run until
it is done: the wall time from the upload's start, and when the 202 came.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_service import hour_csv, wait_healthy  # noqa: E402
from common import machine  # noqa: E402


def upload_to_done(tree: Path, csv_path: Path, start: float, port: int) -> tuple[float, float]:
    """Seconds from the upload's start to the run done, and to the 202, on a fresh server."""
    with tempfile.TemporaryDirectory(prefix="bench-ab-") as data_dir:
        env = {
            **os.environ, "TRACKPROFILE_DATA_DIR": data_dir, "PYTHONPATH": str(tree),
            "TRACKPROFILE_MAX_UPLOAD_MB": "1000", "TRACKPROFILE_INLINE_MAX_SAMPLES": "1000",
        }  # fmt: skip
        env.pop("DATABASE_URL", None)
        server = subprocess.Popen(
            [sys.executable, "-m", "uvicorn", "app.main:app", "--host", "127.0.0.1",
             "--port", str(port), "--log-level", "warning"], cwd=tree, env=env,
        )  # fmt: skip
        try:
            base = f"http://127.0.0.1:{port}"
            wait_healthy(base)
            with httpx.Client(base_url=base, timeout=600) as c, open(csv_path, "rb") as fh:
                t0 = time.perf_counter()
                r = c.post("/api/v1/runs", files={"file": ("log.csv", fh, "text/csv")},
                           data={"track": "ab", "start_chainage_m": str(start)})  # fmt: skip
                accepted = time.perf_counter() - t0
                assert r.status_code == 202, r.text
                run = r.json()
                while run["status"] == "processing":
                    time.sleep(0.05)
                    run = c.get(f"/api/v1/runs/{run['id']}").json()
                done = time.perf_counter() - t0
            if run["status"] != "done":
                raise RuntimeError(f"{tree}: the run failed: {run['error']}")
            return done, accepted
        finally:
            server.terminate()
            server.wait(timeout=30)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--before", type=Path, required=True)
    ap.add_argument("--after", type=Path, required=True)
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--port", type=int, default=8790)
    ns = ap.parse_args()
    csv_path, start = hour_csv(ns.minutes)
    trees = {"before": ns.before.resolve(), "after": ns.after.resolve()}
    times: dict[str, list[tuple[float, float]]] = {k: [] for k in trees}
    for r in range(ns.rounds):
        order = list(trees) if r % 2 == 0 else list(reversed(trees))
        for name in order:
            times[name].append(upload_to_done(trees[name], csv_path, start, ns.port))
            print(f"round {r + 1} {name}: done after {times[name][-1][0]:.2f} s "
                  f"(202 after {times[name][-1][1]:.2f} s)", flush=True)  # fmt: skip
    print(f"machine: {machine()}; load average {os.getloadavg()[0]:.1f}")
    for name, tt in times.items():
        done = sorted(t for t, _ in tt)
        print(f"{name}: upload -> done {' '.join(f'{t:.2f}' for t in done)} s, "
              f"best {done[0]:.2f} s, median {done[len(done) // 2]:.2f} s")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
