"""The bogie vehicle kind: equations, static loads, frequencies, the half-car limit, the
forward model with every wheel on the rail."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import solveh_banded

from engine.beam import BANDWIDTH, hermite_shape
from engine.bogie import FREIGHT_WAGON, PASSENGER_COACH, BogieParams
from engine.chainage import bandpass_distance
from engine.errors import ParameterError
from engine.pipeline import ProcessConfig, process_run
from engine.setup import RunSetup, prepare_run
from engine.simulate import simulate
from engine.spectral import vehicle_response
from engine.stiffness import QuasiStaticModel
from engine.synthetic import SyntheticRun, make_run
from engine.track import SoftZone, Track, TrackParams
from engine.vehicle import GRAVITY, VehicleParams
from engine.vehicle_kinds import VEHICLE_KINDS, vehicle_from_dict
from engine.wheel_force import force_response


@pytest.mark.parametrize("vehicle", [PASSENGER_COACH, FREIGHT_WAGON])
def test_static_wheel_loads_carry_the_weight(vehicle: BogieParams) -> None:
    """Both rails' wheel loads add up to the vehicle's weight, and K q = gravity gives them."""
    loads = vehicle.static_wheel_loads()
    total = vehicle.body_mass_kg + 2 * vehicle.bogie_mass_kg + 4 * vehicle.wheelset_mass_kg
    assert 2 * loads.sum() == pytest.approx(total * GRAVITY, rel=1e-12)
    # static equilibrium of the vehicle on a rigid, level rail: contact forces from K q = f
    _, _, K = vehicle.matrices()
    q = np.linalg.solve(K, vehicle.gravity_load())
    contact = -vehicle.contact_k * q[vehicle.contact_dofs]
    np.testing.assert_allclose(contact, loads, rtol=1e-9)
    assert sum(vehicle.static_axle_loads()) == pytest.approx(loads.sum())


def test_peer_coach_wheel_load() -> None:
    """The coach preset's wheel load is the hand value m_c g/4 + m_b g/2 + m_w g (per rail)."""
    v = PASSENGER_COACH
    hand = GRAVITY * (v.body_mass_kg / 8 + v.bogie_mass_kg / 4 + v.wheelset_mass_kg / 2)
    assert v.static_wheel_loads()[0] == pytest.approx(hand)
    assert hand == pytest.approx(46107.0, abs=1.0)


@pytest.mark.parametrize("vehicle", [PASSENGER_COACH, FREIGHT_WAGON])
def test_natural_frequencies_match_hand_formulas(vehicle: BogieParams) -> None:
    """The model's lowest modes are the hand formulas' body bounce, body pitch and bogie pitch.

    Body bounce sqrt(2 k_s,eq / m_c) and pitch sqrt(2 k_s,eq L² / I_c) with k_s,eq the
    secondary in series with the two primaries (bogie mass neglected: within 3 %); bogie
    pitch sqrt(2 k_p a² / I_b) with the wheels held by the stiff contact (within 1 %).
    """
    d = vehicle.derived()
    modes = [d[f"mode_{i}_hz"] for i in range(1, 5)]
    M, _, K = vehicle.matrices()
    f = np.sort(np.sqrt(np.linalg.eigvals(np.linalg.solve(M, K)).real)) / (2 * np.pi)
    assert min(abs(m - d["body_bounce_hz"]) / d["body_bounce_hz"] for m in modes) < 0.03
    assert min(abs(m - d["body_pitch_hz"]) / d["body_pitch_hz"] for m in modes) < 0.05
    assert np.min(np.abs(f - d["bogie_pitch_hz"])) / d["bogie_pitch_hz"] < 0.01
    m_c = vehicle.body_mass_kg / 2
    ks, kp = vehicle.secondary_k_n_per_m, vehicle.primary_k_n_per_m
    assert d["body_bounce_hz"] == pytest.approx(
        np.sqrt(2 * (ks * 2 * kp / (ks + 2 * kp)) / m_c) / (2 * np.pi)
    )


def _lumped_half_car(b: BogieParams) -> VehicleParams:
    """The half car a bogie vehicle becomes with a rigid primary and a zero wheelbase."""
    mu = b.bogie_mass_kg / 2 + b.wheelset_mass_kg
    return VehicleParams(
        ms=b.body_mass_kg / 2, Is=b.body_pitch_inertia_kgm2 / 2, mu1=mu, mu2=mu,
        ks1=b.secondary_k_n_per_m, ks2=b.secondary_k_n_per_m, cs1=b.secondary_c_ns_per_m,
        cs2=b.secondary_c_ns_per_m, kt1=2 * b.contact_k_n_per_m, kt2=2 * b.contact_k_n_per_m,
        d1=b.bogie_half_spacing_m, d2=b.bogie_half_spacing_m, sensor_x_m=b.sensor_x_m,
    )  # fmt: skip


