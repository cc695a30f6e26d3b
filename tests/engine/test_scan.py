"""engine.scan: the first sample beyond a bound, the same index as the element-wise search
whether the min/max shortcut answers or not."""

from __future__ import annotations

import numpy as np
import pytest

from engine.scan import first_at_most, first_beyond, first_nonfinite, first_outside, first_true


def _cases() -> list[np.ndarray]:
    rng = np.random.default_rng(5)
    base = rng.normal(0.0, 1.0, 5000)
    out = [base, np.empty(0), np.array([3.0])]
    for i, v in ((0, 9.0), (17, -9.0), (4999, 7.5), (2500, np.nan), (10, np.inf), (11, -np.inf)):
        a = base.copy()
        a[i] = v
        out.append(a)
    a = base.copy()
    a[[3, 40]] = [np.nan, 8.0]  # NaN beside a real excess: min/max alone would miss it
    out.append(a)
    out.append(np.full(10, 1e308))  # a sum that overflows, every value finite
    return out


@pytest.mark.parametrize("k", range(11))
def test_each_search_finds_what_the_elementwise_mask_finds(k) -> None:
    a = _cases()[k]
    with np.errstate(invalid="ignore"):
        assert first_beyond(a, 3.0) == first_true(np.abs(a) > 3.0)
        assert first_beyond(a, 2.0, center=1.0) == first_true(np.abs(a - 1.0) > 2.0)
        assert first_outside(a, -2.5, 3.5) == first_true((a < -2.5) | (a > 3.5))
        assert first_at_most(a, -2.0) == first_true(a <= -2.0)
        assert first_nonfinite(a) == first_true(~np.isfinite(a))


def test_the_bound_itself_is_inside_and_the_next_value_is_not() -> None:
    h = 0.001
    steps = np.full(100, h)
    steps[50] = h + 0.01 * h
    assert first_beyond(steps, 0.01 * h, center=h) == first_true(np.abs(steps - h) > 0.01 * h)
    steps[50] = np.nextafter(h + 0.01 * h, 1.0)
    assert first_beyond(steps, 0.01 * h, center=h) == first_true(np.abs(steps - h) > 0.01 * h)
    assert first_outside(np.array([1.0, 2.0]), 1.0, 2.0) is None
    assert first_at_most(np.array([1.0, 0.0]), 0.0) == 1
