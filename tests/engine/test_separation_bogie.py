"""The separation with bogie vehicles: each wheel's load at its position.

Passes are made without simulation from an exact static solve of the discrete-support beam
(:class:`engine.stiffness.QuasiStaticModel`'s matrices, every wheel's load superposed), so
the fit's own modal shortcut is not what makes the data.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import solveh_banded

from benchmarks.accuracy_bogie_separation import CASES, passes_of, score, within
from benchmarks.separation_false_alarms import drawn_case
from engine.chainage import bandpass_distance
from engine.errors import ParameterError
from engine.irregularity import random_profile
from engine.separation import (
    Pass,
    SeparationConfig,
    point_load_factor,
    separate,
    uniform_load_factor,
    view_shifts,
)
from engine.stiffness import InfluenceLine, QuasiStaticModel
from engine.track import TrackParams

STEP = 0.25
ZONE = (60.0, 66.0, 0.45)
COACH = (46e3, 2.5)  # wheel load N, wheelbase m
WAGON = (98e3, 2.0)


def _bogie_levels(load_n: float, wheelbase_m: float, grid: np.ndarray) -> np.ndarray:
    """Mean loaded level (mm) under a bogie's two wheels at each grid point, soft zone in."""
    trk = TrackParams()
    model = QuasiStaticModel(trk, float(grid[0]), float(grid[-1]), grid, 1.0)
    band = model.band_beam.copy()
    band[-1, 0::2] += trk.k_nominal * model.factors(*ZONE)
    W = solveh_banded(band, model.rhs, lower=False)  # nodal response to a unit load anywhere
    # G[p, q]: level at grid point p under a unit load at grid point q, m/N
    G = np.zeros((grid.size, grid.size))
    for j in range(4):
        G += model.shape[:, j][:, None] * W[model.first_dof + j, :]
    h = int(round(0.5 * wheelbase_m / STEP))
    idx = np.arange(h, grid.size - h)
    wheels = (idx - h, idx + h)
    mean = sum(G[m, k] for m in wheels for k in wheels) * load_n / 2.0
    out = np.full(grid.size, np.nan)
    out[idx] = -mean * 1e3
    return out


@pytest.fixture(scope="module")
def bogie_passes() -> list[Pass]:
    """Two coach and two wagon passes over band-limited geometry with 0.01 mm noise."""
    rng = np.random.default_rng(3)
    grid = np.arange(0.0, 130.0, STEP)
    geom = np.cumsum(rng.normal(0, 0.05, grid.size))
    passes = []
    for i, (load, wb) in enumerate((COACH, WAGON, COACH, WAGON)):
        y = geom + _bogie_levels(load, wb, grid) + rng.normal(0, 0.01, grid.size)
        ok = np.isfinite(y)
        lv = np.full(grid.size, np.nan)
        lv[ok] = bandpass_distance(y[ok], STEP, 3.0, 40.0)
        passes.append(
            Pass(grid[ok], lv[ok], 2 * load, label=f"p{i}", wheel_offsets_m=(wb / 2, -wb / 2))
        )
    return passes


def test_load_factors_of_one_wheel_and_of_a_bogie():
    """One wheel: 1 for both factors. Two wheels a apart sink sound track by
    (1 + f(a)/f(0)) / 2 per N of their force; on a zone the wheelbase smooths the dip, more
    for a longer wheelbase."""
    trk = TrackParams()
    infl = InfluenceLine(trk)
    f0 = float(infl(np.zeros(1))[0])
    fa = float(infl(np.array([2.6]))[0])
    assert uniform_load_factor(infl, (0.0,)) == pytest.approx(1.0)
    assert point_load_factor(trk, (0.0,)) == pytest.approx(1.0)
    assert uniform_load_factor(infl, (1.3, -1.3)) == pytest.approx(0.5 * (1 + fa / f0))
    coach, wagon = point_load_factor(trk, (1.3, -1.3)), point_load_factor(trk, (0.95, -0.95))
    assert 0.4 < coach < wagon < 0.5