def test_rigid_primary_limit_is_the_half_car() -> None:
    """With a rigid primary a bogie is one lumped axle: the same body response to the bogie
    level, the same wheel forces, the same static axle loads as the lumped half car."""
    b = PASSENGER_COACH.replace(primary_k_n_per_m=1e10, sensor_x_m=2.0)
    h = _lumped_half_car(b)
    # the inversion's band (0.2-20 Hz); the primary (1e10 N/m) in series with the contact
    # (1e9 N/m) still shifts the wheel-hop mode near 150 Hz: off by ~1e-3 of the response
    w = 2 * np.pi * np.geomspace(0.2, 20.0, 200)
    Hb, Hh = vehicle_response(b, w), vehicle_response(h, w)
    assert np.max(np.abs(Hb - Hh) / np.abs(Hh)) < 2e-3
    Gb, Gh = force_response(b, w), force_response(h, w)
    assert np.max(np.abs(Gb - Gh)) < 2e-3 * np.max(np.abs(Gh))
    np.testing.assert_allclose(b.static_axle_loads(), h.static_axle_loads(), rtol=1e-12)
    # and the primary matters when it is not rigid (the test can tell them apart)
    Hc = vehicle_response(PASSENGER_COACH.replace(sensor_x_m=2.0), w)
    assert np.max(np.abs(Hc - Hh) / np.abs(Hh)) > 0.1


def test_body_sees_only_the_bogie_mean_level() -> None:
    """Antisymmetric wheel levels within a bogie (pitching it) leave the body at rest."""
    v = FREIGHT_WAGON
    M, C, K = v.matrices()
    w = 2 * np.pi * 3.0
    Z = K + 1j * w * C - w**2 * M
    f = np.zeros(10)
    f[6], f[7] = v.contact_k_n_per_m, -v.contact_k_n_per_m  # +1 m front wheel, -1 m rear
    x = np.linalg.solve(Z, f)
    assert np.max(np.abs(x[:3])) < 1e-12 * np.max(np.abs(x))
    assert abs(x[3]) > 1e-3  # the frame pitches


def test_registry_and_parameters() -> None:
    """Kinds are looked up by name; bad values name their field; round trip through dicts."""
    assert set(VEHICLE_KINDS) >= {"half_car", "bogie"}
    assert vehicle_from_dict(PASSENGER_COACH.to_dict()) == PASSENGER_COACH
    assert vehicle_from_dict({"ms": 15000.0}) == VehicleParams(ms=15000.0)
    with pytest.raises(ParameterError, match="unknown vehicle kind") as e:
        vehicle_from_dict({"kind": "tram"})
    assert e.value.field == "kind"
    with pytest.raises(ParameterError) as e:
        BogieParams(wheelbase_m=-2.0)
    assert e.value.field == "wheelbase_m"
    with pytest.raises(ParameterError, match="shorter than the bogie centre distance"):
        BogieParams(bogie_half_spacing_m=1.2, wheelbase_m=2.6)
    with pytest.raises(ParameterError, match="unknown bogie-vehicle parameter"):
        BogieParams.from_dict({"ms": 1.0})


def test_forward_model_puts_every_wheel_on_the_rail() -> None:
    """At the static start the rail under each wheel sits where the superposed static
    deflection basins of all four wheel loads put it (beam on discrete supports), and the
    contact forces are the static wheel loads: the bogie's two wheels act at their own
    positions, not as one load at the bogie centre."""
    params = TrackParams()
    track = Track(120.0, params=params)
    v = FREIGHT_WAGON
    res = simulate(track, vehicle=v, speed=20.0, duration=0.05, start_chainage_m=50.0)
    assert res.y_wheels is not None and res.contact_wheels is not None
    assert res.x_wheels is not None
    xw = res.x_wheels[:, 0]
    P = v.static_wheel_loads()
    expected = np.array(
        [-sum(P[j] * _green(params, xw[k], xw[j]) for j in range(4)) for k in range(4)]
    )
    np.testing.assert_allclose(res.y_wheels[:, 0], expected, rtol=2e-3)
    np.testing.assert_allclose(res.contact_wheels[:, 0], P, rtol=1e-6)
    # one bogie-centre load instead would put the bogie's level elsewhere: the test can fail
    one_load = -2 * P[0] * _green(params, 0.5 * (xw[0] + xw[1]), 0.5 * (xw[0] + xw[1]))
    assert abs(one_load - res.y_front[0]) > 0.05 * abs(res.y_front[0])


