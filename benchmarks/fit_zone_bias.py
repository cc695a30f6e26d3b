"""The stiffness fit's loss error on exact static data, with and without the detector's baseline.

Run: ``python benchmarks/fit_zone_bias.py`` (seconds). A zone of each length and loss is
made with the direct beam solve (:class:`engine.stiffness.QuasiStaticModel`, table1's static
wheel load, nominal track), band-passed to 3-40 m like a processed profile, and fitted by
:func:`engine.stiffness.fit_zone` twice from its true extent: on the band-passed dip itself
and on what the pipeline fits, the dip minus the detector's running-median baseline
(:func:`engine.detect.robust_baseline`, ``DetectionConfig.baseline_window_m``). Prints the
fitted minus true loss, percentage points.
"""

from __future__ import annotations

import numpy as np

from engine.chainage import bandpass_distance
from engine.detect import DetectionConfig, robust_baseline
from engine.stiffness import QuasiStaticModel, fit_zone
from engine.track import TrackParams
from engine.vehicle import TABLE1


def main() -> None:
    p = TrackParams()
    load = float(np.mean(TABLE1.static_axle_loads()))
    step = 0.25
    grid = np.arange(0.0, 200.0, step)
    model = QuasiStaticModel(p, 0.0, 200.0, grid, load)
    sound = model.level(np.ones(model.node_x.size))
    window = DetectionConfig().baseline_window_m
    print("| zone length, m | loss | band-passed dip: error, pp | minus the baseline: error, pp |")
    print("|---|---|---|---|")
    for length in (3.0, 5.0, 8.0, 10.0):
        for loss in (0.3, 0.45, 0.6):
            a = 100.2
            b = a + round(length / p.spacing) * p.spacing
            soft = model.level(model.factors(a, b, loss))
            dip = bandpass_distance((soft - sound) * 1e3, step, 3.0, 40.0)
            res = dip - robust_baseline(dip, step, window)
            e1 = fit_zone(grid, dip, a, b, p, load, 3.0, 40.0).loss - loss
            e2 = fit_zone(grid, res, a, b, p, load, 3.0, 40.0).loss - loss
            print(f"| {length:.0f} | {loss:.2f} | {100 * e1:+.2f} | {100 * e2:+.2f} |")


if __name__ == "__main__":
    main()
