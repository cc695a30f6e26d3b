"""Memory of hostile uploads, measured as the RSS of a real server (issue 16, High 1, Medium 4).

The probe's one-line CSV (a header, then 75 M fields of ``0,``: 145 KB gzip) took the server to
3.0 GB for 46 s before its 422. Here a 20 M-field line (40 MB, ~40 KB gzip; plain and gzip,
three at once) must be refused within seconds with the server's RSS growing by less than a
small multiple of the 50 MB upload limit.
"""

from __future__ import annotations

import gzip
import threading
import time

import httpx

from api.api_support import row_counts
from api.live_server import LiveServer

LIMIT_MB = 50
LINE = b"time_s,accel_z_mps2,pitch_rate_radps,speed_mps\n" + b"0," * 20_000_000 + b"0\n"


def _rss_mb(server: LiveServer) -> float:
    assert server.proc is not None
    with open(f"/proc/{server.proc.pid}/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):  # peak RSS of the process so far
                return int(line.split()[1]) / 1024
    raise AssertionError("no VmHWM")


def test_one_long_line_is_refused_fast_and_small(settings) -> None:
    """Plain and gzip 40 MB lines, then three gzip ones in parallel: each 422 naming line 2,
    each within 10 s, and the server's peak RSS grows by less than 4x the upload limit."""
    server = LiveServer(settings, "mem", TRACKPROFILE_MAX_UPLOAD_MB=LIMIT_MB).start()
    packed = gzip.compress(LINE, compresslevel=6)
    form = {"track": "T", "start_chainage_m": "0"}
    try:
        with httpx.Client(base_url=server.url, timeout=60) as c:
            c.get("/api/v1/runs")  # warm up: imports, first session
            peak0 = _rss_mb(server)
            before = row_counts(settings)
            answers = []
            for name, data in (("line.csv", LINE), ("line.csv.gz", packed)):
                t0 = time.monotonic()
                r = c.post("/api/v1/runs", files={"file": (name, data)}, data=form)
                answers.append((r.status_code, r.json()["detail"].get("row"),
                                time.monotonic() - t0))  # fmt: skip

        def one() -> None:
            with httpx.Client(base_url=server.url, timeout=60) as c2:
                t0 = time.monotonic()
                r = c2.post("/api/v1/runs", files={"file": ("l.csv.gz", packed)}, data=form)
                answers.append((r.status_code, r.json()["detail"].get("row"),
                                time.monotonic() - t0))  # fmt: skip

        threads = [threading.Thread(target=one) for _ in range(3)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(60)
        peak1 = _rss_mb(server)
    finally:
        server.stop()
    assert [(s, row) for s, row, _ in answers] == [(422, 2)] * 5, answers
    assert max(dt for _, _, dt in answers) < 10, answers
    growth = peak1 - peak0
    print(f"peak RSS {peak0:.0f} MB -> {peak1:.0f} MB (+{growth:.0f} MB)")
    assert growth < 4 * LIMIT_MB, (peak0, peak1)  # measured: +128 MB (5 uploads, 3 at once)
    assert row_counts(settings) == before
