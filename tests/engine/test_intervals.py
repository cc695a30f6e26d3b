"""The one interval merge and the one min/max decimator every zone and chart is built from."""

from __future__ import annotations

import numpy as np
import pytest

from engine.decimate import minmax_indices
from engine.intervals import merge_intervals, true_runs


def test_merge_joins_overlaps_and_chains_within_the_gap() -> None:
    """Overlapping, touching and within-gap intervals join (a chain transitively); others don't."""
    starts = [10.0, 0.0, 2.5, 30.0, 12.9]
    ends = [12.0, 2.0, 4.0, 31.0, 14.0]
    groups = merge_intervals(starts, ends, gap=1.0)
    assert [g.tolist() for g in groups] == [[1, 2], [0, 4], [3]]
    assert [g.tolist() for g in merge_intervals(starts, ends, gap=0.0)] == [[1], [2], [0], [4], [3]]
    # a long member extends the reach over later, shorter ones
    assert [g.tolist() for g in merge_intervals([0, 1, 9], [10, 2, 9.5])] == [[0, 1, 2]]
    assert merge_intervals([], []) == []
    with pytest.raises(ValueError, match="gap"):
        merge_intervals([0.0], [1.0], gap=-1.0)


def test_minmax_keeps_every_extreme_within_budget() -> None:
    """Each row keeps its extremes, the ends of the axis are kept, the budget holds."""
    rng = np.random.default_rng(4)
    y = rng.normal(0.0, 1.0, (2, 50_001))
    y[0, 12_345] = -40.0
    y[1, 40_000] = 55.0
    idx = minmax_indices(y, 1000)
    assert idx.size <= 1000 and np.all(np.diff(idx) > 0)
    assert idx[0] == 0 and idx[-1] == y.shape[1] - 1
    assert 12_345 in idx and 40_000 in idx
    assert np.array_equal(minmax_indices(y[0, :800], 1000), np.arange(800))


def test_minmax_keeps_a_nan_where_a_bucket_has_no_data() -> None:
    """A bucket without data keeps one NaN sample (a chart line breaks there), not a bridge."""
    y = np.sin(np.arange(10_000) / 50.0)
    y[3000:6000] = np.nan
    idx = minmax_indices(y, 200)
    kept = y[idx]
    gap = (idx >= 3000) & (idx < 6000)
    assert gap.any() and np.all(np.isnan(kept[gap]))
    assert np.nanmin(kept) == np.nanmin(y) and np.nanmax(kept) == np.nanmax(y)
    with pytest.raises(ValueError, match="max_points"):
        minmax_indices(y, 3)


def _reference_minmax(y: np.ndarray, max_points: int) -> np.ndarray:
    """The decimator's rule written out plainly: NaN-padded buckets, NaN-masked extremes."""
    k, n = y.shape
    buckets = max(1, (max_points - 2) // (2 * k))
    size = -(-n // buckets)
    keep = {0, n - 1}
    for row in y:
        for a in range(0, n, size):
            part = row[a : a + size]
            if np.isnan(part).all():
                keep.add(a)
                continue
            keep.add(a + int(np.nanargmin(part)))
            keep.add(a + int(np.nanargmax(part)))
    return np.array(sorted(keep))


@pytest.mark.parametrize("n", [50_001, 50_000, 999_983])
def test_minmax_rows_as_a_sequence_or_without_gaps_keep_the_same_samples(n: int) -> None:
    """Rows given as a list (not stacked) and rows without gaps (no masked copies, padded with
    their last value) keep exactly the samples of the plain rule, ties and the last bucket
    included."""
    rng = np.random.default_rng(n)
    y = np.round(rng.normal(0.0, 1.0, (3, n)), 1)  # rounded: many ties within a bucket
    y[1, -1] = 9.0  # the last sample an extreme of the last (padded) bucket
    y[2, -1] = -9.0
    gappy = y.copy()
    gappy[0, 100:4000] = np.nan
    for data in (y, gappy):
        want = _reference_minmax(data, 2000)
        assert np.array_equal(minmax_indices(data, 2000), want)
        assert np.array_equal(minmax_indices(list(data), 2000), want)
    with pytest.raises(ValueError, match="one length"):
        minmax_indices([y[0], y[1, :-1]], 2000)


def test_true_runs_gives_each_run_of_true_as_start_and_exclusive_end() -> None:
    """Runs at both ends, single points and no run at all."""
    assert true_runs(np.array([1, 1, 0, 1, 0, 0, 1], dtype=bool)) == [(0, 2), (3, 4), (6, 7)]
    assert true_runs(np.zeros(4, dtype=bool)) == []
    assert true_runs(np.ones(3, dtype=bool)) == [(0, 3)]
