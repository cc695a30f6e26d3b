"""A run's profile on the track grid: the regular-grid shortcut gives what the general
interpolation gives."""

from __future__ import annotations

import numpy as np
import pytest

from app.services.track import alignment
from app.services.track.alignment import GRID_STEP_M, on_track_grid, sample_at


def _general(c: np.ndarray, v: np.ndarray, offset: float) -> tuple[int, np.ndarray]:
    """on_track_grid without the shortcut: sample_at at every grid point."""
    finite = np.flatnonzero(np.isfinite(v))
    lo, hi = sorted((float(c[finite[0]]), float(c[finite[-1]])))
    i_lo, i_hi = alignment.grid_index_range(lo + offset, hi + offset)
    x = np.arange(i_lo, i_hi + 1, dtype=np.float64) * GRID_STEP_M
    return i_lo, sample_at(c + offset, v, x)


@pytest.mark.parametrize("seed", range(6))
def test_a_profile_on_the_engine_grid_is_shifted_like_the_general_interpolation(seed):
    """Runs on the 0.25 m grid (as the engine gives them), with NaN edges and gaps, shifted by
    offsets that are whole, half, tiny and arbitrary fractions of a step: the same points and
    the same levels (to rounding) as interpolating point by point."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(50, 5000))
    c = (int(rng.integers(-4000, 400000)) + np.arange(n)) * GRID_STEP_M
    v = rng.standard_normal(n)
    v[: int(rng.integers(0, 5))] = np.nan
    v[n - int(rng.integers(1, 5)) :] = np.nan
    gap = int(rng.integers(10, n - 20))
    v[gap : gap + int(rng.integers(1, 8))] = np.nan
    offsets = [0.0, 0.25, -0.5, 0.125, 1e-12, -1e-12, 0.25 - 1e-12, *rng.uniform(-30, 30, 6)]
    for off in offsets:
        i_lo, got = on_track_grid(c, v, off)
        j_lo, want = _general(c, v, off)
        assert i_lo == j_lo and got.shape == want.shape, off
        assert np.array_equal(np.isnan(got), np.isnan(want)), off
        ok = ~np.isnan(want)
        # (the general path rounds each fraction from chainages of ~1e5 m: ~1e-11 apart)
        assert np.allclose(got[ok], want[ok], rtol=0, atol=1e-9), off


def test_irregular_or_decreasing_chainages_take_the_general_interpolation(monkeypatch):
    """A profile not on the track's step (a survey's 0.5 m, jitter, decreasing) is
    interpolated point by point."""
    calls = []
    real = alignment.sample_at
    monkeypatch.setattr(alignment, "sample_at", lambda *a: calls.append(1) or real(*a))
    v = np.linspace(0.0, 1.0, 400)
    on_track_grid(np.arange(400) * 0.5, v, 0.1)
    on_track_grid(np.arange(400) * GRID_STEP_M + np.r_[0.0, 0.01, np.zeros(398)], v, 0.0)
    on_track_grid(np.arange(400)[::-1] * GRID_STEP_M, v, 0.0)
    assert len(calls) == 3
    on_track_grid(np.arange(400) * GRID_STEP_M, v, 0.1)
    assert len(calls) == 3  # the engine's grid: the shortcut
