"""Many passes combined (engine.accumulate): the measured noise of the combination, alignment
against the others' mean with no pass dropped, and detection on the combination.

Profiles here are synthetic band-limited series (no vehicle simulation): a track signal common
to every pass plus each pass's own noise, so the truth of the combination's error is known.
"""

from __future__ import annotations

import numpy as np
import pytest

from engine.accumulate import accumulate, combined_noise, detect_on_aggregate, residuals
from engine.align import align_profiles, correlation_z
from engine.chainage import bandpass_distance
from engine.errors import ParameterError

STEP = 0.25


def band(rng: np.random.Generator, n: int, sd: float) -> np.ndarray:
    """A random profile in the product's 3-40 m band with standard deviation ``sd`` mm."""
    x = bandpass_distance(rng.standard_normal(n), STEP, 3.0, 40.0)
    return sd * x / np.std(x)


def dips(grid: np.ndarray, where: tuple[float, ...], depth: float, width: float) -> np.ndarray:
    """Smooth dips (mm, negative) of ``depth`` mm and half-depth width about ``width`` m."""
    out = np.zeros_like(grid)
    for c in where:
        out -= depth * np.exp(-0.5 * ((grid - c) / (width / 2.355)) ** 2)
    return out


def test_measured_noise_of_the_mean_matches_its_true_error_independent_and_shared() -> None:
    """Independent pass noise: the measured noise of the mean is the true error's spread and
    about sigma/sqrt(N). Passes recorded in fours that share half their error: the measured
    noise follows the true error, which falls more slowly than sigma/sqrt(N)."""
    rng = np.random.default_rng(1)
    n, npass, sd = 6000, 16, 0.05
    signal = band(rng, n, 0.03)
    for shared in (False, True):
        errs = [band(rng, n, sd) for _ in range(npass)]
        if shared:
            common = [band(rng, n, sd) for _ in range(npass // 4)]
            errs = [np.sqrt(0.5) * e + np.sqrt(0.5) * common[j // 4] for j, e in enumerate(errs)]
        levels = np.stack([signal + e for e in errs])
        res = residuals(levels, STEP, 40.0)
        true_err = np.std(np.mean(np.stack(errs), axis=0)[400:-400])
        got = combined_noise(res, np.full(npass, sd))
        measured = float(np.median(got.noise_mm))
        assert measured == pytest.approx(true_err, rel=0.25), (shared, measured, true_err)
        naive = sd / np.sqrt(npass)
        if shared:
            assert measured > 1.3 * naive and got.scale > 1.3
        else:
            assert measured == pytest.approx(naive, rel=0.2)


def test_correlation_z_separates_a_weak_true_match_from_chance() -> None:
    """A noisy copy of a profile correlates weakly (~0.3) but far above chance; an unrelated
    profile of the same roughness stays within chance."""
    rng = np.random.default_rng(2)
    sig = band(rng, 4000, 1.0)
    noisy = sig + band(rng, 4000, 2.5)
    other = band(rng, 4000, 1.0)
    assert np.corrcoef(sig, noisy)[0, 1] < 0.45
    assert correlation_z(sig, noisy) > 8.0
    assert abs(correlation_z(sig, other)) < 4.0
    grid = np.arange(4000) * STEP
    al = align_profiles(grid, sig, grid + 0.75, noisy)
    assert not al.ok and al.z_score > 8.0 and al.offset_m == pytest.approx(-0.75, abs=0.15)


def test_accumulate_keeps_every_pass_and_aligns_noisy_ones_against_the_others() -> None:
    """Twelve passes with start errors up to +-1 m and noise three times the track's signal:
    none is dropped, most are aligned against the others' mean and those are right within
    0.3 m (the rest stay within their start error); a lone pass is placed, not aligned."""
    rng = np.random.default_rng(3)
    n = 3200
    grid = np.arange(n) * STEP
    signal = band(rng, n, 0.03) + dips(grid, (200.0, 500.0), 0.3, 5.0)
    errors = rng.uniform(-1.0, 1.0, 12)
    chain = [grid + e for e in errors]  # logged chainage of each pass
    lv = [signal + band(rng, n, 0.09) for _ in errors]
    g, levels, placed = accumulate(chain, lv)
    assert len(placed) == 12 and levels.shape[0] == 12
    got = np.array([p.offset_m for p in placed])
    want = -(errors - errors.mean())
    aligned = np.array([p.aligned for p in placed])
    assert aligned.sum() >= 9
    # aligned passes are right within 0.3 m; a placed one is off by its own start error
    assert np.max(np.abs(got - want)[aligned]) <= 0.3, np.round(got - want, 2)
    assert np.max(np.abs(got - want)[~aligned], initial=0.0) <= 1.1
    _, _, alone = accumulate(chain[:1], lv[:1])
    assert not alone[0].aligned and alone[0].offset_m == 0.0


def test_a_pass_given_in_decreasing_chainage_joins_as_the_same_pass_increasing() -> None:
    """A run driven towards decreasing chainage, handed over in its own sample order, is
    placed exactly as the same samples in increasing order (it used to come out all NaN:
    interpolation needs increasing abscissae)."""
    rng = np.random.default_rng(5)
    n = 2000
    grid = np.arange(n) * STEP
    signal = band(rng, n, 0.03) + dips(grid, (200.0,), 0.3, 5.0)
    other = signal + band(rng, n, 0.01)
    _, up, _ = accumulate([grid, grid + 0.4], [signal, other])
    _, down, placed = accumulate([grid, (grid + 0.4)[::-1]], [signal, other[::-1]])
    assert np.isfinite(down[1]).sum() == np.isfinite(up[1]).sum() > n // 2
    np.testing.assert_array_equal(down, up)
    assert placed[1].aligned


def test_detection_on_the_combination_finds_what_no_single_pass_sees() -> None:
    """Dips at 2.5 sigma of one pass's noise: one pass finds none; 16 passes combined find
    both at the right place and nothing else; pure noise combined gives no spot."""
    rng = np.random.default_rng(4)
    n = 3200
    grid = np.arange(n) * STEP
    signal = dips(grid, (250.0, 520.0), 0.2, 6.0)
    passes = np.stack([signal + band(rng, n, 0.08) for _ in range(16)])
    one = detect_on_aggregate(grid, passes[:1])
    assert one.spots == []
    many = detect_on_aggregate(grid, passes)
    assert [round(s.peak_m) for s in many.spots] == pytest.approx([250, 520], abs=2)
    assert all(len(s.supporting) >= 8 and len(s.covering) == 16 for s in many.spots)
    assert float(np.median(many.noise.noise_mm)) < 0.4 * float(one.noise.noise_mm[n // 2])
    quiet = np.stack([band(rng, n, 0.08) for _ in range(16)])
    assert detect_on_aggregate(grid, quiet).spots == []


def test_detect_on_aggregate_rejects_bad_input_naming_the_field() -> None:
    """A level matrix that does not match the grid, or a non-positive load, is refused."""
    grid = np.arange(100) * STEP
    with pytest.raises(ParameterError) as e:
        detect_on_aggregate(grid, np.zeros((2, 99)))
    assert e.value.field == "levels_mm"
    with pytest.raises(ParameterError) as e:
        detect_on_aggregate(grid, np.zeros((2, 100)), load_n=-1.0)
    assert e.value.field == "load_n"


def test_identical_passes_are_detected_on_with_finite_weights() -> None:
    """The same level twice (one log stored for two runs): no noise to measure, yet the
    combination is searched without error, its dip found, infinitely significant."""
    grid = np.arange(3200) * STEP
    level = dips(grid, (400.0,), 0.3, 6.0)
    with np.errstate(divide="raise", invalid="raise", over="raise"):
        det = detect_on_aggregate(grid, np.stack([level, level]))
    assert np.all(np.isfinite(det.pass_noise_mm)) and np.all(det.pass_noise_mm > 0)
    assert [round(s.peak_m) for s in det.spots] == [400]
    assert det.spots[0].significance > 1e3


def test_soft_spot_records_are_dips_with_their_own_figures_after() -> None:
    """A single pass's and the combination's soft spots share the detector's Dip (its fields
    first, in order), so positional construction and the keys a SoftSpot's dict carries to
    the API and the CSV stay as they are."""
    from dataclasses import fields

    from engine.accumulate import AggregateSpot
    from engine.detect import Dip
    from engine.results import SoftSpot

    head = ["start_m", "end_m", "peak_m", "depth_mm"]
    assert [f.name for f in fields(Dip)] == head
    for cls in (SoftSpot, AggregateSpot):
        assert issubclass(cls, Dip)
        assert [f.name for f in fields(cls)][:4] == head
    spot = SoftSpot(10.0, 14.0, 12.0, 0.3, 40.0)
    assert spot.to_dict() == {
        "start_m": 10.0, "end_m": 14.0, "peak_m": 12.0, "depth_mm": 0.3, "stiffness_loss_pct": 40.0
    }  # fmt: skip
    assert list(spot.to_dict()) == [*head, "stiffness_loss_pct"]
    agg = AggregateSpot(10.0, 14.0, 12.0, 0.3, 40.0, 6.0, (0, 1), (0, 1, 2))
    assert (agg.depth_mm, agg.significance, agg.covering) == (0.3, 6.0, (0, 1, 2))
