"""Coupled forward simulation: closed form, convergence, static start, speed, soft zones."""

import numpy as np
import pytest

from engine.errors import ParameterError
from engine.simulate import simulate
from engine.track import SoftZone, Track, TrackParams
from engine.vehicle import TABLE1
from support.samples import sample


def test_static_level_matches_winkler_closed_form():
    """The static loaded level under each axle matches the Winkler beam within 2 %."""
    sim = simulate(Track(200.0), speed=20.0, duration=0.01, start_chainage_m=100.0)
    p1, p2 = TABLE1.static_axle_loads()
    tp = TrackParams()
    assert -sim.y_front[0] == pytest.approx(tp.winkler_deflection(p1), rel=0.02)
    assert -sim.y_rear[0] == pytest.approx(tp.winkler_deflection(p2), rel=0.02)
    # the contact springs carry the static axle loads
    assert sim.contact_front[0] == pytest.approx(p1, rel=1e-9)
    assert sim.contact_rear[0] == pytest.approx(p2, rel=1e-9)


def test_static_start_has_no_transient():
    """From static equilibrium on sound track, the body barely moves (< 1 mm/s² vs ~2e-2)."""
    sim = simulate(Track(200.0), speed=20.0, duration=3.0, start_chainage_m=40.0)
    assert sim.accel[0] == 0.0
    assert np.max(np.abs(sim.accel)) < 1e-3
    assert np.max(np.abs(sim.pitch_rate)) < 5e-5
    # and a soft zone gives an order of magnitude more
    soft = simulate(
        Track(200.0, zones=[SoftZone(80, 85, 0.5)]), speed=20.0, duration=3.0, start_chainage_m=40
    )
    assert np.max(np.abs(soft.accel)) > 10 * np.max(np.abs(sim.accel))


def test_long_soft_zone_deepens_level_by_winkler_factor():
    """In a long 50 % soft zone the static level deepens by about 0.5**-0.75 = 1.68."""
    track = Track(200.0, zones=[SoftZone(60, 140, 0.5)])
    sim = simulate(track, speed=20.0, duration=0.01, start_chainage_m=100.0)
    ref = simulate(Track(200.0), speed=20.0, duration=0.01, start_chainage_m=100.0)
    assert sim.y_front[0] / ref.y_front[0] == pytest.approx(0.5**-0.75, rel=0.03)


def test_converges_with_second_order_as_step_shrinks():
    """Halving the step cuts the error in body acceleration by about 4 (Newmark is 2nd order)."""
    track = Track(120.0, zones=[SoftZone(50, 54, 0.5)])
    kw = dict(speed=25.0, duration=1.6, start_chainage_m=30.0)
    ref = simulate(track, dt=1.25e-4, **kw)
    errs = []
    for dt in (2e-3, 1e-3, 5e-4):
        sim = simulate(track, dt=dt, **kw)
        k = int(round(dt / 1.25e-4))
        errs.append(np.max(np.abs(sim.accel - ref.accel[::k][: sim.accel.size])))
    assert errs[0] > errs[1] > errs[2]
    assert errs[0] / errs[1] > 3.0 and errs[1] / errs[2] > 3.0


def test_variable_speed_positions_and_zone_location():
    """With a speed ramp, axle chainages integrate the speed and the dip sits on the zone."""
    track = Track(300.0, zones=[SoftZone(150, 155, 0.5)])

    def ramp(t):
        return 20.0 + 2.0 * t

    sim = simulate(track, speed=ramp, duration=5.0, start_chainage_m=100.0)
    t = sim.t
    expected = 100.0 + 20.0 * t + t**2  # integral of the ramp
    assert np.allclose(sim.x_body, expected, atol=1e-6)
    assert np.allclose(sim.x_front - sim.x_body, TABLE1.d1)
    deepest = sim.x_front[np.argmin(sim.y_front)]
    assert 150.0 <= deepest <= 155.0


def test_decreasing_direction_mirrors_axles():
    """Running towards decreasing chainage puts the front axle d1 below the body centre."""
    sim = simulate(Track(200.0), speed=20.0, duration=1.0, start_chainage_m=150.0,
                   direction="decreasing")  # fmt: skip
    assert sim.x_front[0] == pytest.approx(150.0 - TABLE1.d1)
    assert sim.x_body[-1] < sim.x_body[0]


def test_window_matches_whole_rail_solution():
    """Solving only a window of rail around the axles changes levels by < 1e-5 of their range."""
    track = Track(150.0, zones=[SoftZone(80, 84, 0.4)])
    a = simulate(track, speed=25.0, duration=2.0, start_chainage_m=50.0, window_m=None)
    b = simulate(track, speed=25.0, duration=2.0, start_chainage_m=50.0)
    assert np.max(np.abs(a.accel - b.accel)) < 1e-5 * np.ptp(a.accel)
    assert np.max(np.abs(a.y_front - b.y_front)) < 1e-5 * np.ptp(a.y_front)


def test_matches_independent_implementation_on_sample():
    """Same inputs as sample_clean_exact: signals within 2 % of their range, levels too."""
    _, truth = sample("sample_clean_exact")
    track = Track(150.0, zones=[SoftZone(80, 84, 0.4)])
    sim = simulate(track, speed=25.0, duration=4.07, start_chainage_m=24.13)
    for ours, theirs in (
        (sim.accel, truth["acc_clean"]),
        (sim.pitch_rate, truth["pitch_rate_clean"]),
        (sim.y_front, truth["r1"]),
        (sim.y_rear, truth["r2"]),
    ):
        assert ours.shape == theirs.shape
        assert np.max(np.abs(ours - theirs)) < 0.02 * np.ptp(theirs)


def test_axle_leaving_track_is_an_error():
    """A duration that would run an axle off the end is refused with the span in the message."""
    with pytest.raises(ParameterError, match="leaves the track"):
        simulate(Track(100.0), speed=30.0, duration=5.0, start_chainage_m=20.0)


def test_room_to_run_is_one_rule_for_both_directions():
    """The leading (front) axle keeps END_MARGIN_M to the end in either direction; a start off
    the track, a rear axle off it or no room left are refused naming start_chainage_m."""
    from engine.simulate import END_MARGIN_M, room_to_run

    v = TABLE1
    assert room_to_run(500.0, 30.0, "increasing", v) == pytest.approx(
        500.0 - END_MARGIN_M - (30.0 + v.d1)
    )
    assert room_to_run(500.0, 470.0, "decreasing", v) == pytest.approx(470.0 - v.d1 - END_MARGIN_M)
    for start, direction in ((600.0, "increasing"), (0.5, "increasing"), (499.0, "increasing")):
        with pytest.raises(ParameterError) as err:
            room_to_run(500.0, start, direction, v)
        assert err.value.field == "start_chainage_m"
