"""Aggregating many aligned runs: per-chainage robust level, spread and count."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class AggregateProfile:
    """Combined profile of several runs on one chainage grid.

    Attributes
    ----------
    chainage_m : ndarray
        Grid, m.
    level_mm : ndarray
        Median level over the runs that cover each point, mm (NaN where none does).
    spread_mm : ndarray
        Robust spread (1.4826 x median absolute deviation), mm; 0 with one run.
    n_runs : ndarray of int
        Runs covering each point.
    """

    chainage_m: NDArray[np.float64]
    level_mm: NDArray[np.float64]
    spread_mm: NDArray[np.float64]
    n_runs: NDArray[np.int64]


def aggregate_levels(
    chainage_m: NDArray[np.float64], levels_mm: NDArray[np.float64]
) -> AggregateProfile:
    """Median, robust spread and count over runs.

    Parameters
    ----------
    chainage_m : ndarray, shape (g,)
        Common grid, m.
    levels_mm : ndarray, shape (r, g)
        One row per run, mm, NaN where the run has no value.
    """
    lv = np.atleast_2d(np.asarray(levels_mm, dtype=float))
    n = np.isfinite(lv).sum(axis=0)
    med = np.full(lv.shape[1], np.nan)
    spread = np.full(lv.shape[1], np.nan)
    has = n > 0
    if has.any():
        med[has], spread[has] = column_median_spread(lv[:, has], n[has])
    return AggregateProfile(chainage_m, med, spread, n.astype(np.int64))


def column_median_spread(
    values: NDArray[np.float64], n_finite: NDArray[np.integer]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per column of ``values``, each holding ``n_finite`` > 0 finite values: their median
    and robust spread (1.4826 x median absolute deviation), in the units of ``values``."""
    m = column_nanmedian(values, n_finite)
    return m, 1.4826 * column_nanmedian(np.abs(values - m), n_finite)


def column_nanmedian(
    values: NDArray[np.float64], n_finite: NDArray[np.integer]
) -> NDArray[np.float64]:
    """``np.nanmedian(values, axis=0)`` (the same numbers) for columns that each hold
    ``n_finite`` > 0 finite values.

    One sort along the runs (NaN last) and the middle one or two picked per column: numpy's
    nanmedian goes through masked arrays when there are few rows, ten times slower on the
    hundreds of thousands of points of a long run.
    """
    if values.shape[0] == 1:
        return values[0].copy()
    srt = np.sort(values, axis=0)
    lo = np.take_along_axis(srt, ((n_finite - 1) // 2)[None, :], axis=0)[0]
    hi = np.take_along_axis(srt, (n_finite // 2)[None, :], axis=0)[0]
    # numpy's median of an even count is the mean of the middle two: (lo + hi) / 2
    return np.where(n_finite % 2 == 1, lo, (lo + hi) / 2)
