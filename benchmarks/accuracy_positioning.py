"""Accuracy of GNSS placement (issue 11): chainage error of runs placed by their fixes.

Run: ``python benchmarks/accuracy_positioning.py`` (prints a Markdown table for
docs/accuracy.md; about 20 s).

A 1 km pass at 30 m/s over the synthetic bend (tests/support/gnss.py: 300 m straight, 600 m
of 1 200 m radius, straight; line chainage from 11 900 m), odometer 0.6 % long, 10 Hz fixes.
For each noise case, 100 seeds; the figure is each run's largest |fitted - true| chainage
over the whole run (end to end), m.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import numpy as np  # noqa: E402

from engine.positioning import centerline_from_geojson, place_run  # noqa: E402
from support.gnss import (  # noqa: E402
    LINE_START_CHAINAGE_M,
    RUN_OFFSET_M,
    centerline_geojson,
    gnss_fixes,
)

CASES = [
    ("white 1.5 m, no bias", {"bias_m": 0.0}),
    ("white 1.5 m + bias 0.71 m/axis (1 m horizontal), tau 10 s",
     {"bias_m": 0.71, "bias_tau_s": 10.0}),
    ("white 1.5 m + bias 1 m/axis, tau 30 s", {"bias_m": 1.0, "bias_tau_s": 30.0}),
    ("as above + parallel track 4.5 m", {"bias_m": 1.0, "bias_tau_s": 30.0, "lateral_m": 4.5}),
    ("white 3 m + bias 1 m/axis, tau 30 s, 1 Hz", {"white_m": 3.0, "bias_m": 1.0, "rate_hz": 1.0}),
]  # fmt: skip


def main() -> None:
    line = centerline_from_geojson(centerline_geojson())
    t = np.arange(0.0, 33.0, 0.002)
    true = LINE_START_CHAINAGE_M + RUN_OFFSET_M + 24.0 + 30.0 * t
    odo = 1.006 * 30.0 * t
    print("| fixes | median, m | 95 %, m | share < 1 m | scale error 95 %, % |")
    print("|---|---|---|---|---|")
    for name, kw in CASES:
        errs, scale = [], []
        for seed in range(100):
            lat, lon = gnss_fixes(true, t, seed=seed, **kw)
            fit = place_run(line, t, odo, lat, lon)
            errs.append(float(np.max(np.abs(fit.chainage(odo) - true))))
            scale.append(abs(fit.scale * 1.006 - 1.0) * 100)
        e = np.array(errs)
        print(
            f"| {name} | {np.median(e):.2f} | {np.percentile(e, 95):.2f} | "
            f"{np.mean(e < 1.0) * 100:.0f} % | {np.percentile(scale, 95):.2f} |"
        )


if __name__ == "__main__":
    main()
