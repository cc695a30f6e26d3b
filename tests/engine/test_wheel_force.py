"""Wheel forces taken from the spectral inverse's band spectrum (no second transform of the
levels) against the time-domain path and against the forward model's contact force.

A realistic run: German low-disturbance geometry, +-5 % support scatter, a soft zone,
realistic sensor noise and bias, a start chainage logged 1.2 m off; both vehicles.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from engine.setup import RunSetup, prepare_run
from engine.spectral import spectral_inverse
from engine.synthetic import REALISTIC_SENSOR, make_run, make_track
from engine.track import SoftZone
from engine.vehicle import HEAVY, TABLE1
from engine.wheel_force import dynamic_wheel_forces, force_spectrum


@pytest.fixture(scope="module", params=[TABLE1, HEAVY], ids=["table1", "heavy"])
def inverted(request):
    vehicle = request.param
    sensor = dataclasses.replace(REALISTIC_SENSOR, sample_rate_hz=500.0)
    track = make_track(700.0, zones=(SoftZone(300.0, 308.0, 0.4),), jitter=0.05,
                       irregularity="german-low", seed=17)  # fmt: skip
    run = make_run(track=track, vehicle=vehicle, speed=24.0, sensor=sensor, sim_rate_hz=500.0,
                   seed=23, start_chainage_m=15.0, start_error_m=1.2)  # fmt: skip
    log = run.log
    chk = prepare_run(log, RunSetup(start_chainage_m=run.logged_start_chainage_m, vehicle=vehicle))
    inv = spectral_inverse(
        log.accel_z_mps2, log.pitch_rate_radps, log.dt, vehicle, chk.f_lo_hz, chk.f_hi_hz
    )
    return run, vehicle, inv


def test_band_spectrum_is_the_levels_spectrum(inverted):
    """The band spectrum transformed back is exactly the returned levels."""
    _, _, inv = inverted
    y = inv.band.to_time()
    np.testing.assert_array_equal(y[0], inv.y_front)
    np.testing.assert_array_equal(y[1], inv.y_rear)


def test_forces_from_the_band_equal_the_time_domain_path_inside_the_log(inverted):
    """Same operator: away from the ends (where mirrored and zero padding differ) the two
    paths agree within 3 % of the force's spread, per axle (the time path's zero padding
    leaves a slowly decaying transient of ~1.5 % a quarter into a 30 s log)."""
    run, vehicle, inv = inverted
    dt = run.log.dt
    by_time = dynamic_wheel_forces(inv.y_front, inv.y_rear, dt, vehicle)
    by_band = force_spectrum(inv.band, vehicle).to_time()
    n = run.log.n
    inner = slice(int(0.25 * n), int(0.75 * n))
    for a, b in zip(by_time, by_band, strict=True):
        assert a.shape == b.shape == (n,)
        assert np.max(np.abs(a[inner] - b[inner])) < 0.03 * np.std(a[inner])


def test_forces_from_the_band_are_as_close_to_the_forward_model(inverted):
    """Against the simulated contact force (minus the static load) over the whole log but
    its first and last 40 m: the band path is no worse than the time-domain path (2 %)."""
    run, vehicle, inv = inverted
    log, sim = run.log, run.sim
    dt = log.dt
    static = vehicle.static_axle_loads()
    by_time = dynamic_wheel_forces(inv.y_front, inv.y_rear, dt, vehicle)
    by_band = force_spectrum(inv.band, vehicle).to_time()
    for axle, (x, true) in enumerate(((sim.x_front, sim.contact_front),
                                      (sim.x_rear, sim.contact_rear))):  # fmt: skip
        t = np.interp(np.arange(log.n) * dt, sim.t, true) - static[axle]
        pos = np.interp(np.arange(log.n) * dt, sim.t, x)
        keep = (pos > pos.min() + 40.0) & (pos < pos.max() - 40.0)
        err_time = np.sqrt(np.mean((by_time[axle] - t)[keep] ** 2))
        err_band = np.sqrt(np.mean((by_band[axle] - t)[keep] ** 2))
        assert np.std(t[keep]) > 300.0  # the geometry does drive a dynamic force
        assert err_band < 0.3 * np.std(t[keep])
        assert err_band <= 1.02 * err_time
