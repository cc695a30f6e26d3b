"""Positions from GNSS in the engine: centerlines, linear referencing and the odometer fit.

The line is synthetic (tests/support/gnss.py): 300 m straight, a 1 200 m radius bend of 600 m,
a straight, starting at chainage 11 900 m; fixes are the true positions plus 1.5 m white noise
per axis and a wandering (Ornstein-Uhlenbeck) bias.
"""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

from engine.logio import parse_run_csv
from engine.positioning import (
    LATERAL_TOLERANCE_M,
    MAX_FIXES,
    Centerline,
    CenterlineError,
    FixesBesideLine,
    FixesDoNotFollowLine,
    FixesOffLine,
    NoFixes,
    TooFewFixes,
    centerline_from_csv,
    centerline_from_geojson,
    place_log,
    place_run,
    thin_fixes,
)
from engine.synthetic import make_run
from support.gnss import (
    LINE_START_CHAINAGE_M,
    RUN_OFFSET_M,
    centerline_geojson,
    csv_with_fixes,
    gnss_fixes,
    plan_xy,
    to_lonlat,
    with_fixes,
)

FEATURE = centerline_geojson()
START = LINE_START_CHAINAGE_M + RUN_OFFSET_M + 24.0


@pytest.fixture(scope="module")
def line() -> Centerline:
    return centerline_from_geojson(FEATURE)


def constant_run(
    v: float = 30.0, seconds: float = 33.0, rate: float = 500.0
) -> tuple[np.ndarray, np.ndarray]:
    """Sample times (s) and true line chainage (m) of a run at constant speed."""
    t = np.arange(0.0, seconds, 1.0 / rate)
    return t, START + v * t


# ---- centerline ----------------------------------------------------------------------------------


def test_geojson_forms_agree_and_chainage_is_the_length_along_the_line(line: Centerline) -> None:
    """A bare LineString, a Feature and a one-feature FeatureCollection give the same line;
    the chainage grows with the ground length (the synthetic line is 1 400 m long)."""
    bare = centerline_from_geojson(FEATURE["geometry"], start_chainage_m=LINE_START_CHAINAGE_M)
    fc = centerline_from_geojson({"type": "FeatureCollection", "features": [FEATURE]})
    for other in (bare, fc):
        np.testing.assert_array_equal(other.chainage_m, line.chainage_m)
    assert line.start_chainage_m == LINE_START_CHAINAGE_M
    assert line.end_chainage_m == pytest.approx(LINE_START_CHAINAGE_M + 1400.0, abs=0.05)
    assert centerline_from_geojson(FEATURE["geometry"]).start_chainage_m == 0.0


def test_locate_gives_chainage_and_lateral_offset(line: Centerline) -> None:
    """Points 3 m to the side of known chainages project back onto them (m accuracy: mm)."""
    s = np.array([10.0, 299.0, 450.0, 899.5, 1300.0])
    x, y = plan_xy(s)
    hx, hy = plan_xy(s + 0.01)
    tx, ty = (hx - x) / 0.01, (hy - y) / 0.01
    lon, lat = to_lonlat(x - 3.0 * ty, y + 3.0 * tx)
    got = line.locate(lon, lat)
    np.testing.assert_allclose(got.chainage_m, LINE_START_CHAINAGE_M + s, atol=0.02)
    np.testing.assert_allclose(got.offset_m, 3.0, atol=0.02)
    np.testing.assert_allclose(got.lateral_m, 3.0, atol=0.02)  # left, looking up the chainage
    right = line.locate(*to_lonlat(x + 3.0 * ty, y - 3.0 * tx))
    np.testing.assert_allclose(right.lateral_m, -3.0, atol=0.02)


def test_csv_centerline_with_explicit_chainage_and_an_equation() -> None:
    """CSV chainage_m,lat,lon: chainage as given, a jump (chainage equation) kept."""
    s = np.arange(0.0, 1000.0, 10.0)
    lon, lat = to_lonlat(*plan_xy(s))
    ch = 5000.0 + s + np.where(s >= 500.0, 20.0, 0.0)  # 20 m equation at 500 m
    rows = "\n".join(f"{c},{b:.9f},{a:.9f}" for c, a, b in zip(ch, lon, lat, strict=True))
    cl = centerline_from_csv("chainage_m,lat,lon\n" + rows + "\n")
    np.testing.assert_array_equal(cl.chainage_m, ch)
    lo, la = to_lonlat(*plan_xy(np.array([250.0, 750.0])))
    np.testing.assert_allclose(cl.locate(lo, la).chainage_m, [5250.0, 5770.0], atol=0.05)


