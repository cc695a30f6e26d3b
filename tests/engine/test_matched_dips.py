"""The detector matched to coloured noise (engine/matched_dips.py)."""

from __future__ import annotations

import numpy as np
import pytest

from engine.chainage import bandpass_distance
from engine.detect import robust_sigma
from engine.errors import ParameterError
from engine.matched_dips import local_spread, matched_dips, matched_scores, noise_spectrum
from engine.separation import SeparationConfig

STEP_M = 0.25
LENGTHS_M = (3.0, 4.5, 6.0, 8.0, 10.0)


def _red_noise(rng: np.random.Generator, n: int) -> np.ndarray:
    """Band-passed (3-40 m) noise whose density falls as wavelength^-1.5 — long waves
    dominate, as in the separated compliance — scaled to unit robust spread."""
    f = np.fft.rfftfreq(n, STEP_M)
    spec = np.fft.rfft(rng.standard_normal(n)) / np.maximum(f, 1 / 40.0) ** 1.5
    y = bandpass_distance(np.fft.irfft(spec, n), STEP_M, 3.0, 40.0)
    return y / robust_sigma(y)


def _shape(length_m: float) -> np.ndarray:
    x = np.arange(-30.0, 30.0 + STEP_M / 2, STEP_M)
    basin = np.exp(-0.5 * (x / 0.8) ** 2)
    d = bandpass_distance(
        np.convolve((np.abs(x) <= length_m / 2).astype(float), basin, mode="same"),
        STEP_M, 3.0, 40.0,
    )  # fmt: skip
    return d / d.max()


SHAPES = [(length, _shape(length)) for length in LENGTHS_M]


def test_finds_zone_dips_the_white_threshold_misses_and_no_false_dip():
    """A 6 m zone's dip 3 noise deviations deep in red noise: the matched filter finds it at
    its place on most tracks, a 4.5-deviation threshold on the profile on few; pure noise
    gives no dip at all."""
    x = np.arange(0.0, 600.0, STEP_M)
    t = SHAPES[2][1]
    h = t.size // 2
    k = int(round(300.0 / STEP_M))
    matched_hits = white_hits = 0
    for seed in range(10):
        noise = _red_noise(np.random.default_rng(seed), x.size)
        assert matched_dips(x, noise, SHAPES, 4.5, 40.0) == []
        y = noise.copy()
        y[k - h : k + h + 1] -= 3.0 * t
        found = matched_dips(x, y, SHAPES, 4.5, 40.0)
        assert all(abs(d.peak_m - 300.0) <= 1.5 for d in found)
        matched_hits += len(found) == 1
        white_hits += bool(np.min(y[k - 40 : k + 40]) < -4.5 * robust_sigma(y))
    assert matched_hits >= 8
    assert white_hits <= 4


def test_needs_two_segments_of_profile_to_measure_the_noise():
    x = np.arange(0.0, 60.0, STEP_M)
    y = _red_noise(np.random.default_rng(1), x.size)
    y[100:110] -= 20.0
    assert noise_spectrum(y, STEP_M, 40.0) is None
    assert matched_dips(x, y, SHAPES, 4.5, 40.0) is None


def test_gaps_are_left_out_of_the_noise_and_the_filter():
    """NaN stretches split the profile: the dip in one run is found, nothing in the gap."""
    x = np.arange(0.0, 600.0, STEP_M)
    y = _red_noise(np.random.default_rng(3), x.size)
    t = SHAPES[3][1]
    h = t.size // 2
    k = int(round(450.0 / STEP_M))
    y[k - h : k + h + 1] -= 5.0 * t
    y[(x > 250.0) & (x < 330.0)] = np.nan
    found = matched_dips(x, y, SHAPES, 4.5, 40.0)
    assert [round(d.peak_m) for d in found] == [450]
    assert not any(250.0 < d.peak_m < 330.0 for d in found)


def test_separation_config_checks_matched_lengths():
    assert SeparationConfig(matched_lengths_m=()).matched_lengths_m == ()
    for bad in ((0.0,), (3.0, 40.0), (float("nan"),)):
        with pytest.raises(ParameterError, match="matched_lengths_m"):
            SeparationConfig(matched_lengths_m=bad)


def test_scores_are_the_statistic_the_dips_are_found_on():
    """``matched_scores`` peaks where ``matched_dips`` puts its strongest dip, over the
    threshold there and under it on noise alone; NaN in the gaps."""
    x = np.arange(0.0, 600.0, STEP_M)
    y = _red_noise(np.random.default_rng(3), x.size)
    t = SHAPES[3][1]
    h = t.size // 2
    k = int(round(450.0 / STEP_M))
    y[k - h : k + h + 1] -= 5.0 * t
    y[(x > 250.0) & (x < 330.0)] = np.nan
    scores = matched_scores(x, y, SHAPES, 40.0)
    found = matched_dips(x, y, SHAPES, 4.5, 40.0)
    assert scores is not None and found
    assert x[int(np.nanargmax(scores))] == found[0].peak_m
    assert np.nanmax(scores) > 4.5 > np.nanmax(scores[np.abs(x - 450.0) > 40.0])
    assert np.all(np.isnan(scores[(x > 250.0) & (x < 330.0)]))
    assert matched_scores(x[:240], y[:240], SHAPES, 40.0) is None


