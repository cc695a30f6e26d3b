"""A pass's ends are left out of its alignment: the inverse's level rings there
(``engine.align.END_RING_M``), differently for each pass, and a ring matched against the rail
pulls the cross-correlation's peak by centimetres (docs/accuracy.md, "Aligning passes without
their ends")."""

from __future__ import annotations

import numpy as np
import pytest

from engine.align import END_RING_M, align_profiles
from engine.errors import ParameterError

STEP_M = 0.25
GRID = np.arange(0.0, 600.0, STEP_M)


def _rail(seed: int) -> np.ndarray:
    """A rough rail level on GRID, mm: 1 mm SD, wavelengths of metres and more."""
    rng = np.random.default_rng(seed)
    w = np.hanning(int(6.0 / STEP_M))
    level = np.convolve(rng.normal(size=GRID.size), w / w.sum(), mode="same")
    return level / level.std()


def _pass_with_ringing_ends(seed: int, start_m: float, end_m: float) -> tuple[np.ndarray, ...]:
    """The rail between start_m and end_m as a pass sees it, mm, with a 1 mm ring decaying over
    ~20 m from each end of its log (phases at random)."""
    rng = np.random.default_rng(1000 + seed)
    x = np.arange(start_m, end_m, STEP_M)
    d0, d1 = x - x[0], x[-1] - x
    ph = rng.uniform(0.0, 2.0 * np.pi, 2)
    ring = np.exp(-d0 / 10.0) * np.sin(2 * np.pi * d0 / 15.0 + ph[0]) + np.exp(-d1 / 10.0) * np.sin(
        2 * np.pi * d1 / 15.0 + ph[1]
    )
    return x, np.interp(x, GRID, _rail(seed)) + ring


def test_a_pass_is_aligned_on_its_middle_not_its_ringing_ends() -> None:
    """A 300 m pass logged 2 m off, its ends ringing by 1 mm, against a clean aggregate: with
    its ends left out the offset is right within 1 cm on every rail; with them in, the ring
    pulls it by more than 2 cm on some (what the peer's rough runs showed: passes whose logs
    started 19-38 m apart were aligned 0.08-0.29 m apart). Judged on the levels' correlation
    peak, before the slopes refine it (tests/engine/test_align_slopes.py)."""
    errors = {0.0: [], END_RING_M: []}
    for seed in range(8):
        x, level = _pass_with_ringing_ends(seed, 100.0, 400.0)
        for edge in errors:
            # the levels' peak alone (refine_m=0): the slopes' refinement weighs the ring's
            # 15 m waves down as well, and would hide what the ends do
            a = align_profiles(GRID, _rail(seed), x + 2.0, level, edge_m=edge, refine_m=0.0)
            assert a.ok
            errors[edge].append(abs(a.offset_m + 2.0))
    assert max(errors[END_RING_M]) <= 0.01, errors[END_RING_M]
    assert max(errors[0.0]) > 0.02, errors[0.0]  # the case does test something


def test_a_short_pass_keeps_its_ends() -> None:
    """Where leaving the ends out would leave less than the shortest overlap, the whole pass
    is compared (it still aligns), and a negative edge is refused."""
    x, level = _pass_with_ringing_ends(3, 200.0, 275.0)  # 75 m: 35 m without its ends
    a = align_profiles(GRID, _rail(3), x - 1.5, level, edge_m=END_RING_M, min_overlap_m=60.0)
    assert a.ok and a.overlap_m >= 60.0
    assert a.offset_m == pytest.approx(1.5, abs=0.1)
    with pytest.raises(ParameterError, match="edge_m"):
        align_profiles(GRID, _rail(3), x, level, edge_m=-1.0)