@pytest.mark.parametrize(
    ("coords", "words"),
    [
        ([[10.0, 50.0]], "1 point"),
        ([[10.0, 50.0], [10.0, 50.0]], "1 distinct point"),
        ([[10.0, 50.0], [10.01, 50.01], [10.01, 50.0], [10.0, 50.01]], "crosses itself"),
        ([[50.0, 100.0], [50.01, 100.01]], "look swapped"),
        ([[10.0, 50.0], [190.0, 50.0]], "longitude 190"),
        ([[10.0, 50.0], [10.0, -91.0]], "latitude -91"),
        ([[10.0, 50.0], ["a", 50.0]], "must be a number"),
    ],
)
def test_bad_lines_are_refused_naming_the_problem(coords: list, words: str) -> None:
    with pytest.raises(CenterlineError, match=words):
        centerline_from_geojson({"type": "LineString", "coordinates": coords})


def test_csv_chainage_must_grow_and_columns_must_be_there() -> None:
    with pytest.raises(CenterlineError, match="vertex 3 has 5 m after 10 m"):
        centerline_from_csv("chainage_m,lat,lon\n0,50,10\n10,50.0001,10\n5,50.0002,10\n")
    with pytest.raises(CenterlineError, match="not found: lon"):
        centerline_from_csv("chainage_m,lat,x\n0,50,10\n10,50.0001,10\n")
    with pytest.raises(CenterlineError, match="line 3.*'lat' holds 'n/a'"):
        centerline_from_csv("chainage_m,lat,lon\n0,50,10\n10,n/a,10\n")


@pytest.mark.parametrize(("factor", "refused"), [(1.39, True), (0.9, True), (1.03, False)])
def test_csv_chainage_far_from_the_line_length_is_refused_naming_both(
    factor: float, refused: bool
) -> None:
    """A CSV whose chainage runs 39 % longer (or 10 % shorter) than the line's geodesic
    length is refused naming both lengths; 3 % (within the 5 % tolerance) is kept, and so is
    a 200 m chainage equation at a repeated point (not a length)."""
    s = np.arange(0.0, 1000.0, 10.0)
    lon, lat = to_lonlat(*plan_xy(s))
    ch = factor * s
    rows = [f"{c},{b:.9f},{a:.9f}" for c, a, b in zip(ch, lon, lat, strict=True)]
    rows.insert(50, f"{ch[49] + 200.0},{lat[49]:.9f},{lon[49]:.9f}")  # the equation
    after = zip(ch[50:], rows[51:], strict=True)
    rows[51:] = [f"{c + 200.0},{r.split(',', 1)[1]}" for c, r in after]
    text = "chainage_m,lat,lon\n" + "\n".join(rows) + "\n"
    if refused:
        with pytest.raises(CenterlineError, match=r"runs \d+\.\d m along.*is 990\.\d m long") as e:
            centerline_from_csv(text)
        assert e.value.field == "chainage_m"
    else:
        assert centerline_from_csv(text).end_chainage_m == pytest.approx(ch[-1] + 200.0)


def test_two_start_chainages_that_disagree_are_refused() -> None:
    with pytest.raises(CenterlineError, match="given twice"):
        centerline_from_geojson(copy.deepcopy(FEATURE), start_chainage_m=0.0)


# ---- the odometer fit ----------------------------------------------------------------------------


def test_clean_fixes_give_start_direction_and_scale(line: Centerline) -> None:
    t, true = constant_run()
    lat, lon = gnss_fixes(true, t, white_m=0.0, bias_m=0.0)
    fit = place_run(line, t, 1.006 * 30.0 * t, lat, lon)
    assert fit.direction == "increasing"
    assert fit.scale == pytest.approx(1 / 1.006, rel=1e-5)
    assert np.max(np.abs(fit.chainage(1.006 * 30.0 * t) - true)) < 0.01
    assert fit.n_used == fit.n_fixes and fit.n_rejected == 0


