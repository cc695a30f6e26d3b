"""Stiffness-loss fit: the fast influence-line model against a direct beam solve."""

import numpy as np
import pytest

from engine.chainage import bandpass_distance
from engine.stiffness import (
    InfluenceLine,
    QuasiStaticModel,
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
