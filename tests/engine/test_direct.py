"""The paper's direct-integration inverse: exact round trip, and its known weakness."""

import numpy as np
import pytest

from engine.direct import direct_inverse, direct_inverse_loop
from engine.errors import InversionError, ParameterError
from engine.simulate import simulate
from engine.track import SoftZone, Track
from engine.vehicle import VehicleParams
from support.samples import sample


def test_reproduces_sample_clean_exact_levels():
    """On the independent 1 kHz Newmark sample the inverse returns r - r[0] to <= 1e-6 m."""
    raw, truth = sample("sample_clean_exact")
    res = direct_inverse(raw[:, 1], raw[:, 2], 1e-3)
    assert np.max(np.abs(res.y_front - (truth["r1"] - truth["r1"][0]))) <= 1e-6
    assert np.max(np.abs(res.y_rear - (truth["r2"] - truth["r2"][0]))) <= 1e-6


@pytest.mark.parametrize("gamma,beta", [(0.5, 0.25), (0.6, 0.3025)])
def test_round_trip_forward_then_inverse_is_exact(gamma, beta):
    """Forward (same step, same gamma/beta) then inverse gives y - y(0) to rounding error."""
    veh = VehicleParams(ms=20000.0, d1=5.0, d2=4.0)
    track = Track(200.0, zones=[SoftZone(90, 95, 0.5), SoftZone(120, 121.5, 0.3)])
    sim = simulate(track, vehicle=veh, speed=lambda t: 18 + 3 * t, duration=3.0,
                   start_chainage_m=60.0, gamma=gamma, beta=beta)  # fmt: skip
    res = direct_inverse(sim.accel, sim.pitch_rate, sim.dt, veh, gamma=gamma, beta=beta)
    scale = np.ptp(sim.y_front)
    assert np.max(np.abs(res.y_front - (sim.y_front - sim.y_front[0]))) < 1e-7 * scale
    assert np.max(np.abs(res.y_rear - (sim.y_rear - sim.y_rear[0]))) < 1e-7 * scale


def test_vectorised_equals_per_sample_loop():
    """The filter form and the straightforward loop are the same algorithm."""
    rng = np.random.default_rng(3)
    a = rng.normal(0, 0.01, 3000)
    q = rng.normal(0, 1e-4, 3000)
    v = direct_inverse(a, q, 1e-3)
    loop = direct_inverse_loop(a, q, 1e-3)
    scale = np.max(np.abs(loop.y_front))
    assert np.max(np.abs(v.y_front - loop.y_front)) < 1e-8 * scale
    assert np.max(np.abs(v.y_rear - loop.y_rear)) < 1e-8 * scale


def test_unknown_implementation_is_refused_by_name():
    """An implementation outside the registry raises ParameterError naming the field."""
    a = np.zeros(10)
    with pytest.raises(ParameterError, match="implementation") as err:
        direct_inverse(a, a, 1e-3, implementation="vectorised")
    assert err.value.field == "implementation"


def test_known_weakness_noise_and_rounding_break_the_direct_method():
    """Noise, bias or 8-digit rounding make the raw result wrong by far more than the signal."""
    raw, truth = sample("sample_noisy")
    res = direct_inverse(raw[:, 1], raw[:, 2], 1e-3)
    signal = np.ptp(truth["r1"])  # ~0.4 mm
    err = np.max(np.abs(res.y_front - (truth["r1"] - truth["r1"][0])))
    assert err > 10 * signal
    # even rounding alone to 8 significant digits of clean, finer-step data spoils it
    track = Track(200.0, zones=[SoftZone(100, 104, 0.5)])
    sim = simulate(track, speed=22.0, duration=5.0, start_chainage_m=40.0, dt=2.5e-4)
    a = np.array([float(f"{x:.7e}") for x in sim.accel[::4]])
    q = np.array([float(f"{x:.7e}") for x in sim.pitch_rate[::4]])
    res2 = direct_inverse(a, q, 1e-3)
    sig2 = np.ptp(sim.y_front)
    assert np.max(np.abs(res2.y_front - (sim.y_front[::4] - sim.y_front[0]))) > sig2


def test_bad_input_shapes():
    """Mismatched or too short inputs are an InversionError (a ValueError)."""
    with pytest.raises(InversionError):
        direct_inverse(np.zeros(10), np.zeros(9), 1e-3)
    with pytest.raises(ValueError):
        direct_inverse(np.zeros(2), np.zeros(2), 1e-3)
