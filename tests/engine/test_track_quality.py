"""EN 13848 quality analysis (engine.track_quality): filters against their definition, section
SDs, speed-class limits and quality classes at their boundaries, trends, observability."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import numpy as np
import pytest

from engine.bogie import PASSENGER_COACH
from engine.errors import ParameterError
from engine.quality_limits import (
    DEFAULT_ISOLATED_MM,
    LineSpeed,
    QualityLimits,
    check_line_speeds,
    isolated_defects,
    unverified_defaults,
)
from engine.register import Observation, build_register
from engine.track_quality import (
    BANDS,
    band_levels,
    observability,
    predict_crossing,
    repeatability,
    section_statistics,
    trim_ends,
)
from engine.vehicle import TABLE1

STEP = 0.25


@pytest.mark.parametrize("name", ["D1", "D2"])
def test_filter_gain_is_minus_3_db_at_the_band_limits_and_flat_inside(name: str) -> None:
    """The zero-phase gain is -3 dB at both band limits, ~1 in the middle of the band and
    small an octave and more outside it."""
    b = BANDS[name]
    g = b.transfer([b.lambda_min_m, b.lambda_max_m])
    assert np.allclose(20 * np.log10(g), -3.0, atol=0.02)
    mid = np.sqrt(b.lambda_min_m * b.lambda_max_m)
    assert b.transfer([mid])[0] > (0.97 if name == "D1" else 0.8)
    assert b.transfer([b.lambda_min_m / 2, b.lambda_max_m * 2]).max() < 0.02


@pytest.mark.parametrize("name", ["D1", "D2"])
@pytest.mark.parametrize("frac", [0.0, 0.5, 1.0])
def test_applied_filter_matches_its_transfer_function(name: str, frac: float) -> None:
    """A sinusoid through ``apply`` keeps the amplitude the transfer function states (at the
    lower limit, the geometric middle and the upper limit of the band), with no phase shift."""
    b = BANDS[name]
    lam = b.lambda_min_m * (b.lambda_max_m / b.lambda_min_m) ** frac
    x = np.arange(0.0, 3000.0, STEP)
    y = np.sin(2 * np.pi * x / lam)
    f = b.apply(y, STEP)
    m = slice(int(400 / STEP), int(-400 / STEP))
    gain = float(b.transfer([lam])[0])
    assert np.std(f[m]) / np.std(y[m]) == pytest.approx(gain, rel=0.01)
    assert np.corrcoef(f[m], y[m])[0, 1] > 0.999  # zero phase


def test_filter_keeps_nan_gaps_and_refuses_a_too_coarse_grid() -> None:
    """NaN stays NaN, a stretch shorter than the band's longest wave gets no value, and a
    grid too coarse for 3 m waves is refused naming the step."""
    y = np.sin(np.arange(4000) * STEP * 2 * np.pi / 10.0)
    y[1000:1010] = np.nan
    y[3990:] = np.nan
    y[3900:3990] = 1.0  # 22.5 m: shorter than D1's 25 m
    y[3899] = np.nan
    f = BANDS["D1"].apply(y, STEP)
    assert np.isnan(f[1000:1010]).all() and np.isnan(f[3900:]).all()
    assert np.isfinite(f[:1000]).all()
    with pytest.raises(ParameterError) as e:
        BANDS["D1"].apply(y, 2.0)
    assert e.value.field == "step_m"


def test_section_sd_of_a_known_sinusoid() -> None:
    """A 10 m sine of amplitude 2 mm has SD sqrt(2) mm in D1 in every 200 m section."""
    x = np.arange(0.0, 1000.0, STEP)
    f = BANDS["D1"].apply(2.0 * np.sin(2 * np.pi * x / 10.0), STEP)
    st = section_statistics(x, {"D1": f}, 200.0)
    assert [s.start_m for s in st] == [0.0, 200.0, 400.0, 600.0, 800.0]
    for s in st[1:-1]:
        assert s.sd_mm["D1"] == pytest.approx(
            np.sqrt(2.0) * BANDS["D1"].transfer([10.0])[0], rel=0.01
        )
    half = f.copy()
    half[x < 150] = np.nan
    st = section_statistics(x, {"D1": half}, 200.0, min_coverage=0.5)
    assert np.isnan(st[0].sd_mm["D1"])  # 25 % covered


def test_isolated_limits_at_speed_class_boundaries() -> None:
    """A value exactly at a limit reaches it; the speed class boundary is inclusive upwards
    (80 km/h is in the <= 80 class, 80.1 in the next)."""
    lim = QualityLimits()
    assert lim.level("D1", 80.0, 12.0) == "alert"
    assert lim.level("D1", 80.0, 11.99) is None
    assert lim.level("D1", 80.1, 8.0) == "alert"
    assert lim.level("D1", 80.1, -12.0) == "intervention"
    assert lim.level("D1", 300.0, 16.0) == "immediate"
    assert lim.level("D2", 160.0, 50.0) is None  # D2 limits above 160 km/h only
    assert lim.level("D2", 161.0, 8.0) == "alert"


def test_quality_class_boundaries() -> None:
    """Class bounds are upper-inclusive; beyond D's bound is E; an unknown speed takes the
    strictest class row."""
    lim = QualityLimits()
    a, b, c, d = lim.class_sd_mm[2]
    assert lim.quality_class(a, 150.0) == "A"
    assert lim.quality_class(a + 1e-6, 150.0) == "B"
    assert lim.quality_class(d, 150.0) == "D"
    assert lim.quality_class(d + 0.01, 150.0) == "E"
    assert lim.quality_class(lim.class_sd_mm[-1][0] + 0.01, None) == "B"


def test_limits_refuse_disorder_and_bad_rows() -> None:
    """Limits that shrink from alert to immediate, or rows of the wrong length, are refused
    naming the field."""
    with pytest.raises(ParameterError) as e:
        QualityLimits.from_dict({"isolated_mm": {"D1": [[5.0, 4.0, 9.0]] * 5}})
    assert e.value.field == "isolated_mm.D1[0]"
    with pytest.raises(ParameterError):
        QualityLimits.from_dict({"class_sd_mm": [[1.0, 2.0, 3.0, 4.0]] * 4})
    with pytest.raises(ParameterError):
        QualityLimits.from_dict({"class_sd_mm": [[2.0, 1.0, 3.0, 4.0]] * 5})


def test_isolated_defects_follow_line_speed() -> None:
    """The same 15 mm bump (about 11 mm in D1) is an alert at 100 km/h and an intervention
    at 150 km/h; one defect per exceedance, at its peak."""
    x = np.arange(0.0, 600.0, STEP)
    y = np.zeros_like(x)
    for c in (150.0, 450.0):
        y += -15.0 * np.exp(-(((x - c) / 2.0) ** 2))
    speeds = check_line_speeds([LineSpeed(300.0, 600.0, 150.0), LineSpeed(0.0, 300.0, 100.0)])
    f = BANDS["D1"].apply(y, STEP)
    found = isolated_defects(x, f, "D1", QualityLimits(), speeds)
    v = float(np.abs(f[int(150 / STEP)]))
    assert 10.0 <= v < 12.0  # alert at 100 km/h (8-12 mm), intervention at 150 (10-14)
    assert [(round(d.peak_m), d.level) for d in found] == [(150, "alert"), (450, "intervention")]
    with pytest.raises(ParameterError):
        check_line_speeds([LineSpeed(0, 200, 100), LineSpeed(150, 300, 120)])


def test_repeatability_of_noisy_copies() -> None:
    """Two copies with independent N(0, s) noise differ by N(0, s sqrt 2): 95 % of |diff| is
    1.96 s sqrt 2."""
    rng = np.random.default_rng(3)
    base = rng.normal(size=20000)
    s = 0.1
    r = repeatability(
        [base + s * rng.normal(size=base.size), base + s * rng.normal(size=base.size)]
    )
    assert r.r95_mm == pytest.approx(1.96 * s * np.sqrt(2), rel=0.05)
    assert r.n_pairs == 1


def test_predicted_crossing_of_a_linear_trend() -> None:
    """Values growing 1 mm per 100 days from 2 mm reach 5 mm 300 days after the start; the
    interval brackets it; a flat series gives no date; at the limit it is reached."""
    t0 = datetime(2026, 1, 1, tzinfo=UTC)
    times = [t0 + timedelta(days=50 * i) for i in range(5)]
    rng = np.random.default_rng(1)
    vals = [2.0 + 0.01 * 50 * i + 0.02 * rng.normal() for i in range(5)]
    c = predict_crossing(times, vals, 5.0)
    assert c.date is not None and abs((c.date - (t0 + timedelta(days=300))).days) < 15
    assert c.earliest is not None and c.earliest <= c.date
    assert c.latest is None or c.latest >= c.date
    assert predict_crossing(times, [2.0, 2.0, 2.0, 2.0, 2.0], 5.0).date is None
    assert predict_crossing(times, [2, 3, 4, 5, 6], 5.0).reached


def test_observability_names_the_axle_spacing_nulls() -> None:
    """Table 1's axles are 8.26 m apart: bounce nulls at 16.52, 5.51, 3.3 m, pitch nulls at
    8.26 and 4.13 m; together the two signals leave no wavelength of 3-70 m unobserved."""
    o = observability(TABLE1, 24.0)
    assert o.bounce_nulls_m == (16.52, 5.51, 3.3)
    assert o.pitch_nulls_m == (8.26, 4.13)
    assert o.unobservable_m == ()
    stiff = observability(TABLE1, 24.0, threshold=0.99)
    assert stiff.unobservable_m  # a demanding threshold does flag ranges


def test_observability_of_a_bogie_vehicle_names_its_wheelbase_nulls() -> None:
    """A bogie's two wheelsets 2.6 m apart cancel a 5.2 m wavelength between them (and its odd
    fractions): the body cannot see it, whatever its suspension; the bogie centres' spacing
    (19 m) gives the bounce and pitch nulls a half car's axles would."""
    o = observability(PASSENGER_COACH, 28.0)
    assert o.wheelbase_nulls_m == (5.2,)
    assert o.bounce_nulls_m[0] == 38.0 and o.pitch_nulls_m[0] == 19.0
    at = int(np.argmin(np.abs(o.wavelength_m - 5.2)))
    assert o.gain[at] < 0.05 and any(a <= 5.2 <= b for a, b in o.unobservable_m)
    assert observability(TABLE1, 24.0).wheelbase_nulls_m == ()
    assert o.to_dict()["wheelbase_nulls_m"] == [5.2]