def test_coach_and_wagon_passes_give_the_zone_and_its_loss(bogie_passes):
    """A coach's and a wagon's bogies (force of the two wheels, 2.5 and 2.0 m apart): the
    zone's ends within 0.7 m and its loss within 6 points. Read as point loads of the
    bogie's whole force (no wheel offsets) the loss comes out far too low."""
    sep = separate(bogie_passes, config=SeparationConfig(edge_factor=0.0))
    assert len(sep.soft_spots) == 1
    s = sep.soft_spots[0]
    assert abs(s.start_m - 59.7) <= 0.7 and abs(s.end_m - 66.3) <= 0.7
    assert abs(s.loss_pct - 45.0) <= 6.0
    as_points = [Pass(p.chainage_m, p.level_mm, p.force_n, label=p.label) for p in bogie_passes]
    wrong = separate(as_points, config=SeparationConfig(edge_factor=0.0)).soft_spots
    assert all(w.loss_pct < 35.0 for w in wrong)


def test_wheel_offsets_are_checked(bogie_passes):
    """Offsets that are not finite, or none: an error naming the pass and the field."""
    p = bogie_passes[0]
    for bad in ((), (float("nan"),), (30.0, -30.0)):
        with pytest.raises(ParameterError, match="p0: wheel_offsets_m") as e:
            separate([Pass(p.chainage_m, p.level_mm, p.force_n, label="p0",
                           wheel_offsets_m=bad), bogie_passes[1]])  # fmt: skip
        assert e.value.field == "wheel_offsets_m"


def _rough_pass(
    label: str,
    load_n: float,
    wheelbase_m: float,
    seed: int,
    span_m: tuple[float, float] = (0.0, 130.0),
) -> Pass:
    """A bogie's pass over rough rail as it measures it: the German low-disturbance geometry
    averaged under its two wheels (its own view of the rail), the zone's dip, 0.01 mm noise;
    band-passed 3-40 m. The pass covers ``span_m`` (m; the zone is at 60-66 m)."""
    start_m = span_m[0]
    grid = np.arange(start_m, span_m[1], STEP)
    geom = random_profile("german-low", span_m[1] - start_m + 10.0, seed=11, step_m=0.05)
    half = 0.5 * wheelbase_m
    seen = 0.5 * (geom(grid - start_m + half) + geom(grid - start_m - half)) * 1e3
    noise = np.random.default_rng(seed).normal(0, 0.01, grid.size)
    y = seen + _bogie_levels(load_n, wheelbase_m, grid) + noise
    ok = np.isfinite(y)
    lv = bandpass_distance(y[ok], STEP, 3.0, 40.0)
    return Pass(grid[ok], lv, 2 * load_n, label=label, wheel_offsets_m=(half, -half))


def test_a_coach_and_a_wagon_over_rough_rail_see_the_rail_through_each_others_wheels():
    """One coach pass (2.5 m bogies) and one wagon pass (2.0 m) over 1 mm of rough rail: each
    sees the geometry through its own wheelbase (the two views differ by about 0.1 mm at
    3-8 m). Averaged through each other's wheels the geometry cancels: the zone comes back
    with both ends within 1 m and its loss within 6 points, and nothing else is reported
    (without that view the difference reads as compliance: no zone, or false ones)."""
    coach = _rough_pass("coach", *COACH, seed=1)
    wagon = _rough_pass("wagon", *WAGON, seed=2)
    # each pass through the other's wheels: the coach over +-1.0 m, the wagon over +-1.25 m
    shifts = view_shifts([coach.wheel_offsets_m, wagon.wheel_offsets_m])
    assert shifts == [(-1.0, 1.0), (-1.25, 1.25)]
    sep = separate([coach, wagon], config=SeparationConfig(edge_factor=0.0))
    spots = [(s.start_m, s.end_m, s.loss_pct) for s in sep.soft_spots]
    assert len(spots) == 1, spots
    start, end, loss = spots[0]
    assert abs(start - 59.7) <= 1.0 and abs(end - 66.3) <= 1.0, spots
    assert abs(loss - 45.0) <= 6.0, spots


