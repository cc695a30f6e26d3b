"""A bogie coach on smooth rail in a configuration unlike the peer's runs: every zone found
with both ends within 1.5 m and the loss within 10 points, no false zone; and the detection
limit a bogie vehicle's pass states is that of its two wheels."""

from __future__ import annotations

import pytest

from engine.bogie import PASSENGER_COACH
from engine.pipeline import process_run
from engine.sensor import SensorModel
from engine.setup import RunSetup, prepare_run
from engine.synthetic import make_run
from engine.track import SoftZone
from engine.visibility import detection_limit

TOL_M = 1.5
"""Zone end tolerance, m (the peer README's section 5)."""


@pytest.mark.slow
def test_unseen_coach_on_smooth_rail_finds_every_zone() -> None:
    """A coach 10 % off its registered preset, at 36 m/s (the peer ran 28), over a short
    zone (3.6 m, 50 %) and a long one (9.6 m, 40 %) on supports scattered 5 %, simulated at
    2 kHz and written at 1 kHz with 10 digits (as the peer's logs); processed with the
    registered preset. (A 3 m zone of 35 % or a 9.6 m one of 30 % dips 0.059 mm here, under
    the detector's 0.06 mm floor: docs/accuracy.md.)"""
    true = PASSENGER_COACH.replace(
        body_mass_kg=PASSENGER_COACH.body_mass_kg * 1.1,
        body_pitch_inertia_kgm2=PASSENGER_COACH.body_pitch_inertia_kgm2 * 0.9,
        secondary_k_n_per_m=PASSENGER_COACH.secondary_k_n_per_m * 1.1,
        secondary_c_ns_per_m=PASSENGER_COACH.secondary_c_ns_per_m * 0.9,
        primary_k_n_per_m=PASSENGER_COACH.primary_k_n_per_m * 0.9,
        bogie_mass_kg=PASSENGER_COACH.bogie_mass_kg * 1.1,
    )
    zones = (SoftZone(90.0, 93.6, 0.5), SoftZone(150.0, 159.6, 0.4))
    run = make_run(
        length=230.0, zones=zones, speed=36.0, start_chainage_m=30.0, jitter=0.05,
        sensor=SensorModel(sample_rate_hz=1000.0, digits=10), sim_rate_hz=2000.0, seed=3,
        vehicle=true,
    )  # fmt: skip
    res = process_run(
        prepare_run(run.log, RunSetup(start_chainage_m=30.0, vehicle=PASSENGER_COACH))
    )
    assert res.geometry_check.smooth
    false = [
        s
        for s in res.soft_spots
        if not any(s.start_m <= z.end_m + TOL_M and s.end_m >= z.start_m - TOL_M for z in zones)
    ]
    assert not false
    for z in zones:
        hits = [s for s in res.soft_spots if s.start_m <= z.end_m and s.end_m >= z.start_m]
        assert len(hits) == 1, z
        assert abs(hits[0].start_m - z.start_m) <= TOL_M
        assert abs(hits[0].end_m - z.end_m) <= TOL_M
        assert abs(hits[0].stiffness_loss_pct - 100 * z.loss) <= 10.0


def test_detection_limit_of_a_bogie_is_that_of_its_two_wheels() -> None:
    """A bogie's profile is the mean level under its two wheels 2.6 m apart, which smooths a
    short zone's dip: at the detector's 0.06 mm floor a 3 m zone needs about 42 % under the
    coach's bogie (one 46 kN wheel would show 23 %); measured on the engine's own coach run, a
    3 m zone of 35 % dipped 0.059 mm and was not found. Long zones barely differ."""
    band = dict(load=46107.0, lambda_min_m=3.0, lambda_max_m=40.0, taper=0.3, step_m=0.25,
                baseline_window_m=40.0)  # fmt: skip
    one = detection_limit(0.06, zone_lengths_m=(3.0, 9.6), **band)
    bogie = detection_limit(0.06, zone_lengths_m=(3.0, 9.6), wheel_offsets_m=(1.3, -1.3), **band)
    assert one.min_loss_pct[0] < 30.0 < 35.0 < bogie.min_loss_pct[0]
    assert abs(bogie.min_loss_pct[1] - one.min_loss_pct[1]) < 5.0