def test_isolated_defects_agree_with_the_scalar_rule_at_boundaries() -> None:
    """Along a line whose speed steps at 80 km/h, values exactly at and just below each limit
    get the level ``QualityLimits.level`` gives them, and a place without a line speed takes
    the strictest class."""
    lim = QualityLimits()
    speeds = check_line_speeds([LineSpeed(0.0, 100.0, 80.0), LineSpeed(100.0, 200.0, 80.1)])
    values = [12.0, 11.99, 17.0, 28.0, 8.0, 12.0, 26.0, 4.0]
    where = [10.0, 20.0, 30.0, 40.0, 110.0, 120.0, 130.0, 250.0]
    x = np.arange(0.0, 300.0, 1.0)
    v = np.zeros_like(x)
    for c, a in zip(where, values, strict=True):
        v[int(c)] = a
    found = {d.peak_m: d for d in isolated_defects(x, v, "D1", lim, speeds)}
    for c, a in zip(where, values, strict=True):
        s = None if c >= 200 else (80.0 if c < 100 else 80.1)
        want = lim.level("D1", s, a)
        assert (found[c].level if c in found else None) == want, (c, a)
    assert found[250.0].speed_kmh is None and found[250.0].level == "alert"


def test_trim_ends_blanks_each_stretch_ends() -> None:
    """25 m (100 points at 0.25 m) at both ends of every finite stretch become NaN; the rest
    is untouched; a stretch shorter than twice the margin vanishes."""
    v = np.ones(1000)
    v[400:410] = np.nan
    v[900:] = np.nan
    v[850] = np.nan
    t = trim_ends(v, 0.25, 25.0)
    assert np.isnan(t[:100]).all() and np.isfinite(t[100:300]).all() and np.isnan(t[300:510]).all()
    assert np.isfinite(t[510:750]).all() and np.isnan(t[750:]).all()


