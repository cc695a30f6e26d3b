"""The spectral inverse's band spectrum evaluated on a chainage grid from a decimated copy
(no full-rate inverse transform of the levels) against the full-rate levels.

Realistic runs (German low-disturbance geometry, realistic sensor noise and bias, a start
chainage logged 1.5 m off) at three speeds, i.e. three decimation steps; both directions.
"""

from __future__ import annotations

import numpy as np
import pytest

from engine.chainage import to_grid
from engine.methods import METHODS, MethodInput
from engine.pipeline import ProcessConfig, process_run
from engine.setup import RunSetup, prepare_run
from engine.spectral import SPLINE_OVERSAMPLING, decimation_step, spectral_inverse
from engine.synthetic import REALISTIC_SENSOR, make_run, make_track
from engine.vehicle import TABLE1


@pytest.fixture(scope="module")
def track():
    return make_track(450.0, jitter=0.05, irregularity="german-low", seed=29)


CASES = [(12.0, "increasing"), (24.0, "decreasing"), (42.0, "increasing")]


@pytest.fixture(scope="module", params=CASES, ids=["12mps", "24mps-dec", "42mps"])
def inverted(request, track):
    speed, direction = request.param
    start = 20.0 if direction == "increasing" else 430.0
    run = make_run(track=track, vehicle=TABLE1, speed=speed, sensor=REALISTIC_SENSOR, seed=31,
                   start_chainage_m=start, start_error_m=1.5, direction=direction)  # fmt: skip
    log = run.log
    chk = prepare_run(
        log, RunSetup(start_chainage_m=run.logged_start_chainage_m, direction=direction)
    )
    inv = spectral_inverse(
        log.accel_z_mps2, log.pitch_rate_radps, log.dt, TABLE1, chk.f_lo_hz, chk.f_hi_hz
    )
    return run, chk, inv


def test_decimation_step_keeps_the_oversampling():
    """The step is the largest 2-3-5-smooth one that keeps 8 samples per period of the
    band's top; 1 when the log is too slow for any."""
    assert decimation_step(1e-3, 17.0) == 6  # 1000 / (8 * 17) = 7.35
    assert decimation_step(1e-3, 12.0) == 10  # 10.4
    assert decimation_step(2e-3, 50.0) == 1
    for dt, f in ((1e-3, 5.0), (1e-3, 31.0), (5e-3, 9.0)):
        step = decimation_step(dt, f)
        assert 1 / (dt * step) >= SPLINE_OVERSAMPLING * f


@pytest.mark.slow
def test_decimated_samples_are_the_full_rate_ones(inverted):
    """The short inverse transform gives the full-rate levels at every step-th sample."""
    _, _, inv = inverted
    band = inv.band
    assert band.step > 1 and band.nfft % band.step == 0
    t, y = band.decimated()
    full = band.to_time()
    inside = (t >= 0) & (t <= (band.n - 1) * band.dt + 1e-9)
    idx = np.rint(t[inside] / band.dt).astype(int)
    np.testing.assert_allclose(y[:, inside], full[:, idx], rtol=0, atol=1e-9 * np.ptp(full))


def test_levels_at_any_sample_time_match_the_full_rate_levels(inverted):
    """Between the decimated samples the spline gives the full-rate levels within 3e-5 of
    their range (a few 1e-4 mm)."""
    run, _, inv = inverted
    full = inv.band.to_time()
    t = np.arange(run.log.n) * run.log.dt
    at = inv.band.at_times(np.stack([t, t]))
    assert np.max(np.abs(at - full)) < 3e-5 * np.ptp(full)
    nan_t = np.stack([np.full(3, np.nan), t[:3]])
    assert np.isnan(inv.band.at_times(nan_t)[0]).all()


def test_profile_on_the_grid_matches_the_full_rate_levels_gridded(inverted):
    """The spectral method's levels per axle on the grid are the full-rate levels put on the
    grid (linear interpolation of 1 kHz samples) and band-passed, within 0.001 mm."""
    run, chk, inv = inverted
    cfg = ProcessConfig()
    pos = chk.positions
    lo, hi = min(pos.front.min(), pos.rear.min()), max(pos.front.max(), pos.rear.max())
    grid = np.arange(np.ceil(lo / 0.25) * 0.25, hi + 1e-9, 0.25)
    given = MethodInput(
        log=run.log, positions=pos, grid=grid, step_m=0.25, vehicle=TABLE1,
        f_lo_hz=chk.f_lo_hz, f_hi_hz=chk.f_hi_hz, lambda_min_m=cfg.lambda_min_m,
        lambda_max_m=cfg.lambda_max_m, taper=cfg.taper,
    )  # fmt: skip
    got = METHODS["spectral"](given)
    assert got.y_front is None and got.band is not None
    for axle, y in ((pos.front, inv.y_front), (pos.rear, inv.y_rear)):
        want = given.bandpass(to_grid(axle, y * 1e3, grid))
        have = got.front_mm if axle is pos.front else got.rear_mm
        ok = np.isfinite(want)
        assert np.array_equal(ok, np.isfinite(have))
        assert np.max(np.abs(have[ok] - want[ok])) < 1e-3


def test_pipeline_forces_match_the_full_rate_forces_gridded(inverted):
    """process_run's wheel forces with the spectral method (band spectrum, decimated) are its
    full-rate forces on the grid within 5 N (their dynamic part spreads over ~1 kN)."""
    from engine.wheel_force import force_spectrum

    run, chk, inv = inverted
    direction = "increasing" if chk.positions.sign > 0 else "decreasing"
    setup = RunSetup(
        start_chainage_m=run.logged_start_chainage_m, direction=direction,
        config=ProcessConfig(method="spectral"),
    )  # fmt: skip
    res = process_run(prepare_run(run.log, setup))
    f1, f2 = force_spectrum(inv.band, TABLE1).to_time()
    static = TABLE1.static_axle_loads()
    pos = chk.positions
    for have, axle, f, s in ((res.front_force_n, pos.front, f1, static[0]),
                             (res.rear_force_n, pos.rear, f2, static[1])):  # fmt: skip
        want = s + to_grid(axle, f, res.chainage_m)
        ok = np.isfinite(want)
        assert np.max(np.abs(have[ok] - want[ok])) < 5.0
        assert np.std(want[ok]) > 100.0
