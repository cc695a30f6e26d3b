"""The default method's wheel forces against the forward model's true contact forces.

A noisy run the accuracy table (``benchmarks/accuracy_wheel_force.py``) does not use: rough
rail (German low-disturbance geometry), +-5 % support scatter, a soft zone, an industrial
MEMS log (noise, bias and its wander, resolution, jitter) at 500 Hz, 42 m/s, the start
chainage logged 1.5 m off.
"""

from __future__ import annotations

import numpy as np
import pytest

from engine.chainage import to_grid
from engine.pipeline import process_run
from engine.sensor import sensor_for_grade
from engine.setup import RunSetup, prepare_run
from engine.synthetic import make_run, make_track
from engine.track import SoftZone
from engine.vehicle import TABLE1

BOUND_KN = 0.8
"""The default method's RMS wheel-force error on this run, kN: a quarter of what the spectral
method's flat weighting leaves on such a log (1.4 kN, docs/accuracy.md)."""


@pytest.mark.slow
def test_default_wheel_forces_are_within_the_bound_of_the_truth():
    """Per axle, on the profile grid away from the first and last 40 m: the pipeline's force
    (default method) minus the simulated contact force when that axle passed the point has an
    RMS below BOUND_KN, and the truth does vary there more than that (the check can fail)."""
    track = make_track(400.0, zones=(SoftZone(200.0, 206.0, 0.4),), jitter=0.05,
                       irregularity="german-low", seed=57)  # fmt: skip
    run = make_run(track=track, vehicle=TABLE1, speed=42.0, seed=57, sim_rate_hz=500.0,
                   sensor=sensor_for_grade("industrial-mems", 500.0, 57),
                   start_chainage_m=15.0, start_error_m=1.5)  # fmt: skip
    prepared = prepare_run(
        run.log, RunSetup(start_chainage_m=run.logged_start_chainage_m, vehicle=TABLE1)
    )
    assert prepared.setup.config.method == "wiener"
    res = process_run(prepared)
    assert res.front_force_n is not None and res.rear_force_n is not None
    t = np.arange(run.log.n) * run.log.dt
    grid, sim = res.chainage_m, run.sim
    inner = (grid > grid[0] + 40.0) & (grid < grid[-1] - 40.0)
    axles = ((prepared.positions.front, sim.contact_front, res.front_force_n),
             (prepared.positions.rear, sim.contact_rear, res.rear_force_n))  # fmt: skip
    for positions, contact, force in axles:
        when = to_grid(positions, t, grid)
        ok = inner & np.isfinite(when) & np.isfinite(force)
        truth = np.interp(when[ok], sim.t, contact)
        rms_kn = float(np.sqrt(np.mean((force[ok] - truth) ** 2))) / 1e3
        assert ok.sum() > 0.5 * inner.sum()
        assert np.std(truth) / 1e3 > BOUND_KN
        assert rms_kn < BOUND_KN, f"RMS wheel-force error {rms_kn:.2f} kN"
