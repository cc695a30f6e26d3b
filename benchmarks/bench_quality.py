"""Time of the numerics behind ``GET /tracks/{t}/quality`` (engine.track_quality), by track
length and number of passes. Prints a Markdown table for docs/benchmarks.md.

Run: ``python benchmarks/bench_quality.py`` (about a minute on 2 cores).

What the service computes per request, on the 0.25 m grid: the track's level filtered to D1
and D2, every pass filtered to D1 (sections, trends) and to 6-70 m (repeatability), the
section SDs, the isolated defects of both bands and the repeatability of successive passes.
The database reads (one range scan per table) are not included.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
from common import best_of, machine  # noqa: E402

from engine.quality_limits import QualityLimits, isolated_defects  # noqa: E402
from engine.track_quality import (  # noqa: E402
    BANDS,
    BandFilter,
    repeatability,
    section_statistics,
)

STEP = 0.25
REP = BandFilter("rep", 6.0, 70.0)


def answer(x: np.ndarray, level: np.ndarray, passes: list[np.ndarray]) -> int:
    filt = {n: b.apply(level, STEP) for n, b in BANDS.items()}
    section_statistics(x, filt, 200.0)
    [BANDS["D1"].apply(p, STEP) for p in passes]
    repeatability([REP.apply(p, STEP) for p in passes], pairs="successive")
    lim = QualityLimits()
    return sum(len(isolated_defects(x, filt[n], n, lim)) for n in BANDS)


def case(km: int, n_pass: int, rng: np.random.Generator) -> float:
    x = np.arange(0.0, km * 1000.0, STEP)
    level = np.cumsum(rng.normal(size=x.size)) * 0.01
    passes = [level + 0.05 * rng.normal(size=x.size) for _ in range(n_pass)]
    t, _ = best_of(lambda: answer(x, level, passes), repeat=3 if km < 100 else 1)
    return t


def main() -> None:
    rng = np.random.default_rng(0)
    rows = []
    for km, n_pass in ((1, 10), (10, 20), (10, 50), (100, 50)):
        rows.append(f"| {km} km | {n_pass} | {case(km, n_pass, rng):.2f} s |")
    print(f"Measured by `python benchmarks/bench_quality.py` ({machine()}):\n")
    print("| track | passes | numerics of one quality answer |\n|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
