"""Intervals along the chainage: the one rule that merges extents into zones, and the runs
of a mask (where a profile is defined, over a limit, ...).

Dips of one profile (:func:`engine.detect.find_dips`), fitted soft zones of one run
(:func:`engine.pipeline.process_run`) and soft spots of many runs (:func:`engine.register.
build_register`) all become zones by the same rule, so it is written once, here.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray


def true_runs(mask: ArrayLike) -> list[tuple[int, int]]:
    """Start and end (exclusive) indices of each run of True in the 1-D ``mask``, in order
    (e.g. the stretches a profile covers: ``true_runs(np.isfinite(level))``)."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], np.asarray(mask).astype(np.int8), [0]])))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def merge_intervals(
    starts: ArrayLike | Sequence[float], ends: ArrayLike | Sequence[float], gap: float = 0.0
) -> list[NDArray[np.intp]]:
    """Group intervals that overlap or lie at most ``gap`` apart.

    Intervals are visited by increasing start; one joins the current group when its start is
    at most ``gap`` beyond the furthest end reached by the group so far (so a chain of
    neighbours becomes one group even if its first and last members are far apart).

    Parameters
    ----------
    starts, ends : array_like of float
        Extent of each interval, m (``ends >= starts``; any consistent unit works).
    gap : float
        Largest distance between a group's reach and the next start that still merges, same
        unit as the extents; 0 merges overlapping and touching intervals only.

    Returns
    -------
    list of ndarray of int
        One array per group, the indices of its members into ``starts`` ordered by start;
        groups ordered by start. Empty input gives an empty list.
    """
    s = np.asarray(starts, dtype=np.float64).ravel()
    e = np.asarray(ends, dtype=np.float64).ravel()
    if s.shape != e.shape:
        raise ValueError(f"starts and ends differ in length: {s.size} vs {e.size}")
    if not (np.isfinite(gap) and gap >= 0):
        raise ValueError(f"gap must be a finite number >= 0, got {gap}")
    if s.size == 0:
        return []
    order = np.argsort(s, kind="stable")
    reach = np.maximum.accumulate(e[order])
    # a new group starts where the start lies beyond the reach of everything before it
    breaks = np.flatnonzero(s[order][1:] > reach[:-1] + gap) + 1
    return [g.astype(np.intp) for g in np.split(order, breaks)]