def test_a_short_pair_on_rough_rail_measures_its_noise_in_its_middle():
    """One coach and one wagon pass over 260 m of rough rail (1.7 mm robust spread), the zone
    in the middle. The edge term (0.3 of the roughness, decaying over 46 m) stays above the
    passes' prior noise for about 115 m from each end, so 29 m is clear of it: the
    compliance's noise is then measured on the 40 m least affected by the ends rather than
    left at the prior (four times the spread measured there), which made nothing separable."""
    coach = _rough_pass("coach", *COACH, seed=1, span_m=(-70.0, 190.0))
    wagon = _rough_pass("wagon", *WAGON, seed=2, span_m=(-70.0, 190.0))
    sep = separate([coach, wagon])
    assert sep.separable[sep.n_passes > 0].mean() > 0.2
    spots = [(s.start_m, s.end_m, s.loss_pct) for s in sep.soft_spots]
    assert len(spots) == 1, spots
    start, end, loss = spots[0]
    assert abs(start - 59.7) <= 1.0 and abs(end - 66.3) <= 1.0, spots
    assert abs(loss - 45.0) <= 6.0, spots


@pytest.mark.slow
def test_matched_detector_finds_zones_the_white_threshold_misses_on_rough_rail():
    """The engine's rough-rail case n101 (benchmarks/accuracy_bogie_separation.py, made after
    the matched detector to judge it; true vehicles): the residual's white threshold misses a
    zone of three (two found since passes are aligned without their ringing ends, one
    before), the detector matched to the compliance's coloured noise finds all three, ends
    within 1.5 m and losses within 10 pp, and no false zone."""
    case = CASES["n101"]
    passes = passes_of(case)["true vehicles"]
    white = score(separate(passes, config=SeparationConfig(matched_lengths_m=())), case.zones)
    matched = score(separate(passes), case.zones)
    assert white["found"] < len(case.zones)
    assert matched["found"] == len(case.zones)
    assert matched["false"] == [] and white["false"] == []


@pytest.mark.slow
def test_no_false_spot_from_the_long_waves_on_a_zone_free_rough_track():
    """Zone-free rough rail (seed 1010 of benchmarks/separation_false_alarms.py, presets 10 %
    off): the residual's white threshold reports an 11 m spot in the middle of the separable
    stretch; with the matched filter running there, the default reports none."""
    case = drawn_case(1010)
    assert case.zones == ()
    passes = passes_of(case)["registered presets"]
    white = separate(passes, config=SeparationConfig(matched_lengths_m=()))
    assert len(white.soft_spots) == 1
    assert separate(passes).soft_spots == []


@pytest.mark.slow
def test_zone_ends_follow_the_dip_not_the_long_waves_beside_it():
    """The engine's case s19 (true vehicles): its third zone, 2 m from the end of the
    separable stretch, sits on the compliance's long-wave noise; fitted with a level and
    a slope beside it (``EXTENT_TREND_ORDER``) its ends are within 1.5 m and its loss within
    10 pp (with the plain misfit: 1.2 m long and 30 pp too deep), and the long waves beside
    it are not reported as a spot of their own within 5 m of it. (Since the passes are
    aligned on their slopes, 0.4 cm from the truth instead of 2 cm, a weak 13 m spot 9 m
    past it, 384-397 m and 31 %, is reported on a compliance that barely moved: the
    detector's threshold, docs/accuracy.md "Passes aligned on their slopes".)"""
    case = CASES["s19"]
    sc = score(separate(passes_of(case)["true vehicles"]), case.zones)
    assert not sc["cells"].split("; ")[2].endswith("(out)"), sc
    assert sc["cells"].split("; ")[2] != "missed", sc
    third = case.zones[2]
    beside = [
        f for f in sc["false"]
        if float(f.split("-")[0]) <= third.end_m + 5.0
        and float(f.split("-")[1]) >= third.start_m - 5.0
    ]  # fmt: skip
    assert sc["found"] >= 2 and beside == [], sc


def test_an_end_error_of_exactly_the_tolerance_counts_as_found():
    """The benchmarks' count: a reported end lies 0.3 m off the 0.6 m support grid the
    zones' ends are on, so an end error is often exactly 1.5 m, which the float sum makes a
    hair over or under (d5006's third zone: 408.29999999999995 against 409.8 m)."""
    assert within(408.29999999999995 - 409.8, 0.0, 0.0)
    assert within(0.0, 414.0 + 1.5 - 414.0, -10.0)
    assert not within(-1.51, 0.0, 0.0)
    assert not within(0.0, 1.51, 0.0)
    assert not within(0.0, 0.0, 10.1)
