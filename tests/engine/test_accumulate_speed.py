"""The combined detection's shortcuts give the numbers of the plain computation: each pass's
noise measured for all passes at once, a detection that wants one stretch's spots only, and
the residuals kept between detections (engine.accumulate).

Profiles are synthetic band-limited series (as in test_accumulate.py): a track signal with
dips common to every pass plus each pass's own noise, passes covering different stretches.
"""

from __future__ import annotations

import numpy as np
import pytest

import engine.pipeline
from engine.accumulate import (
    ResidualCache,
    detect_on_aggregate,
    pass_noise,
    residuals,
)
from engine.chainage import bandpass_distance
from engine.detect import robust_sigma
from engine.errors import ParameterError

STEP = 0.25
LOAD_N = 60e3


def band(rng: np.random.Generator, n: int, sd: float) -> np.ndarray:
    """A random profile in the product's 3-40 m band with standard deviation ``sd`` mm."""
    x = bandpass_distance(rng.standard_normal(n), STEP, 3.0, 40.0)
    return sd * x / np.std(x)


def passes(seed: int, centres: tuple[float, ...], n: int = 6000, k: int = 8) -> np.ndarray:
    """``k`` passes (rows, mm) over ``n`` points: 0.25 mm dips of ~5 m at ``centres`` (m)
    plus 0.02 mm of each pass's own noise; each pass misses a different stretch at its
    ends (NaN), as passes with different start chainages do."""
    rng = np.random.default_rng(seed)
    grid = np.arange(n) * STEP
    signal = np.zeros(n)
    for c in centres:
        signal -= 0.25 * np.exp(-0.5 * ((grid - c) / 2.1) ** 2)
    out = np.stack([signal + band(rng, n, 0.02) for _ in range(k)])
    for j in range(k):
        out[j, : int(rng.integers(0, 400))] = np.nan
        out[j, n - int(rng.integers(1, 400)) :] = np.nan
    return out


def test_pass_noise_is_each_pass_robust_spread_about_the_median_pass() -> None:
    """Each pass's noise equals its definition computed pass by pass: robust_sigma of its
    residual minus the median residual where two passes or more cover, times N/(N-1)."""
    lv = passes(1, (300.0, 900.0))
    res = residuals(lv, STEP, 40.0)
    n = np.isfinite(res).sum(axis=0)
    med = np.full(res.shape[1], np.nan)
    med[n > 0] = np.nanmedian(res[:, n > 0], axis=0)
    want = []
    for j in range(res.shape[0]):
        use = np.isfinite(res[j]) & (n >= 2)
        nn = float(np.mean(n[use]))
        want.append(robust_sigma(res[j, use] - med[use]) * nn / (nn - 1.0))
    assert pass_noise(lv, STEP, 40.0, res=res) == pytest.approx(np.array(want), rel=1e-12)


def test_detection_of_one_stretch_gives_the_full_detections_spots_there_and_fits_less(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Asked for the spots whose deepest point lies in a stretch, the detection returns
    exactly those of the detection of everything (extents, losses, significance, passes),
    also where the stretch's end cuts a chain of dips 15 m apart; dips far from the stretch
    are not fitted."""
    centres = (150.0, 480.0, 495.0, 510.0, 900.0, 1300.0)
    lv = passes(2, centres)
    grid = np.arange(lv.shape[1]) * STEP
    calls = []
    fit = engine.pipeline.fit_zone
    monkeypatch.setattr(
        engine.pipeline, "fit_zone", lambda *a, **k: calls.append(a[2]) or fit(*a, **k)
    )
    full = detect_on_aggregate(grid, lv, load_n=LOAD_N)
    assert len(full.spots) >= 4 and all(np.isfinite(s.stiffness_loss_pct) for s in full.spots)
    n_full = len(calls)
    for lo, hi in ((0.0, 497.0), (497.0, 1000.0), (100.0, 200.0), (600.0, 1200.0)):
        calls.clear()
        part = detect_on_aggregate(grid, lv, load_n=LOAD_N, peaks_in_m=(lo, hi))
        assert part.spots == [s for s in full.spots if lo <= s.peak_m < hi], (lo, hi)
        assert len(calls) < n_full
    with pytest.raises(ParameterError) as e:
        detect_on_aggregate(grid, lv, peaks_in_m=(10.0, 10.0))
    assert e.value.field == "peaks_in_m"


def test_residual_cache_gives_the_same_residuals_and_refilters_a_changed_row() -> None:
    """Residuals through the cache are the plain residuals, on first sight and when kept; a
    row that changed (a pass moved) is filtered again, not served stale; the cache holds
    at most its memory (the least recently used rows go); a size below one byte is refused."""
    lv = passes(3, (300.0,), n=2000, k=4)
    plain = residuals(lv, STEP, 40.0)
    cache = ResidualCache(max_bytes=5 * lv[0].nbytes)
    for _ in range(2):
        got = residuals(lv, STEP, 40.0, cache=cache)
        np.testing.assert_array_equal(got, plain)
    got[0] += 1.0  # a caller's changes stay its own
    np.testing.assert_array_equal(residuals(lv, STEP, 40.0, cache=cache), plain)
    moved = lv.copy()
    moved[1] = np.roll(moved[1], 8)
    np.testing.assert_array_equal(
        residuals(moved, STEP, 40.0, cache=cache), residuals(moved, STEP, 40.0)
    )
    assert len(cache) == 5
    assert cache.nbytes == 5 * lv[0].nbytes
    with pytest.raises(ParameterError) as e:
        ResidualCache(max_bytes=0)
    assert e.value.field == "max_bytes"


def test_residual_cache_drops_the_least_recently_used_row_past_its_memory(monkeypatch) -> None:
    """With room for two rows, a row used again stays and the one unused longest is filtered
    again when asked for; a row larger than the whole cache is filtered and not kept."""
    import engine.accumulate as acc

    filtered = []
    real = acc.robust_baseline
    monkeypatch.setattr(
        acc,
        "robust_baseline",
        lambda row, *args: filtered.append(row.tobytes()) or real(row, *args),
    )
    a, b, c = passes(3, (300.0,), n=2000, k=3)
    cache = ResidualCache(max_bytes=2 * a.nbytes)
    for row in (a, b, a, c, a, b):
        cache.residual(row, STEP, 40.0)
    assert filtered == [a.tobytes(), b.tobytes(), c.tobytes(), b.tobytes()]
    assert cache.nbytes == 2 * a.nbytes
    small = ResidualCache(max_bytes=a.nbytes - 1)
    np.testing.assert_array_equal(small.residual(a, STEP, 40.0), residuals(a, STEP, 40.0)[0])
    assert small.nbytes == 0
