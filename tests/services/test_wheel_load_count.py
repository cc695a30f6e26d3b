"""The register's distinct wheel loads are counted per wheel, whatever the vehicle kind.

A bogie vehicle's measured point (a bogie centre) carries two wheels, a half car's (an axle)
one: a run's stored wheel force and a separated spot's support are the force per wheel, so a
coach and a half car of the same wheel load are one load, and loads the separation's
threshold apart are two.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from app.services.run_lifecycle.processing import invert, mean_wheel_load
from app.services.track.register import LOAD_RATIO
from app.services.track.separation_store import PassLevels, _support
from engine.bogie import PASSENGER_COACH
from engine.register import count_loads
from engine.setup import RunSetup, prepare_run
from engine.synthetic import REALISTIC_SENSOR, make_run, make_track
from engine.vehicle import GRAVITY, TABLE1
from engine.vehicle_kinds import Vehicle

COACH_WHEEL_N = float(np.mean(PASSENGER_COACH.static_wheel_loads()))


def _half_car(wheel_load_n: float) -> Vehicle:
    """Table 1's half car with the body mass that gives it this mean static wheel load, N."""
    axles = 0.5 * (TABLE1.mu1 + TABLE1.mu2) * GRAVITY
    return TABLE1.with_body_mass(2.0 * (wheel_load_n - axles) / GRAVITY)


def _coach(wheel_load_n: float) -> Vehicle:
    """The passenger coach with the body mass that gives it this static wheel load, N."""
    rest = COACH_WHEEL_N - 0.25 * PASSENGER_COACH.ms * GRAVITY  # a quarter of the body each
    return PASSENGER_COACH.with_body_mass(4.0 * (wheel_load_n - rest) / GRAVITY)


@pytest.fixture(scope="module")
def stored_loads() -> dict[str, float]:
    """The per-wheel mean force the run store keeps for three noisy runs over one rough
    track (+-5 % support scatter, start chainage 0.8 m off): a half car and a coach of the
    coach's wheel load, and a coach 12 % heavier per wheel."""
    sensor = dataclasses.replace(REALISTIC_SENSOR, sample_rate_hz=500.0)
    track = make_track(200.0, jitter=0.05, irregularity="german-low", seed=41)
    out = {}
    for name, vehicle in (
        ("half car", _half_car(COACH_WHEEL_N)),
        ("coach", _coach(COACH_WHEEL_N)),
        ("heavier coach", _coach(1.12 * COACH_WHEEL_N)),
    ):
        run = make_run(track=track, vehicle=vehicle, speed=25.0, sensor=sensor, seed=7,
                       sim_rate_hz=500.0, start_chainage_m=15.0, start_error_m=0.8)  # fmt: skip
        prepared = prepare_run(
            run.log, RunSetup(start_chainage_m=run.logged_start_chainage_m, vehicle=vehicle)
        )
        load = mean_wheel_load(invert(prepared))
        assert load is not None
        out[name] = load
    return out


@pytest.mark.slow
def test_a_run_keeps_its_force_per_wheel(stored_loads):
    """The processed run's wheel force, shared by its point's wheels, is its static wheel
    load within 2 % for both kinds (the coach's point force is twice that)."""
    assert stored_loads["half car"] == pytest.approx(COACH_WHEEL_N, rel=0.02)
    assert stored_loads["coach"] == pytest.approx(COACH_WHEEL_N, rel=0.02)
    assert stored_loads["heavier coach"] == pytest.approx(1.12 * COACH_WHEEL_N, rel=0.02)


@pytest.mark.slow
def test_half_car_and_coach_of_one_wheel_load_are_one_load(stored_loads):
    """Same wheel load, different kinds: one load; 12 % apart (threshold 10 %): two."""
    assert count_loads([stored_loads["half car"], stored_loads["coach"]], LOAD_RATIO) == 1
    assert count_loads([stored_loads["half car"], stored_loads["heavier coach"]], LOAD_RATIO) == 2


def test_separated_support_is_per_wheel():
    """A separated spot's support names each pass with its force per wheel: a half car's
    axle at W and a bogie centre at 2 W are one load; a bogie centre at 2.22 W is a second."""
    grid = np.arange(0.0, 20.0, 0.25)
    w = 50e3

    def support(bogie_point_n: float) -> list[float]:
        passes = [
            PassLevels("run", 1, np.zeros(grid.size), np.full(grid.size, w), (0.0,)),
            PassLevels("run", 2, np.zeros(grid.size), np.full(grid.size, bogie_point_n),
                       (1.3, -1.3)),
        ]  # fmt: skip
        return [e["force_n"] for e in _support(passes, grid, 5.0, 10.0)]

    assert support(2 * w) == [pytest.approx(w), pytest.approx(w)]
    assert count_loads(support(2 * w), LOAD_RATIO) == 1
    assert count_loads(support(2.22 * w), LOAD_RATIO) == 2
