"""Calibration of a bogie vehicle from its own runs: the kind's own quantities.

Runs come from the engine's forward model driven by a coach that is NOT the registered
passenger-coach preset (body pitch inertia +30 %, secondary -25 %), over German-low rail with
5 % support scatter, realistic sensor at 500 Hz from a 1 kHz simulation (fixed seeds).
"""

from __future__ import annotations

import dataclasses

import pytest

from engine.bogie import PASSENGER_COACH
from engine.calibration import CalibrationConfig, CalibrationRun, calibrate, held_vehicle
from engine.errors import ParameterError
from engine.synthetic import REALISTIC_SENSOR, make_run
from engine.track import SoftZone
from engine.vehicle import TABLE1

COACH = PASSENGER_COACH
REAL = COACH.replace(
    body_pitch_inertia_kgm2=COACH.body_pitch_inertia_kgm2 * 1.3,
    secondary_k_n_per_m=COACH.secondary_k_n_per_m * 0.75,
)
SENSOR = dataclasses.replace(REALISTIC_SENSOR, sample_rate_hz=500.0)


@pytest.mark.slow
def test_a_bogie_coach_is_calibrated_to_its_true_pitch_inertia_and_secondary():
    """Two runs: pitch inertia and secondary stiffness (over the held body mass) within
    ±10 % of the truth, both significant; the front/rear disagreement drops. The registered
    values are 30 % and 25 % off, so the test fails without a working fit."""
    runs = [
        make_run(length=400.0, zones=[SoftZone(120, 125, 0.5)], irregularity="german-low",
                 speed=v, sensor=SENSOR, sim_rate_hz=1000.0, jitter=0.05, seed=300 + i,
                 vehicle=REAL)
        for i, v in enumerate((22.0, 30.0))
    ]  # fmt: skip
    res = calibrate(
        [CalibrationRun(r.log, r.start_chainage_m, r.direction, f"run {i}")
         for i, r in enumerate(runs)],
        COACH,
    )  # fmt: skip
    p = res.params
    assert res.significant, res.message
    assert p.kind == "bogie" and p.body_mass_kg == COACH.body_mass_kg
    assert [f.name for f in res.fitted] == ["Is", "ks"]
    assert all(f.identified and f.significant for f in res.fitted)
    got = p.body_pitch_inertia_kgm2 / REAL.body_pitch_inertia_kgm2
    assert abs(got - 1) <= 0.10, res.message
    assert abs(p.secondary_k_n_per_m / REAL.secondary_k_n_per_m - 1) <= 0.10, res.message
    assert res.objective_after < 0.7 * res.objective_before


def test_a_bogie_vehicle_is_asked_for_its_own_quantities():
    """ks1/ks2 are the half car's: on a bogie vehicle an error naming fit and what it has;
    the defaults differ per kind; a load figure sets the bogie body (inertia scaled)."""
    cfg = CalibrationConfig(fit=("Is", "ks1"))
    with pytest.raises(ParameterError, match=r"cannot fit \['ks1'\] on a bogie") as e:
        cfg.fit_for("bogie")
    assert e.value.field == "fit" and "kp" in str(e.value)
    assert CalibrationConfig().fit_for("bogie") == ("Is", "ks")
    assert CalibrationConfig().fit_for("half_car") == ("Is", "ks1", "ks2")
    with pytest.raises(ParameterError, match=r"cannot fit \['kp'\] on a half_car"):
        CalibrationConfig(fit=("kp",)).fit_for("half_car")
    held = held_vehicle(COACH, 15000.0)
    assert held.body_mass_kg == 30000.0
    ratio = held.body_pitch_inertia_kgm2 / COACH.body_pitch_inertia_kgm2
    assert ratio == pytest.approx(30000.0 / COACH.body_mass_kg)
    assert held_vehicle(TABLE1, 9000.0) == TABLE1.replace(ms=9000.0)
