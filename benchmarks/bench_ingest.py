"""The upload path of a 1-hour log, stage by stage, in one process (no HTTP, no database).

    python benchmarks/bench_ingest.py [--repeats 3]

What ``POST /api/v1/runs`` does with a 135 MB CSV before it answers 202, and what the
worker does before the engine, each stage timed alone on the cached 1-hour log of
``bench_service.py`` (best of ``--repeats``): the CSV's byte checks, the table read (the
threaded pyarrow reader and the reference numpy reader), the whole of ``parse_run_csv``,
the plausibility checks, hashing, the upload-time pre-flight, the display signals,
compressing the log for storage and uncompressing it in the worker. ``bench_service.py``
gives the end-to-end figure these add up to (plus the multipart body, the database and the
engine). The load average is printed with the figures: on the shared 2-core machine a
loaded measurement is several times a quiet one.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench_service import hour_csv  # noqa: E402
from common import machine  # noqa: E402


def best(fn: Callable[[], Any], repeats: int) -> tuple[float, Any]:
    """Fastest of ``repeats`` calls, s, and the last result."""
    times = []
    out = None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=3)
    ns = ap.parse_args()

    from app.services.run_lifecycle.logs import (
        pack_log,
        recorded_at_of,
        sha256_hex,
        summarize,
        unpack_log,
    )
    from app.services.views.signals import log_signals
    from engine.logio import header as lheader
    from engine.logio import limits, parse_run_csv, source, table, threaded
    from engine.plausibility import check_plausible
    from engine.setup import RunSetup, prepare_run

    path, start = hour_csv()
    r = ns.repeats
    rows: list[tuple[str, float]] = []
    t_read, data = best(path.read_bytes, r)
    rows.append((f"read the file from disk ({len(data) / 1e6:.0f} MB)", t_read))
    rows.append(
        ("check_lines (line lengths, raw bytes)", best(lambda: limits.check_lines(data), r)[0])
    )
    rows.append(("text encoding", best(lambda: source._detect_encoding(data), r)[0]))
    src = source._Source(data, "utf-8-sig")
    with src.lines() as f:
        hdr = lheader._read_header(f)
    needed = list(range(len(hdr.names)))
    rows.append(
        (
            "table, threaded reader (pyarrow)",
            best(lambda: threaded.parse_arrow(src, hdr, needed), r)[0],
        )
    )
    rows.append(
        (
            "table, reference reader (numpy)",
            best(lambda: table._parse_reference(src, hdr, needed), r)[0],
        )
    )
    t_parse, parsed = best(lambda: parse_run_csv(data), r)
    rows.append(("parse_run_csv, all of it (threaded)", t_parse))
    log = parsed.log
    rows.append(("  of which check_plausible", best(lambda: check_plausible(log), r)[0]))
    rows.append(("sha256 of the body", best(lambda: sha256_hex(data), r)[0]))
    rows.append(("recorded_at (the file's clock)", best(lambda: recorded_at_of(data, {}), r)[0]))
    rows.append(
        (
            "pre-flight (prepare_run of the read CSV)",
            best(lambda: prepare_run(log, RunSetup(start), log_checked=True), r)[0],
        )
    )
    rows.append(
        ("summary + display signals", best(lambda: (summarize(log), log_signals(log)), r)[0])
    )
    t_pack, packed = best(lambda: pack_log(log), r)
    rows.append((f"pack_log (compress, {len(packed) / 1e6:.0f} MB)", t_pack))
    rows.append(("unpack_log (the worker)", best(lambda: unpack_log(packed), r)[0]))

    print(f"machine: {machine()}; load average {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print(f"1-hour log: {log.n} samples, best of {r}")
    for what, t in rows:
        print(f"  {what:<48} {t:6.3f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
