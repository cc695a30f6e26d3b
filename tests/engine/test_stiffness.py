"""Stiffness-loss fit: the fast influence-line model against a direct beam solve."""

import numpy as np
import pytest
from scipy.linalg import solveh_banded

from engine.chainage import bandpass_distance
from engine.errors import ParameterError
from engine.stiffness import (
    InfluenceLine,
    QuasiStaticModel,
    _bandpass_block,
    _bandpass_rows,
    _fine_losses,
    fit_zone,
    modal_dips,
    softening_modes,
)
from engine.track import TrackParams
from engine.vehicle import TABLE1


def test_influence_line_matches_direct_solve():
    """Deflection under a moving unit load, from the influence line = a direct banded solve."""
    p = TrackParams()
    grid = np.arange(40.0, 60.0, 0.25)
    model = QuasiStaticModel(p, 40.0, 60.0, grid, load=1.0)
    direct = -model.level(np.ones(model.node_x.size))
    infl = InfluenceLine(p)
    # load at x: deflection under it = n(x)^T K^-1 n(x); at a support it is f(0)
    at_support = np.isclose(grid % p.spacing, 0.0) | np.isclose(grid % p.spacing, p.spacing)
    assert np.allclose(direct[at_support], infl(np.zeros(1))[0], rtol=1e-9)
    assert infl(np.array([0.3]))[0] == pytest.approx(infl(np.array([-0.3]))[0], rel=1e-12)
    assert infl(np.array([40.0]))[0] == 0.0


@pytest.mark.parametrize("start,end,loss", [(100.2, 104.4, 0.4), (98.4, 107.4, 0.6)])
def test_fit_recovers_zone_from_modelled_dip(start, end, loss):
    """A noise-free dip made with the direct beam solve is fitted back: extent and loss."""
    p = TrackParams()
    load = float(np.mean(TABLE1.static_axle_loads()))
    grid = np.arange(0.0, 200.0, 0.25)
    model = QuasiStaticModel(p, 0.0, 200.0, grid, load)
    ref = model.level(np.ones(model.node_x.size))
    soft = model.level(model.factors(start, end, loss))
    meas = bandpass_distance((soft - ref) * 1e3, 0.25, 3.0, 40.0)
    fit = fit_zone(grid, meas, start + 0.9, end - 0.9, p, load, 3.0, 40.0)
    assert fit.start_m == pytest.approx(start, abs=0.01)
    assert fit.end_m == pytest.approx(end, abs=0.01)
    assert fit.loss == pytest.approx(loss, abs=0.005)
    assert fit.rms_mm < 0.01 * np.max(np.abs(meas))


def test_modal_dips_equal_the_direct_beam_solve_and_the_low_rank_inverse():
    """The fit's modal form of a softened zone's dip (eigenbasis of the supports'
    flexibility) gives the level change of a direct beam solve, and the same numbers as the
    low-rank formula with a matrix inverse per loss; zero (not NaN) at loss 0."""
    p = TrackParams()
    load = float(np.mean(TABLE1.static_axle_loads()))
    grid = np.arange(0.0, 120.0, 0.25)
    start, end = 58.8, 63.0
    model = QuasiStaticModel(p, 0.0, 120.0, grid, load)
    ref = model.level(np.ones(model.node_x.size))
    infl = InfluenceLine(p)
    sup_x = np.arange(round(start / p.spacing), round(end / p.spacing) + 1) * p.spacing
    F = infl(sup_x[None, :] - sup_x[:, None])
    B = infl(grid[None, :] - sup_x[:, None])
    lam, E = softening_modes(F, B, np.eye(grid.size))
    losses = np.array([0.0, 0.2, 0.45, 0.8])
    dips = modal_dips(lam, E, losses, p.k_nominal, load)
    assert np.all(dips[0] == 0.0)
    for loss, dip in zip(losses[1:], dips[1:], strict=True):
        direct = (model.level(model.factors(start, end, loss)) - ref) * 1e3
        assert np.max(np.abs(dip - direct)) < 1e-6 * np.max(np.abs(direct))
        assert dip.min() < -0.01  # the zone sinks
        d = -loss * p.k_nominal
        low_rank = np.einsum("ig,ij,jg->g", B, np.linalg.inv(np.eye(F.shape[0]) / d + F), B)
        assert np.allclose(dip, low_rank * load * 1e3, rtol=1e-9, atol=1e-12)


def _bogie_dip(p, grid, start, end, loss, load, half_wheelbase):
    """Mean rail level under a bogie's two wheels (each ``load``) with the bogie centre at
    each grid point, soft zone minus nominal, from a direct beam solve, mm."""
    front = QuasiStaticModel(p, 0.0, 200.0, grid + half_wheelbase, load)
    rear = QuasiStaticModel(p, 0.0, 200.0, grid - half_wheelbase, load)
    assert np.array_equal(front.node_x, rear.node_x)

    def level(factors):
        band = front.band_beam.copy()
        band[3, 0::2] += p.k_nominal * factors
        W = solveh_banded(band, front.rhs + rear.rhs, lower=False)
        return -load * 0.5 * (front._at_load(W) + rear._at_load(W))

    ones = np.ones(front.node_x.size)
    return (level(front.factors(start, end, loss)) - level(ones)) * 1e3


