"""The detector's shortcuts give the numbers of the plain computation (engine.detect)."""

from __future__ import annotations

import numpy as np
import pytest

from engine.detect import DetectionConfig, dip_thresholds, find_dips, robust_sigma


@pytest.mark.parametrize("n", [*range(1, 30), 1000, 4001, 12346])
def test_robust_sigma_is_numpys_median_absolute_deviation(n: int) -> None:
    """robust_sigma equals 1.4826 x numpy's median of the absolute deviations from numpy's
    median, exactly: odd and even counts, ties, NaN left out, a constant series."""
    rng = np.random.default_rng(n)
    for x in (rng.normal(0, 0.3, n), np.round(rng.normal(0, 2, n), 1), np.full(n, 0.7)):
        with_nan = x.copy()
        with_nan[::3] = np.nan
        for y in (x, with_nan):
            v = y[np.isfinite(y)]
            want = float(1.4826 * np.median(np.abs(v - np.median(v)))) if v.size else 0.0
            assert robust_sigma(y) == want


def test_find_dips_with_its_thresholds_given_finds_what_it_finds_alone() -> None:
    """Thresholds worked out beforehand (dip_thresholds) change nothing."""
    rng = np.random.default_rng(5)
    grid = np.arange(8000) * 0.1
    res = rng.normal(0, 0.05, grid.size)
    res -= 0.4 * np.exp(-0.5 * ((grid - 300.0) / 2.0) ** 2)
    cfg = DetectionConfig()
    alone = find_dips(grid, res, cfg)
    given = find_dips(grid, res, cfg, thresholds=dip_thresholds(0.1, res, cfg))
    assert alone == given and alone[0]
