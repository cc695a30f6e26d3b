"""The first sample that breaks a bound, found without temporary arrays when none does.

A log's checks ask, column by column, "which is the first sample beyond this limit?" over
millions of samples. Asked as ``np.flatnonzero(np.abs(a) > limit)`` each question builds two
or three arrays the size of the column (about 0.01 s each for an hour at 1 kHz, a dozen of
them per upload) to find, almost always, nothing. Here the minimum and the maximum answer it
first (no allocation): a column whose extremes are within the bound has every sample within
it, because ``|x - c|`` rounds monotonically on each side of ``c``. Only a column that fails
(or holds NaN, where min and max say nothing) is searched element by element, with the same
comparison as before, so the index found is the same.

Units: whatever the values carry; bounds in the same unit.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def first_true(mask: NDArray[np.bool_]) -> int | None:
    """Index of the first True in ``mask``, or None."""
    idx = np.flatnonzero(mask)
    return int(idx[0]) if idx.size else None


def first_beyond(values: NDArray[np.floating], limit: float, center: float = 0.0) -> int | None:
    """First ``i`` with ``|values[i] - center| > limit`` (NaN is never beyond), or None."""
    if values.size == 0:
        return None
    lo, hi = values.min(), values.max()
    if abs(hi - center) <= limit and abs(lo - center) <= limit:
        return None
    shifted = values if center == 0.0 else values - center
    return first_true(np.abs(shifted) > limit)


def first_outside(values: NDArray[np.floating], lo: float, hi: float) -> int | None:
    """First ``i`` with ``values[i] < lo`` or ``values[i] > hi`` (NaN is never), or None."""
    if values.size == 0 or (values.min() >= lo and values.max() <= hi):
        return None
    return first_true((values < lo) | (values > hi))


def first_at_most(values: NDArray[np.floating], floor: float) -> int | None:
    """First ``i`` with ``values[i] <= floor`` (NaN is never), or None."""
    if values.size == 0 or values.min() > floor:
        return None
    return first_true(values <= floor)


def first_nonfinite(values: NDArray[np.floating]) -> int | None:
    """First ``i`` where ``values[i]`` is NaN or infinite, or None.

    A finite sum means every term is finite (NaN and infinities propagate); a sum that
    overflows sends the check to the element-wise search, which then finds nothing.
    """
    if values.size == 0:
        return None
    with np.errstate(over="ignore", invalid="ignore"):
        if np.isfinite(values.sum()):
            return None
    return first_true(~np.isfinite(values))
