"""Min/max decimation for display: thin a series so every dip and peak survives.

One rule for every chart the product draws (run profiles, the chainage map's windows, the
track's aggregated profile, raw signals, the PDF-style report): split the series into buckets
of consecutive samples and keep, from each, the sample with the lowest and the one with the
highest value. A plotted line of the kept samples has the same envelope as the whole series.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray


def minmax_indices(y: ArrayLike, max_points: int) -> NDArray[np.intp]:
    """Indices of the samples kept when thinning ``y`` to at most ``max_points``.

    Parameters
    ----------
    y : array_like, shape (n,) or (k, n), or a sequence of ``k`` arrays of shape (n,)
        The series (any unit). With ``k`` rows sharing one axis (front, rear and fused level;
        acceleration and pitch rate), each row gets ``1/k`` of the budget and the kept indices
        are the union, so each row keeps its own extremes on the shared axis. A sequence of
        rows is read row by row (no stacked copy of long signals).
    max_points : int
        Most indices returned (at least ``2 k + 2``).

    Returns
    -------
    ndarray of int
        Sorted, unique indices into the axis. ``arange(n)`` when ``n <= max_points``.
        The first and the last index are always kept, so the thinned axis spans the same
        extent.

    Notes
    -----
    NaN (no data) is ignored when looking for a bucket's extremes. A bucket with no finite
    value keeps one sample, its first (a NaN), so a chart line drawn through the kept
    samples breaks across the gap instead of bridging it.
    """
    if isinstance(y, (list, tuple)) and y and all(np.ndim(r) == 1 for r in y):
        a: Sequence[NDArray[np.float64]] | NDArray[np.float64] = [
            np.asarray(r, dtype=np.float64) for r in y
        ]
        if len({r.size for r in a}) != 1:
            raise ValueError("the rows of y must have one length")
        k, n = len(a), a[0].size
    else:
        a = np.atleast_2d(np.asarray(y, dtype=np.float64))
        if a.ndim != 2:
            raise ValueError(f"y must be 1-D or 2-D, got {a.ndim} dimensions")
        k, n = a.shape
    if max_points < 2 * k + 2:
        raise ValueError(f"max_points must be >= {2 * k + 2} for {k} row(s), got {max_points}")
    if n <= max_points:
        return np.arange(n, dtype=np.intp)
    buckets = max(1, (max_points - 2) // (2 * k))
    size = -(-n // buckets)
    pad = (-n) % size
    starts = np.arange(0, n, size)
    keep = [np.array([0, n - 1])]
    for row in a:
        if not np.isnan(row).any():
            # no gaps: padded with its last value (argmin/argmax take the first of equal
            # values, the real sample) and no masked copies of a long signal
            blocks = np.concatenate([row, np.full(pad, row[-1])]).reshape(-1, size)
            keep.append(starts + blocks.argmin(axis=1))
            keep.append(starts + blocks.argmax(axis=1))
            continue
        blocks = np.concatenate([row, np.full(pad, np.nan)]).reshape(-1, size)
        missing = np.isnan(blocks)
        # an all-NaN bucket: both argmin and argmax give 0, its first sample
        keep.append(starts + np.where(missing, np.inf, blocks).argmin(axis=1))
        keep.append(starts + np.where(missing, -np.inf, blocks).argmax(axis=1))
    idx = np.unique(np.concatenate(keep))
    return idx[idx < n].astype(np.intp)