@pytest.mark.parametrize("start,end,loss", [(100.2, 104.4, 0.55), (97.2, 105.0, 0.35)])
def test_fit_with_both_wheels_of_a_bogie(start, end, loss):
    """The dip a bogie measures (mean level under its two wheels 2.6 m apart, each the
    superposition of both wheels' basins) is fitted back with the wheels at their offsets;
    the same dip read as one load of both wheels at the bogie centre is off by many points
    (what a lumped half car reports)."""
    p = TrackParams()
    load = 46107.0
    grid = np.arange(20.0, 180.0, 0.25)
    meas = bandpass_distance(_bogie_dip(p, grid, start, end, loss, load, 1.3), 0.25, 3.0, 40.0)
    fit = fit_zone(
        grid, meas, start + 0.9, end - 0.9, p, load, 3.0, 40.0, wheel_offsets_m=(1.3, -1.3)
    )
    assert fit.start_m == pytest.approx(start, abs=0.01)
    assert fit.end_m == pytest.approx(end, abs=0.01)
    assert fit.loss == pytest.approx(loss, abs=0.005)
    lumped = fit_zone(grid, meas, start + 0.9, end - 0.9, p, 2 * load, 3.0, 40.0)
    assert abs(lumped.loss - loss) > 0.05


def test_fit_rejects_bad_wheel_offsets():
    """No wheels, or a non-finite offset, name the field."""
    grid = np.arange(0.0, 50.0, 0.25)
    with pytest.raises(ParameterError) as e:
        fit_zone(grid, np.zeros_like(grid), 20, 24, TrackParams(), 5e4, 3, 40, wheel_offsets_m=())
    assert e.value.field == "wheel_offsets_m"


@pytest.mark.parametrize(
    "n,lambda_max",
    # mirrored ends apart, overlapping (a point mirrored at both ends) and as long as the row
    [(517, 25.0), (300, 40.0), (300, 70.0), (5, 40.0), (2, 40.0)],
)
def test_bandpass_block_is_the_band_pass_of_unit_rows(n, lambda_max):
    """The fit's band-pass map taken from its convolution kernel equals band-passing each
    unit row (the map it replaces), rows and columns picked anywhere, ends included."""
    full = _bandpass_rows(np.eye(n), 0.25, 3.0, lambda_max, 0.3)
    rows = np.arange(0, n, 3)
    cols = np.arange(n - 1, -1, -2)
    block = _bandpass_block(n, 0.25, 3.0, lambda_max, 0.3, rows, cols)
    assert np.abs(block - full[np.ix_(rows, cols)]).max() <= 1e-14 * np.abs(full).max()


def test_fine_losses_are_the_clipped_linspace():
    """The loss search's fine grid is np.clip(np.linspace(lo, hi, 9), 0, MAX_LOSS) exactly."""
    from engine.stiffness import MAX_LOSS

    for lo, hi in [(0.1, 0.2), (-0.03, 0.05), (0.9, 0.98), (0.3172, 0.3735)]:
        want = np.clip(np.linspace(lo, hi, 9), 0.0, MAX_LOSS)
        assert np.array_equal(_fine_losses(lo, hi), want)


def test_fit_with_a_trend_ignores_a_level_and_slope_under_the_dip():
    """The modelled dip on a level and a slope (long-wave noise across the fitted window,
    as in the separation's compliance): fitted with a first-order trend, extent and loss are
    those of the dip alone; with the plain misfit the slope moves the ends or the loss."""
    p = TrackParams()
    load = float(np.mean(TABLE1.static_axle_loads()))
    grid = np.arange(0.0, 200.0, 0.25)
    start, end, loss = 100.2, 105.6, 0.45
    model = QuasiStaticModel(p, 0.0, 200.0, grid, load)
    ref = model.level(np.ones(model.node_x.size))
    dip = bandpass_distance((model.level(model.factors(start, end, loss)) - ref) * 1e3,
                            0.25, 3.0, 40.0)  # fmt: skip
    meas = dip - 0.1 - 0.02 * (grid - 103.0)  # mm: 0.1 mm low, falling 0.02 mm/m
    fit = fit_zone(grid, meas, start + 0.9, end - 0.9, p, load, 3.0, 40.0, trend_order=1)
    assert fit.start_m == pytest.approx(start, abs=0.01)
    assert fit.end_m == pytest.approx(end, abs=0.01)
    assert fit.loss == pytest.approx(loss, abs=0.005)
    plain = fit_zone(grid, meas, start + 0.9, end - 0.9, p, load, 3.0, 40.0)
    assert plain.end_m > end + 0.5 and plain.loss > loss + 0.02  # late and deep


@pytest.mark.parametrize("start, end, loss", [(100.2, 103.8, 0.5), (100.2, 105.6, 0.45),
                                              (100.2, 106.8, 0.35)])  # fmt: skip
def test_fit_from_a_longer_seed_moves_the_ends_to_the_dip(start, end, loss):
    """Seeded with a 10 m span about the dip's centre (the matched detector's longest shape,
    engine.matched_dips), the extent search with the trend shrinks both ends to the zone's:
    the seed does not hold the ends, the misfit does."""
    p = TrackParams()
    load = float(np.mean(TABLE1.static_axle_loads()))
    grid = np.arange(0.0, 200.0, 0.25)
    model = QuasiStaticModel(p, 0.0, 200.0, grid, load)
    ref = model.level(np.ones(model.node_x.size))
    dip = bandpass_distance((model.level(model.factors(start, end, loss)) - ref) * 1e3,
                            0.25, 3.0, 40.0)  # fmt: skip
    meas = dip - 0.1 - 0.02 * (grid - 103.0)  # mm: a level and a slope under the dip
    centre = 0.5 * (start + end)
    fit = fit_zone(grid, meas, centre - 5.0, centre + 5.0, p, load, 3.0, 40.0, trend_order=1)
    assert fit.start_m == pytest.approx(start, abs=0.01)
    assert fit.end_m == pytest.approx(end, abs=0.01)
    assert fit.loss == pytest.approx(loss, abs=0.005)