def test_d2_is_filtered_from_its_own_long_level() -> None:
    """D1 comes from the quality level, D2 from the long level when one is given (a 50 m wave
    only the long level holds shows at its full amplitude in D2, not in D1); without a long
    level D2 falls back to the quality level and says so; the quality level is required."""
    x = np.arange(0.0, 1000.0, STEP)
    short = 1.0 * np.sin(2 * np.pi * x / 10.0)
    long = short + 2.0 * np.sin(2 * np.pi * x / 50.0)
    inner = (x > 200) & (x < 800)
    filt, used = band_levels({"quality": short, "long": long}, STEP)
    assert used == {"D1": "quality", "D2": "long"}
    assert np.max(np.abs(filt["D2"][inner])) == pytest.approx(2.0, rel=0.03)
    assert np.max(np.abs(filt["D1"][inner])) == pytest.approx(1.0, rel=0.03)
    alone, used = band_levels({"quality": short}, STEP, trim_m=25.0)
    assert used["D2"] == "quality" and np.max(np.abs(alone["D2"][inner])) < 0.05
    assert np.isnan(alone["D1"][: int(25.0 / STEP)]).all()  # the trimmed end
    with pytest.raises(ParameterError) as e:
        band_levels({"long": long}, STEP)
    assert e.value.field == "levels"


