"""Accuracy of GNSS placement: chainage error of runs placed by their fixes.

Run: ``python benchmarks/accuracy_positioning.py`` (prints a Markdown table for
docs/accuracy.md; about 20 s).

A 1 km pass at 30 m/s over the synthetic bend (tests/support/gnss.py: 300 m straight, 600 m
of 1 200 m radius, straight; line chainage from 11 900 m), odometer 0.6 % long, 10 Hz fixes.
For each noise case, 100 seeds; the figure is each run's largest |fitted - true| chainage
over the whole run (end to end), m.

Second table: the lateral tolerance (``LATERAL_TOLERANCE_M``, 3 m) on the same
short runs, the hardest case (a 33 s run sees one value of a bias wandering over 30 s): how
often a run on its own track is refused as beside the line, and how often a run on a
neighbouring track is placed, with the median reported lateral offset.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import numpy as np  # noqa: E402

from engine.positioning import (  # noqa: E402
    LATERAL_TOLERANCE_M,
    FixesBesideLine,
    centerline_from_geojson,
    place_run,
)
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
    ("as above, centerline drawn 1 m off the track's middle",
     {"bias_m": 1.0, "bias_tau_s": 30.0, "lateral_m": 1.0}),
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


LATERAL_CASES = [
    ("own track, bias 1 m/axis, tau 30 s", 0.0, True),
    ("own track, centerline 1 m off", 1.0, True),
    ("own track, centerline 2 m off (drawn between two tracks)", 2.0, True),
    ("neighbouring track 3.4 m away", 3.4, False),
    ("neighbouring track 4.0 m away", 4.0, False),
    ("neighbouring track 4.5 m away", 4.5, False),
]


def lateral() -> None:
    line = centerline_from_geojson(centerline_geojson())
    t = np.arange(0.0, 33.0, 0.002)
    true = LINE_START_CHAINAGE_M + RUN_OFFSET_M + 24.0 + 30.0 * t
    odo = 1.006 * 30.0 * t
    print()
    print(f"| run (white 1.5 m + bias 1 m/axis, tau 30 s) | refused (> {LATERAL_TOLERANCE_M:g} m) "
          "| placed | median lateral offset, m |")  # fmt: skip
    print("|---|---|---|---|")
    for name, offset, own in LATERAL_CASES:
        refused, offsets = 0, []
        for seed in range(100):
            lat, lon = gnss_fixes(true, t, seed=seed, bias_m=1.0, bias_tau_s=30.0,
                                  lateral_m=offset)  # fmt: skip
            try:
                offsets.append(place_run(line, t, odo, lat, lon).lateral_offset_m)
            except FixesBesideLine as exc:
                refused += 1
                offsets.append(exc.lateral_offset_m)
        wrong = refused if own else 100 - refused
        print(
            f"| {name} | {refused} % | {100 - refused} % | {np.median(offsets):.2f} "
            f"({'wrongly refused' if own else 'wrongly placed'}: {wrong} %) |"
        )


if __name__ == "__main__":
    main()
    lateral()
