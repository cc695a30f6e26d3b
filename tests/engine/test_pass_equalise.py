"""Per-pass transfer equalisation before the separation (engine/pass_equalise.py).

Passes made from one band-passed rough rail (about 1 mm), each seen through its own smooth
transfer error (gain 0.85-1.15 and a phase lag varying over the band), with a soft zone whose
dip scales with the pass's load and sensor noise: the equalisation must take the transfer
differences out and leave the load-proportional dip.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.fft import irfft, rfft, rfftfreq

from engine.chainage import bandpass_distance
from engine.errors import ParameterError
from engine.pass_equalise import EqualiseConfig, equalise_passes

STEP = 0.25
N = 2400  # 600 m
BAND = (3.0, 40.0)
ZONE = slice(1200, 1224)  # 300-306 m


def _passes(seed: int, gains: list[tuple[float, float]], loads: list[float], rough_mm: float):
    """Levels (passes x points), the true level of each without its transfer error, loads."""
    rng = np.random.default_rng(seed)
    g = bandpass_distance(rng.standard_normal(N), STEP, *BAND)
    g *= rough_mm / g.std()
    dip = np.zeros(N)
    dip[ZONE] = -np.hanning(ZONE.stop - ZONE.start)
    dip = bandpass_distance(dip, STEP, *BAND)
    dip *= 0.3 / -dip.min()  # 0.3 mm under a 100 kN load
    freq = rfftfreq(N, STEP)
    lam = 1.0 / np.maximum(freq, 1e-9)
    truth, levels = [], []
    for (g_err, lag), f in zip(gains, loads, strict=True):
        true = g + dip * f / 100e3
        # smooth in log-wavelength, as a vehicle's inversion error is
        u = np.clip(np.log(lam / 3.0) / np.log(40.0 / 3.0), 0.0, 1.0)
        h = (1.0 + g_err * np.sin(np.pi * u)) * np.exp(-1j * lag * u)
        y = irfft(rfft(true) * h, N) + 0.01 * rng.standard_normal(N)
        truth.append(true)
        levels.append(y)
    return np.array(levels), np.array(truth), np.array(loads)


def test_transfer_differences_removed_and_load_dip_kept() -> None:
    """Four passes (two light, two heavy) with different transfer errors: the spread of the
    passes about their mean (away from the zone) drops at least threefold, and the
    heavy-minus-light dip at the zone stays within 10 % of the truth's."""
    gains = [(0.12, 0.1), (-0.1, -0.15), (0.05, 0.2), (-0.15, 0.0)]
    loads = [50e3, 100e3, 45e3, 95e3]
    levels, truth, f = _passes(3, gains, loads, rough_mm=1.0)
    eq = equalise_passes(levels, STEP, *BAND, loads_n=f)
    assert eq.applied.all()
    away = np.ones(N, dtype=bool)
    away[1100:1330] = False
    away[:160] = away[-160:] = False

    def spread(x: np.ndarray) -> float:
        return float(np.sqrt(np.mean((x - x.mean(axis=0))[:, away] ** 2)))

    assert spread(eq.levels_mm) < spread(levels) / 3
    heavy, light = [1, 3], [0, 2]

    def dip(x: np.ndarray) -> float:
        d = x[heavy].mean(axis=0) - x[light].mean(axis=0)
        return float(-d[ZONE].min())

    assert dip(eq.levels_mm) == pytest.approx(dip(truth), rel=0.10)


def test_two_passes_without_transfer_error_keep_their_dip() -> None:
    """A light and a heavy pass with no transfer error (only noise): the heavy-minus-light
    dip at the zone is kept within 10 %."""
    levels, truth, f = _passes(5, [(0.0, 0.0), (0.0, 0.0)], [46e3, 98e3], rough_mm=1.0)
    eq = equalise_passes(levels, STEP, *BAND, loads_n=f)
    d_eq = -(eq.levels_mm[1] - eq.levels_mm[0])[ZONE].min()
    d_true = -(truth[1] - truth[0])[ZONE].min()
    assert d_eq == pytest.approx(d_true, rel=0.10)


def test_smooth_rail_left_as_it_is() -> None:
    """On rail smoother than min_common_mm there is no common signal to fit on: nothing is
    applied and the levels come back unchanged."""
    levels, _, f = _passes(7, [(0.1, 0.0), (-0.1, 0.0)], [46e3, 98e3], rough_mm=0.05)
    eq = equalise_passes(levels, STEP, *BAND, loads_n=f)
    assert not eq.applied.any()
    np.testing.assert_array_equal(eq.levels_mm, levels)


def test_bad_config_names_the_field() -> None:
    """An out-of-range setting is a ParameterError naming it."""
    with pytest.raises(ParameterError) as e:
        EqualiseConfig(n_nodes=1)
    assert e.value.field == "n_nodes"