def test_noisy_fixes_with_outliers_and_decreasing_direction(line: Centerline) -> None:
    """1.5 m noise, 0.7 m wandering bias, 10 % of fixes thrown 20-40 m along the line: the
    outliers are rejected, the chainage stays within 1 m; travel in decreasing chainage."""
    t, up = constant_run()
    true = up[-1] + up[0] - up  # the same stretch, driven the other way
    lat, lon = gnss_fixes(true, t, bias_m=0.7, bias_tau_s=10.0, seed=1)
    rng = np.random.default_rng(5)
    have = np.flatnonzero(np.isfinite(lat))
    bad = rng.choice(have, have.size // 10, replace=False)
    wrong = true[bad] + rng.choice([-1, 1], bad.size) * rng.uniform(20, 40, bad.size)
    lon[bad], lat[bad] = to_lonlat(*plan_xy(wrong - LINE_START_CHAINAGE_M))
    fit = place_run(line, t, 0.994 * 30.0 * t, lat, lon)
    assert fit.direction == "decreasing"
    assert fit.n_rejected >= bad.size * 0.9
    assert np.max(np.abs(fit.chainage(0.994 * 30.0 * t) - true)) < 1.0
    assert fit.scale == pytest.approx(1 / 0.994, abs=0.002)


@pytest.mark.parametrize(("lateral_m", "side"), [(4.5, "left"), (-8.0, "right")])
def test_fixes_on_a_neighbouring_track_are_refused_naming_offset_and_side(
    line: Centerline, lateral_m: float, side: str
) -> None:
    """A run whose fixes lie a steady 4.5 m (the next track) or 8 m from the line is refused
    beyond LATERAL_TOLERANCE_M, naming the offset and the side it lies on."""
    t, true = constant_run()
    lat, lon = gnss_fixes(true, t, lateral_m=lateral_m, bias_m=0.5, seed=2)
    with pytest.raises(FixesBesideLine, match=rf"steady {abs(lateral_m):.0f}\.\d m to its {side}"):
        place_run(line, t, 30.0 * t, lat, lon)
    # a looser tolerance places it, the offset reported with its sign
    fit = place_run(line, t, 30.0 * t, lat, lon, lateral_tolerance_m=10.0)
    assert fit.lateral_offset_m == pytest.approx(lateral_m, abs=0.6)


def test_a_run_on_the_line_with_a_biased_gnss_is_placed(line: Centerline) -> None:
    """A run on this track, its centerline drawn 1 m off the rails' middle and its GNSS
    biased by a steady ~1 m (a 33 s run sees one value of a bias wandering over 30 s): within
    LATERAL_TOLERANCE_M, placed, the offset reported with its sign."""
    t, true = constant_run()
    lat, lon = gnss_fixes(true, t, lateral_m=-1.0, bias_m=1.0, seed=2)
    fit = place_run(line, t, 30.0 * t, lat, lon)
    assert -LATERAL_TOLERANCE_M < fit.lateral_offset_m < -1.0
    assert np.max(np.abs(fit.chainage(30.0 * t) - true)) < 3.0  # the bias's along-track part


@pytest.mark.parametrize("receiver_hz", [10.0, 500.0])
def test_thinning_fixes_leaves_the_placement_unchanged(
    line: Centerline, receiver_hz: float
) -> None:
    """A fix on every row of a 500 Hz log, with a wandering bias, 1.5 m white noise and 2 %
    outliers: from a 10 Hz receiver held on every row (what a logger writes), and with noise
    of its own on every row (the most thinning to 10 Hz can throw away). The placement from
    the thinned fixes stays within 0.15 m / 0.3 m of the one from every fix over the whole run
    (the placement's own error against the truth is metres here: the bias), the scale within
    the same tolerance per 500 m (the run is 1 km) and the lateral offset within 0.2 m."""
    t, true = constant_run()
    lat, lon = gnss_fixes(true, t, rate_hz=receiver_hz, white_m=1.5, bias_m=1.0, seed=7)
    rng = np.random.default_rng(7)
    bad = np.isfinite(lon) & (rng.random(t.size) < 0.02)
    lon[bad] += rng.normal(0.0, 3e-4, int(bad.sum()))  # ~20 m east-west outliers
    fix = np.flatnonzero(np.isfinite(lat))
    held = fix[np.searchsorted(fix, np.arange(t.size), side="right") - 1]
    lat, lon = lat[held], lon[held]
    odo = 0.995 * 30.0 * t
    every = place_run(line, t, odo, lat, lon, fix_interval_s=0.0, max_fixes=None)
    thinned = place_run(line, t, odo, lat, lon)
    assert every.n_considered == every.n_fixes == t.size
    assert thinned.n_considered == pytest.approx(t.size / 50, rel=0.01)
    tolerance = 0.15 if receiver_hz == 10.0 else 0.3
    assert np.max(np.abs(thinned.chainage(odo) - every.chainage(odo))) < tolerance
    assert thinned.scale == pytest.approx(every.scale, abs=tolerance / 500.0)
    assert thinned.lateral_offset_m == pytest.approx(every.lateral_offset_m, abs=0.2)


def test_thin_fixes_keeps_a_10_hz_receiver_whole_and_caps_the_count() -> None:
    """Fixes at exactly 10 Hz all stay (time rounding does not drop any); an hour of fixes on
    every row of a 1 kHz log becomes 36 000; MAX_FIXES bounds a longer run."""
    t = np.arange(0.0, 60.0, 0.001)
    every_100th = np.zeros(t.size, bool)
    every_100th[::100] = True
    assert thin_fixes(t, every_100th).size == 600
    hour = np.arange(0.0, 3600.0, 0.001)
    assert thin_fixes(hour, np.ones(hour.size, bool)).size in (36_000, 36_001)  # both ends
    ten_hours = np.arange(0.0, 36_000.0, 0.05)
    assert thin_fixes(ten_hours, np.ones(ten_hours.size, bool)).size <= MAX_FIXES + 1


def test_a_scale_change_along_a_long_run_is_fitted_piecewise() -> None:
    """A 12 km straight run whose odometer reads 1 % long for 6 km, then right: one knot
    near 6 km, the chainage within 1 m everywhere (a single line is off by ~15 m)."""
    s = np.arange(0.0, 13000.0, 20.0)
    lon_v, lat_v = to_lonlat(s * 0.8, s * 0.6)
    cl = Centerline(lon_v, lat_v, s)
    t = np.arange(0.0, 400.0, 0.1)
    true = 100.0 + 30.0 * t
    odo = np.where(true - 100 < 6000, 1.01 * (true - 100), 6060.0 + (true - 6100))
    rng = np.random.default_rng(3)
    lon, lat = to_lonlat(
        true * 0.8 + rng.normal(0, 1.5, t.size), true * 0.6 + rng.normal(0, 1.5, t.size)
    )
    fit = place_run(cl, t, odo, lat, lon)
    assert len(fit.knots_m) >= 1
    assert min(abs(k - 6060.0) for k in fit.knots_m) < 300.0
    assert np.max(np.abs(fit.chainage(odo) - true)) < 1.0


def test_fixes_50_m_off_the_line_are_refused_naming_the_distance(line: Centerline) -> None:
    t, true = constant_run()
    lat, lon = gnss_fixes(true, t, lateral_m=50.0, seed=4)
    with pytest.raises(FixesOffLine, match=r"median 5\d\.\d m from the track's centerline") as e:
        place_run(line, t, 30.0 * t, lat, lon)
    assert 45 < e.value.median_offset_m < 55


def test_swapped_fix_columns_are_named(line: Centerline) -> None:
    t, true = constant_run()
    lat, lon = gnss_fixes(true, t, seed=4)
    with pytest.raises(FixesOffLine, match="swapped"):
        place_run(line, t, 30.0 * t, lon, lat)


def test_fixes_of_another_line_crossing_this_one_do_not_follow_it(line: Centerline) -> None:
    """A line crossing at right angles: its fixes near the crossing project onto one spot, so
    they do not advance with the odometer (or lie far off): refused either way."""
    t = np.arange(0.0, 33.0, 0.002)
    s_cross = 150.0
    x0, y0 = plan_xy(np.array([s_cross]))
    # the other line runs north-west through the crossing, most of its fixes far away
    d = 30.0 * t - 500.0
    lon, lat = to_lonlat(x0 - 0.5 * d, y0 + 0.866 * d)
    lat[1::2] = np.nan
    lon[1::2] = np.nan
    with pytest.raises((FixesOffLine, FixesDoNotFollowLine)):
        place_run(line, t, 30.0 * t, lat, lon)
    # only the stretch near the crossing: near the line, but standing still on it
    near = np.abs(d) < 8.0
    lat2, lon2 = np.where(near, lat, np.nan), np.where(near, lon, np.nan)
    with pytest.raises(FixesDoNotFollowLine, match="do not follow the centerline"):
        # every one of the half second's fixes (thinned to 10 Hz they would be too few)
        place_run(line, t, 30.0 * t, lat2, lon2, fix_interval_s=0.0)


def test_no_fixes_and_too_few_fixes(line: Centerline) -> None:
    t, true = constant_run()
    empty = np.full(t.size, np.nan)
    with pytest.raises(NoFixes, match="no GNSS fixes"):
        place_run(line, t, 30.0 * t, empty, empty)
    lat, lon = gnss_fixes(true, t, rate_hz=0.2, seed=0)
    with pytest.raises(TooFewFixes, match="only 7 GNSS fixes"):
        place_run(line, t, 30.0 * t, lat, lon)


# ---- logs with fixes -----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def short_run():  # type: ignore[no-untyped-def]
    return make_run(length=240.0, speed=30.0, sim_rate_hz=500.0, start_chainage_m=20.0)


def test_csv_with_sparse_lat_lon_is_read_and_placed(short_run, line: Centerline) -> None:  # type: ignore[no-untyped-def]
    """lat/lon columns with empty cells between 10 Hz fixes are recognised (degrees) and the
    placed log's chainage is the line's."""
    true = LINE_START_CHAINAGE_M + RUN_OFFSET_M + short_run.sim.x_body[: short_run.log.n]
    lat, lon = gnss_fixes(true, short_run.log.time_s, white_m=0.3, bias_m=0.0, seed=6)
    data = csv_with_fixes(with_fixes(short_run.log, lat, lon))
    parsed = parse_run_csv(data)
    assert parsed.columns["lat"] == "lat" and parsed.columns["lon"] == "lon"
    assert parsed.units["lat"] == "deg"
    assert parsed.log.lat_deg is not None
    assert int(np.isfinite(parsed.log.lat_deg).sum()) == int(np.isfinite(lat).sum())
    placed, fit = place_log(parsed.log, line)
    assert placed.chainage_m is not None
    assert np.max(np.abs(placed.chainage_m - true)) < 0.5
    assert fit.n_fixes == int(np.isfinite(lat).sum())


def test_csv_fix_problems_name_the_column_and_line(short_run) -> None:  # type: ignore[no-untyped-def]
    true = LINE_START_CHAINAGE_M + RUN_OFFSET_M + short_run.sim.x_body[: short_run.log.n]
    lat, lon = gnss_fixes(true, short_run.log.time_s, seed=6)
    text = csv_with_fixes(with_fixes(short_run.log, lat, lon)).decode()
    head, *rows = text.splitlines()
    only_lat = "\n".join([head.replace(",lon", ",x")] + rows) + "\n"
    with pytest.raises(ValueError, match="no column is the longitude"):
        parse_run_csv(only_lat.encode())
    half = rows[:]
    half[0] = half[0].rsplit(",", 1)[0] + ","  # a latitude without its longitude
    with pytest.raises(ValueError, match="line 2 has a value in column 'lat' but column 'lon'"):
        parse_run_csv(("\n".join([head, *half]) + "\n").encode())
    swapped = "\n".join([head.replace("lat,lon", "lon,lat")] + rows) + "\n"
    log = parse_run_csv(swapped.encode()).log  # 50 N / 10 E swapped is still in range ...
    with pytest.raises(FixesOffLine, match="swapped"):  # ... but the placement names it
        place_log(log, centerline_from_geojson(FEATURE))
    no_fixes = dataclasses.replace(short_run.log, lat_deg=None, lon_deg=None)
    with pytest.raises(NoFixes):
        place_log(no_fixes, centerline_from_geojson(FEATURE))
