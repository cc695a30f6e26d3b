"""Whole-vehicle plausibility (engine.vehicle_plausibility): derived quantities in range, the
reason in the message, a registry other vehicle kinds can join; the result bound."""

from __future__ import annotations

import math

import numpy as np
import pytest

from engine.pipeline import process_run
from engine.setup import RunSetup, prepare_run
from engine.synthetic import REALISTIC_SENSOR, make_run
from engine.track import SoftZone, TrackParams
from engine.vehicle import GRAVITY, PRESETS, TABLE1
from engine.vehicle_plausibility import (
    KINDS,
    RANGES,
    ImplausibleResult,
    VehicleImplausible,
    VehicleKind,
    check_result,
    check_vehicle,
    implausibilities,
    result_bound_mm,
    vehicle_quantities,
)


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_presets_are_plausible(name: str) -> None:
    """Every preset passes every check (a check refusing them would refuse real vehicles)."""
    assert implausibilities(PRESETS[name]) == []


def test_table1_quantities_by_hand() -> None:
    """The derived quantities of Table 1, computed here from their definitions."""
    q = vehicle_quantities(TABLE1)
    assert q["gyration_ratio"] == pytest.approx(math.sqrt(111193.0 / 16200.0) / 4.13)
    k1 = 0.4e6 * 1.75e6 / (0.4e6 + 1.75e6)
    k2 = 1.0e6 * 3.5e6 / (1.0e6 + 3.5e6)
    assert q["bounce_hz"] == pytest.approx(math.sqrt((k1 + k2) / 16200.0) / (2 * math.pi))
    assert q["axle_hop_front_hz"] == pytest.approx(math.sqrt(2.15e6 / 700.0) / (2 * math.pi))
    assert q["deflection_front_mm"] == pytest.approx(1e3 * 16200.0 * GRAVITY / 2 / 0.4e6)
    assert q["wheel_load_rear_kn"] == pytest.approx((16200.0 / 2 + 1100.0) * GRAVITY / 1e3)


def test_light_body_with_huge_inertia_is_refused_naming_the_quantity() -> None:
    """ms 500 kg with Is 1e8 kg m² (a radius of gyration of 447 m): each value is in its
    own range, the vehicle is not; the message names the quantity, its range and why."""
    vp = TABLE1.replace(ms=500.0, Is=1e8)
    with pytest.raises(VehicleImplausible) as err:
        check_vehicle(vp)
    assert err.value.quantity == "gyration_ratio"
    assert err.value.field == "params"
    msg = str(err.value)
    assert "radius of gyration" in msg and "pitch natural frequency" in msg
    assert "0.3 to 2" in msg and "Is, ms" in msg


@pytest.mark.parametrize(
    ("changes", "quantity"),
    [
        ({"kt1": 3e4, "kt2": 3e4}, "bounce_hz"),
        ({"mu1": 2e4}, "axle_hop_front_hz"),
        ({"ks1": 1e9}, "deflection_front_mm"),
        ({"ks2": 1e4}, "deflection_rear_mm"),
        ({"ms": 60000.0, "Is": 4e5, "ks1": 4e6, "ks2": 4e6}, "wheel_load_front_kn"),
        ({"Is": 1e4}, "gyration_ratio"),
    ],
)
def test_each_check_catches_its_quantity(changes: dict[str, float], quantity: str) -> None:
    """A vehicle off in one respect is refused by that quantity's check."""
    found = [f.quantity for f in implausibilities(TABLE1.replace(**changes))]
    assert quantity in found


def test_a_new_vehicle_kind_provides_its_own_quantities() -> None:
    """A kind registered in KINDS is judged by the shared ranges from its own quantities."""
    KINDS["test_kind"] = VehicleKind(lambda v: {"bounce_hz": v}, {"bounce_hz": ("k",)})
    try:
        assert implausibilities(1.0, "test_kind") == []
        (f,) = implausibilities(50.0, "test_kind")
        assert f.quantity == "bounce_hz" and f.range is RANGES["bounce_hz"]
    finally:
        del KINDS["test_kind"]


def test_result_bound_from_the_track_model() -> None:
    """The bound is the margin times geometry plus the Winkler deflection under twice the
    heavier wheel load on 90 %-softened supports (about 67 mm for Table 1)."""
    trk = TrackParams()
    w = trk.winkler_deflection(2 * max(TABLE1.static_axle_loads()), 0.1)
    assert result_bound_mm(TABLE1, trk) == pytest.approx(2 * (28.0 + 1e3 * w))
    assert 60 < result_bound_mm(TABLE1, trk) < 75
    level = np.zeros(100)
    check_result(level, level, [0.4], TABLE1, trk)  # a real soft spot passes
    with pytest.raises(ImplausibleResult, match="dip is 120.0 mm"):
        check_result(level, level, [120.0], TABLE1, trk)
    level[50] = -90.0
    with pytest.raises(ImplausibleResult, match="deviates from its baseline by 90.0 mm"):
        check_result(level, level * 0, [], TABLE1, trk)


def test_wrong_vehicle_inversion_fails_instead_of_inventing_dips() -> None:
    """The issue's vehicle (ms 500, Is 1e8) inverts a run with one 0.3 mm soft spot into
    levels hundreds of mm deep: process_run raises ImplausibleResult; the right vehicle passes."""
    run = make_run(length=160.0, zones=[SoftZone(70.0, 75.0, 0.5)], speed=25.0,
                   start_chainage_m=12.0, jitter=0.03, sensor=REALISTIC_SENSOR, seed=3)  # fmt: skip
    ok = process_run(prepare_run(run.log, RunSetup(start_chainage_m=12.0, vehicle=TABLE1)))
    assert len(ok.soft_spots) == 1
    with pytest.raises(ImplausibleResult, match="not physically plausible"):
        process_run(
            prepare_run(
                run.log, RunSetup(start_chainage_m=12.0, vehicle=TABLE1.replace(ms=500.0, Is=1e8))
            )
        )
