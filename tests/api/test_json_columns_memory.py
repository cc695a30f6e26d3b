"""JSON ``columns`` uploads are read into arrays without a Python object per number (issue 16,
High 1 for the JSON path): memory measured as the peak RSS of a real server.

``{"columns": {"time_s": [0,0,0,...], ...}}`` is 2 bytes per number; parsed into Python
lists it took ~35 bytes per number (a float object and a list slot, plus pydantic's
copies): a 32 MB body grew the server by 1.3 GB. The arrays are now parsed a chunk at a time
into float64 arrays (8 bytes per number: 4x the text of ``0,``, as for a CSV of zeros).
"""

from __future__ import annotations

import time

import httpx
import pytest

from api.api_support import row_counts
from api.live_server import LiveServer
from api.test_upload_memory import _rss_mb

LIMIT_MB = 50
N = 3_000_000


def _body(n: int, time_s: bytes | None = None) -> bytes:
    zeros = b"[" + b"0," * (n - 1) + b"0]"
    cols = b", ".join(
        b'"%s": %s' % (name, time_s if (time_s is not None and name == b"time_s") else zeros)
        for name in (b"time_s", b"accel_z_mps2", b"pitch_rate_radps", b"speed_mps")
    )
    return b'{"track": "T", "start_chainage_m": 0, "columns": {' + cols + b"}}"


@pytest.mark.slow
def test_big_json_columns_are_refused_fast_and_small(settings) -> None:
    """Four columns of 3 M zeros (24 MB): 422 naming time_s and its row 3 (time does not
    increase), within 10 s, the server's peak RSS growing by less than 4x the upload limit
    (the bound of the CSV path, test_upload_memory.py)."""
    server = LiveServer(settings, "jsonmem", TRACKPROFILE_MAX_UPLOAD_MB=LIMIT_MB).start()
    body = _body(N)
    try:
        with httpx.Client(base_url=server.url, timeout=60) as c:
            c.get("/api/v1/runs")  # warm up: imports, first session
            peak0 = _rss_mb(server)
            before = row_counts(settings)
            t0 = time.monotonic()
            r = c.post("/api/v1/runs", content=body, headers={"content-type": "application/json"})
            elapsed = time.monotonic() - t0
            peak1 = _rss_mb(server)
    finally:
        server.stop()
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert (detail.get("column"), detail.get("row")) == ("time_s", 3), detail
    assert elapsed < 10, elapsed
    growth = peak1 - peak0
    print(f"peak RSS {peak0:.0f} MB -> {peak1:.0f} MB (+{growth:.0f} MB) in {elapsed:.1f} s")
    assert growth < 4 * LIMIT_MB, (peak0, peak1)  # before: +1 GB
    assert row_counts(settings) == before