def test_separation_config_checks_the_near_end_threshold():
    assert SeparationConfig(near_end_matched_z=-np.inf).near_end_matched_z == -np.inf
    with pytest.raises(ParameterError, match="near_end_matched_z"):
        SeparationConfig(near_end_matched_z=float("nan"))


def test_running_spread_keeps_a_rougher_stretch_from_reading_as_zones():
    """Noise twice as strong over 300 m of 600 m (the rail rougher there): against the
    whole profile's spread the filter reads several times more dips in that stretch than
    against its running spread, and a zone in the quieter part is found either way."""
    x = np.arange(0.0, 600.0, STEP_M)
    rough = (x >= 150.0) & (x < 450.0)
    t = SHAPES[2][1]
    h = t.size // 2
    k = int(round(480.0 / STEP_M))
    one_spread = running = 0
    for seed in range(10):
        y = _red_noise(np.random.default_rng(seed), x.size) * np.where(rough, 2.0, 1.0)
        y[k - h : k + h + 1] -= 6.0 * t
        for window, count in ((None, 0), (160.0, 1)):
            found = matched_dips(x, y, SHAPES, 4.5, 40.0, window)
            assert any(abs(d.peak_m - 480.0) <= 1.5 for d in found)
            n_rough = sum(bool(rough[int(round(d.peak_m / STEP_M))]) for d in found)
            if count:
                running += n_rough
            else:
                one_spread += n_rough
    assert one_spread >= 8
    assert running <= one_spread // 4


def test_running_spread_follows_the_noise_and_not_a_zone():
    """The running spread of noise of two levels is each level's away from the change;
    a zone-sized dip ten deviations deep lifts it by less than a fifth."""
    rng = np.random.default_rng(5)
    x = np.arange(0.0, 600.0, STEP_M)
    y = rng.standard_normal(x.size) * np.where(x < 300.0, 1.0, 3.0)
    s = local_spread(y, STEP_M, 160.0)
    assert np.median(s[x < 200.0]) == pytest.approx(1.0, rel=0.1)
    assert np.median(s[x > 400.0]) == pytest.approx(3.0, rel=0.1)
    z = y.copy()
    z[(x > 100.0) & (x < 108.0)] -= 10.0
    assert np.max(local_spread(z, STEP_M, 160.0) / s) < 1.2
    y[(x > 500.0) & (x < 560.0)] = np.nan
    assert np.isnan(local_spread(y, STEP_M, 160.0)[(x > 500.0) & (x < 560.0)]).all()


def test_separation_config_checks_the_spread_window():
    SeparationConfig(matched_spread_m=None)
    for bad in (0.0, 10.0, float("inf"), float("nan")):
        with pytest.raises(ParameterError, match="matched_spread_m"):
            SeparationConfig(matched_spread_m=bad)
    for bad in (0.0, 1.5, float("nan")):
        with pytest.raises(ParameterError, match="matched_local_share"):
            SeparationConfig(matched_local_share=bad)


def test_noise_is_measured_without_the_dips_found():
    """Three 6 m zones on 250 m of red noise, one deep (12 deviations) and two at 3.5: their
    dips fill about half of the 40 m segments the noise spectrum is measured on, and were
    the spectrum measured once, on the profile with them, it would hold their own band and
    weigh it down (then all three are found on about half the tracks). Measured again on
    the profile with the dips found taken out, until a round finds none, all three are found
    at their places on at least 9 of 10 tracks, with at most one dip elsewhere over the ten."""
    x = np.arange(0.0, 250.0, STEP_M)
    t = SHAPES[2][1]
    h = t.size // 2
    centres = (60.0, 125.0, 190.0)
    all_found = elsewhere = 0
    for seed in range(100, 110):
        y = _red_noise(np.random.default_rng(seed), x.size)
        for c, depth in zip(centres, (12.0, 3.5, 3.5), strict=True):
            k = int(round(c / STEP_M))
            y[k - h : k + h + 1] -= depth * t
        found = matched_dips(x, y, SHAPES, 4.5, 40.0)
        all_found += all(any(abs(d.peak_m - c) <= 1.5 for d in found) for c in centres)
        elsewhere += sum(all(abs(d.peak_m - c) > 5.0 for c in centres) for d in found)
    assert all_found >= 9
    assert elsewhere <= 1
