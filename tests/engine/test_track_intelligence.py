"""Alignment of repeated runs, aggregation and the soft-spot register (issue 6, engine side)."""

import dataclasses
import datetime as dtm
import warnings

import numpy as np
import pytest

from engine.aggregate import aggregate_levels, column_nanmedian
from engine.align import align_profiles
from engine.errors import ParameterError
from engine.pipeline import process_run
from engine.register import Limits, Observation, RunCoverage, build_register
from engine.setup import RunSetup, prepare_run
from engine.synthetic import REALISTIC_SENSOR, make_run
from engine.track import SoftZone

SENSOR = dataclasses.replace(REALISTIC_SENSOR, sample_rate_hz=1000.0)
T0 = dtm.datetime(2026, 1, 1, tzinfo=dtm.UTC)


def _campaign(losses_of_run, n_runs, seed):
    """Runs over one physical track (same support scatter) with start-chainage errors."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n_runs):
        err = float(rng.uniform(-5, 5))
        speed = float(rng.uniform(20, 30))
        zones = losses_of_run(i)
        run = make_run(
            length=320.0,
            zones=zones,
            speed=speed,
            sensor=SENSOR,
            sim_rate_hz=1000.0,
            jitter=0.05,
            seed=seed * 100 + i,
            track_seed=seed,
        )
        res = process_run(
            prepare_run(run.log, RunSetup(start_chainage_m=run.start_chainage_m + err))
        )
        out.append((err, res, T0 + dtm.timedelta(days=10 * i)))  # fmt: skip
    return out


def _register(campaign):
    ref = campaign[0][1]
    obs, cov, offsets = [], [], []
    for i, (_, res, when) in enumerate(campaign):
        al = align_profiles(ref.chainage_m, ref.level_mm, res.chainage_m, res.level_mm)
        off = al.offset_m if i else 0.0
        assert i == 0 or al.ok
        offsets.append(off)
        for s in res.soft_spots:
            obs.append(Observation(i, when, s.start_m + off, s.end_m + off, s.peak_m + off,
                                   s.depth_mm, s.stiffness_loss_pct))  # fmt: skip
        cov.append(RunCoverage(i, when, res.chainage_m[0] + off, res.chainage_m[-1] + off))
    return build_register(obs, cov), offsets


@pytest.fixture(scope="module")
def steady():
    zones = [SoftZone(90, 94, 0.5), SoftZone(160, 163, 0.35), SoftZone(230, 236, 0.4)]
    return _campaign(lambda i: zones, 5, seed=3)


@pytest.mark.slow
def test_runs_align_within_half_a_metre(steady):
    """Start-chainage errors up to +-5 m are undone to within 0.5 m (relative to run 0)."""
    _, offsets = _register(steady)
    err0 = steady[0][0]
    for (err, _, _), off in zip(steady[1:], offsets[1:], strict=True):
        # logged = true + err, so the offset that maps it onto run 0 is err0 - err
        assert abs(off - (err0 - err)) <= 0.5


def test_one_defect_per_zone_seen_in_every_run(steady):
    """Each real soft zone becomes exactly one defect, seen by every run that covered it."""
    register, _ = _register(steady)
    assert len(register) == 3
    for d in register:
        assert d.runs_seen == 5 == d.runs_covering
        assert d.status in ("stable", "worsening", "confirmed")
    assert [d.priority for d in register] == sorted(d.priority for d in register)


@pytest.mark.slow
def test_deepening_zone_reported_worsening_with_rate():
    """A zone whose loss grows 20 % -> 50 % over 50 days is worsening at ~+18 pp/month."""
    camp = _campaign(
        lambda i: [SoftZone(90, 94, 0.5), SoftZone(200, 206, 0.2 + 0.06 * i)], 6, seed=4
    )
    register, _ = _register(camp)
    grow = [d for d in register if 190 < d.peak_m < 215]
    steady = [d for d in register if 80 < d.peak_m < 105]
    assert len(grow) == 1 and len(steady) == 1
    g = grow[0]
    assert g.status == "worsening"
    true_rate = 6.0 / 10 * dtm.timedelta(days=30.4375).days  # pp per month
    assert g.trend_loss_pct_per_month == pytest.approx(true_rate, rel=0.35)
    assert g.trend_mm_per_month > 0.05
    assert steady[0].status == "stable"
    assert abs(steady[0].trend_mm_per_month) < 0.02


def test_alignment_flags_unrelated_profiles():
    """A profile that does not match the reference is flagged, not silently placed."""
    g = np.arange(0.0, 300.0, 0.25)
    rng = np.random.default_rng(0)
    a = np.convolve(rng.normal(size=g.size), np.ones(20) / 20, mode="same")
    b = np.convolve(rng.normal(size=g.size), np.ones(20) / 20, mode="same")
    assert not align_profiles(g, a, g, b).ok
    assert not align_profiles(g, a, g[:100], a[:100]).ok  # too short an overlap
    shifted = align_profiles(g, a, g + 3.3, a)
    assert shifted.ok and shifted.offset_m == pytest.approx(-3.3, abs=0.05)
    with pytest.raises(ParameterError):
        align_profiles(g, a, np.arange(0.0, 300.0, 0.5), a[::2])


def test_aggregate_median_spread_count():
    """Median and robust spread per chainage, counting only runs that cover it."""
    g = np.arange(5.0)
    lv = np.array([[1, 2, np.nan, 4, 5], [1, 2, 3, 4, 7], [1, 8, 3, np.nan, 6]], dtype=float)
    agg = aggregate_levels(g, lv)
    assert np.allclose(agg.level_mm, [1, 2, 3, 4, 6])
    assert list(agg.n_runs) == [3, 3, 2, 2, 3]
    assert agg.spread_mm[0] == 0.0 and agg.spread_mm[4] == pytest.approx(1.4826)


@pytest.mark.parametrize("runs", [1, 2, 3, 4, 7, 30])
def test_aggregate_median_is_numpys_nanmedian_to_the_bit(runs):
    """The aggregate's median (one sort along the runs) gives numpy's nanmedian exactly, for
    odd and even counts, ties, and runs that cover only parts of the grid (float32 levels, as
    stored)."""
    rng = np.random.default_rng(runs)
    lv = rng.standard_normal((runs, 5000)).astype(np.float32).astype(np.float64)
    lv[rng.random(lv.shape) < 0.35] = np.nan
    lv[:, :50] = 0.25  # ties
    n = np.isfinite(lv).sum(axis=0)
    has = n > 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        want = np.nanmedian(lv[:, has], axis=0)
        want_mad = np.nanmedian(np.abs(lv[:, has] - want), axis=0)
    assert np.array_equal(column_nanmedian(lv[:, has], n[has]), want)
    agg = aggregate_levels(np.arange(lv.shape[1], dtype=float), lv)
    assert np.array_equal(agg.level_mm[has], want)
    assert np.array_equal(agg.spread_mm[has], 1.4826 * want_mad)
    assert np.all(np.isnan(agg.level_mm[~has])) and np.all(agg.n_runs == n)


def test_limits_levels_and_validation():
    """Depth or loss reaching a level gives that level; limits must grow with urgency."""
    lim = Limits(
        alert_depth_mm=0.1, intervention_depth_mm=0.2, immediate_depth_mm=0.3,
        alert_loss_pct=None, intervention_loss_pct=40, immediate_loss_pct=None,
    )  # fmt: skip
    assert lim.level(0.05, 10) is None
    assert lim.level(0.12, 10) == "alert"
    assert lim.level(0.12, 45) == "intervention"
    assert lim.level(0.35, None) == "immediate"
    with pytest.raises(ParameterError):
        Limits(alert_depth_mm=0.3, intervention_depth_mm=0.2)


def test_register_level_since_and_split_zone():
    """level_since is the first run reaching today's level; a split zone counts once per run."""
    mk = lambda run, day, s, e, d: Observation(run, T0 + dtm.timedelta(days=day), s, e,  # noqa: E731
                                               (s + e) / 2, d, None)  # fmt: skip
    obs = [mk(1, 0, 10, 14, 0.1), mk(2, 30, 10, 12, 0.2), mk(2, 30, 12.5, 14, 0.26),
           mk(3, 60, 10.2, 14, 0.3)]  # fmt: skip
    (d,) = build_register(obs)
    assert d.runs_seen == 3
    assert d.level == "intervention"
    assert d.level_since == T0 + dtm.timedelta(days=30)
    assert d.first_seen == T0 and d.last_seen == T0 + dtm.timedelta(days=60)
