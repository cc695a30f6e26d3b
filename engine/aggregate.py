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
        sub = lv[:, has]
        m = np.nanmedian(sub, axis=0)
        med[has] = m
        spread[has] = 1.4826 * np.nanmedian(np.abs(sub - m), axis=0)
    return AggregateProfile(chainage_m, med, spread, n.astype(np.int64))