def _green(params: TrackParams, x: float, x_load: float) -> float:
    """Static deflection at ``x`` under a unit load at ``x_load`` on a long nominal rail, m/N."""
    model = QuasiStaticModel(params, x_load - 5, x_load + 5, np.array([x_load]), 1.0)
    band = model.band_beam.copy()
    band[BANDWIDTH, 0::2] += params.k_nominal
    W = solveh_banded(band, model.rhs, lower=False)[:, 0]
    s = params.spacing
    e = int(np.floor((x - model.node_x[0]) / s))
    sh = hermite_shape(np.array([(x - model.node_x[0]) / s - e]), s)[0]
    return float(sh @ W[2 * e : 2 * e + 4])


@pytest.fixture(scope="module")
def coach_run() -> SyntheticRun:
    """A coach over two soft zones on smooth rail (exact 1 kHz output, registered vehicle)."""
    zones = (SoftZone(100.2, 104.4, 0.55), SoftZone(160.2, 166.8, 0.4))
    return make_run(length=240.0, zones=zones, speed=28.0, start_chainage_m=30.0,
                    vehicle=PASSENGER_COACH)  # fmt: skip


@pytest.mark.slow
def test_bogie_run_gives_the_bogie_mean_level_and_its_zones(coach_run: SyntheticRun) -> None:
    """The spectral inversion of a bogie vehicle's body signals returns the mean level under
    each bogie's wheels, and the fit with both wheel loads finds each zone (ends within half
    a bay of the reported convention, loss within 5 points)."""
    res = process_run(
        prepare_run(coach_run.log, RunSetup(start_chainage_m=30.0, vehicle=PASSENGER_COACH))
    )
    truth = bandpass_distance(coach_run.true_profile(res.chainage_m), 0.25, 3.0, 40.0)
    ok = np.isfinite(truth) & np.isfinite(res.level_mm)
    ok[:200] = ok[-200:] = False  # the band-pass's ends
    assert np.sqrt(np.mean((res.level_mm[ok] - truth[ok]) ** 2)) < 0.1 * np.std(truth[ok])
    assert len(res.soft_spots) == 2
    for spot, zone in zip(res.soft_spots, coach_run.zones, strict=True):
        assert abs(spot.start_m - zone.start_m) <= 0.61
        assert abs(spot.end_m - zone.end_m) <= 0.61
        assert abs(spot.stiffness_loss_pct - 100 * zone.loss) <= 5.0


@pytest.mark.slow
def test_half_car_only_methods_refuse_a_bogie_vehicle(coach_run: SyntheticRun) -> None:
    """The paper's recursion is the half car's algebra: a bogie vehicle gets a clear error."""
    with pytest.raises(ParameterError, match="needs a half-car vehicle") as e:
        process_run(
            prepare_run(
                coach_run.log,
                RunSetup(
                    start_chainage_m=30.0,
                    vehicle=PASSENGER_COACH,
                    config=ProcessConfig(method="direct"),
                ),
            )
        )
    assert e.value.field == "method"


@pytest.mark.slow
def test_agreement_indicator_is_not_the_band_pass_ends() -> None:
    """On rough rail the front and rear bogies' true levels agree (same rail), and so does
    the indicator: it leaves out the common stretch's ends, where one profile's band-pass
    edge effect alone reads millimetres."""
    run = make_run(length=300.0, speed=28.0, start_chainage_m=30.0, vehicle=PASSENGER_COACH,
                   irregularity="german-low", seed=4)  # fmt: skip
    res = process_run(
        prepare_run(run.log, RunSetup(start_chainage_m=30.0, vehicle=PASSENGER_COACH))
    )
    f, r = res.front_level_mm, res.rear_level_mm
    both = np.isfinite(f) & np.isfinite(r)
    whole = float(np.sqrt(np.mean((f[both] - r[both]) ** 2)))
    truth = run.true_profile(res.chainage_m)
    assert res.quality.axle_agreement_mm < 0.5 * whole
    assert res.quality.axle_agreement_mm < 0.1 * np.nanstd(truth)