def test_unverified_defaults_are_named_until_replaced() -> None:
    """Every default table is flagged; a track's own D1 table is not; restating a default
    (same figures) keeps it flagged."""
    assert unverified_defaults(QualityLimits()) == (
        "isolated_mm.D1", "isolated_mm.D2", "class_sd_mm",
    )  # fmt: skip
    own = QualityLimits.from_dict({"isolated_mm": {"D1": [[1.5, 2.0, 2.5]] * 5}})
    assert unverified_defaults(own) == ("isolated_mm.D2", "class_sd_mm")
    same = QualityLimits.from_dict(
        {"isolated_mm": {"D1": [list(t) for t in DEFAULT_ISOLATED_MM["D1"]]}}
    )
    assert "isolated_mm.D1" in unverified_defaults(same)


def test_register_judges_isolated_sightings_by_their_own_level() -> None:
    """A defect of isolated-level sightings takes the level its latest sighting carries (the
    speed-class limits'), not the register's depth limits (which 5 mm would exceed), and
    ``level_since`` is the first sighting at that level or worse; a soft-spot sighting at the
    same depth is still judged by the depth limits."""
    t0 = datetime(2026, 1, 1, tzinfo=UTC)
    seen = [
        Observation(i, t0 + timedelta(days=30 * i), 100.0, 104.0, 102.0, v, None,
                    source="isolated", level=lv)
        for i, (v, lv) in enumerate(((4.0, None), (5.0, "alert"), (5.5, "alert")))
    ]  # fmt: skip
    (d,) = build_register(seen)
    assert d.source == "isolated" and d.level == "alert" and d.priority == 3
    assert d.level_since == t0 + timedelta(days=30)
    assert d.trend_mm_per_month > 0 and d.status == "worsening"
    (soft,) = build_register([Observation(9, t0, 100.0, 104.0, 102.0, 5.0, None)])
    assert soft.level == "immediate"  # 5 mm over the default 0.40 mm depth limit
