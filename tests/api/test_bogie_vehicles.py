"""Bogie vehicles through the service: registered as the datasheet gives them, presets,
edits and versions, runs simulated and uploaded with them processed to their soft zones."""

from __future__ import annotations

import io

import pytest

from api.api_support import row_counts, upload, wait_done
from engine.bogie import FREIGHT_WAGON, PASSENGER_COACH

COACH = PASSENGER_COACH.to_dict()


def test_a_bogie_vehicle_is_registered_as_its_datasheet_gives_it(client) -> None:
    """POST with kind bogie stores the whole-vehicle values; GET and the versions show them;
    an edit makes version 2 of the same kind."""
    r = client.post("/api/v1/vehicles", json={"name": "coach-1", "params": COACH})
    assert r.status_code == 201, r.text
    assert r.json()["params"] == COACH
    got = client.get("/api/v1/vehicles/coach-1").json()
    assert got["params"]["kind"] == "bogie"
    assert got["params"]["wheelbase_m"] == COACH["wheelbase_m"]
    r = client.patch("/api/v1/vehicles/coach-1", json={"params": {"body_mass_kg": 30000.0}})
    assert r.status_code == 200, r.text
    assert r.json()["version"] == 2
    assert r.json()["params"] == COACH | {"body_mass_kg": 30000.0}
    versions = client.get("/api/v1/vehicles/coach-1/versions").json()["data"]
    assert [v["params"]["kind"] for v in versions] == ["bogie", "bogie"]


@pytest.mark.parametrize(
    ("name", "value"),
    [("wheelbase_m", -2.6), ("contact_k_n_per_m", 1e30), ("body_mass_kg", 1e-3)],
)
def test_a_bad_bogie_parameter_is_422_naming_it(client, settings, name, value) -> None:
    """A value outside its physical range is refused naming the parameter; nothing stored."""
    before = row_counts(settings)
    r = client.post("/api/v1/vehicles", json={"name": "c", "params": COACH | {name: value}})
    assert r.status_code == 422, r.text
    assert r.json()["detail"]["field"] == f"params.{name}"
    assert row_counts(settings) == before


def test_bogie_cross_check_and_unknown_kind(client, settings) -> None:
    """A wheelbase longer than the bogie distance, and an unknown kind, are 422s."""
    before = row_counts(settings)
    r = client.post(
        "/api/v1/vehicles",
        json={"name": "c", "params": COACH | {"bogie_half_spacing_m": 1.2}},
    )
    assert r.status_code == 422, r.text
    assert "wheelbase_m" in r.json()["detail"]["field"]
    r = client.post("/api/v1/vehicles", json={"name": "c", "params": {"kind": "tram"}})
    assert r.status_code == 422, r.text
    assert row_counts(settings) == before


def test_bogie_presets(client) -> None:
    """The coach and wagon presets are listed and make vehicles; a half-car preset still
    makes a half car."""
    presets = client.get("/api/v1/vehicles/presets").json()
    assert presets["passenger_coach"] == COACH
    assert presets["freight_wagon"] == FREIGHT_WAGON.to_dict()
    assert "kind" in presets["table1"] and presets["table1"]["kind"] == "half_car"
    r = client.post("/api/v1/vehicles", json={"name": "w", "preset": "freight_wagon"})
    assert r.status_code == 201, r.text
    assert r.json()["params"] == FREIGHT_WAGON.to_dict()
    r = client.post(
        "/api/v1/vehicles",
        json={"name": "w2", "preset": "freight_wagon",
              "params": {"kind": "bogie", "body_mass_kg": 60000.0}},
    )  # fmt: skip
    assert r.status_code == 201, r.text
    assert r.json()["params"]["body_mass_kg"] == 60000.0
    assert r.json()["params"]["wheelbase_m"] == FREIGHT_WAGON.wheelbase_m


def test_calibrating_a_bogie_vehicle_asks_for_its_own_quantities(client, settings) -> None:
    """A bogie vehicle is calibrated with its kind's quantities: ks1 (its bogies share one
    secondary) is a 422 naming fit and saying what it has; with no run to calibrate from, a
    422 naming run_ids; nothing stored either way."""
    client.post("/api/v1/vehicles", json={"name": "coach-1", "params": COACH})
    before = row_counts(settings)
    r = client.post("/api/v1/vehicles/coach-1/calibrate", json={"fit": ["Is", "ks1"]})
    assert r.status_code == 422, r.text
    assert r.json()["detail"]["field"] == "fit"
    assert "ks1" in r.json()["detail"]["message"] and "kp" in r.json()["detail"]["message"]
    r = client.post("/api/v1/vehicles/coach-1/calibrate", json={})
    assert r.status_code == 422, r.text
    assert r.json()["detail"]["field"] == "run_ids"
    assert row_counts(settings) == before


@pytest.mark.slow
def test_runs_of_a_bogie_vehicle_are_processed(client) -> None:
    """A run simulated with the coach, and the same kind of log uploaded, are processed with
    the coach's model: the soft zone is found within 1.5 m."""
    from engine.logio import write_run_csv
    from engine.synthetic import make_run
    from engine.track import SoftZone

    client.post("/api/v1/vehicles", json={"name": "coach-1", "params": COACH})
    r = client.post(
        "/api/v1/simulate",
        json={"vehicle": "coach-1", "length_m": 200.0, "speed_mps": 28.0, "sensor": "ideal",
              "zones": [{"start_m": 100.2, "end_m": 105.0, "loss": 0.55}],
              "start_chainage_m": 30.0},
    )  # fmt: skip
    assert r.status_code in (200, 201, 202), r.text
    run = wait_done(client, r.json()["run"]["id"])
    assert run["status"] == "done", run
    spots = client.get(f"/api/v1/runs/{run['id']}/soft-spots").json()
    spots = spots["data"] if isinstance(spots, dict) else spots
    assert len(spots) == 1, spots
    assert abs(spots[0]["start_m"] - 100.2) <= 1.5 and abs(spots[0]["end_m"] - 105.0) <= 1.5

    syn = make_run(length=200.0, zones=(SoftZone(120.0, 124.2, 0.5),), speed=25.0,
                   start_chainage_m=30.0, vehicle=PASSENGER_COACH)  # fmt: skip
    buf = io.StringIO()
    write_run_csv(syn.log, buf)
    r = upload(client, buf.getvalue().encode(), vehicle="coach-1", start_chainage_m=30.0,
               track="L-up")  # fmt: skip
    assert r.status_code in (200, 201, 202), r.text
    run = wait_done(client, r.json()["id"])
    assert run["status"] == "done", run
    spots = client.get(f"/api/v1/runs/{run['id']}/soft-spots").json()
    spots = spots["data"] if isinstance(spots, dict) else spots
    assert len(spots) == 1, spots
    assert abs(spots[0]["start_m"] - 120.0) <= 1.5 and abs(spots[0]["end_m"] - 124.2) <= 1.5


def test_a_declared_wheel_load_sets_a_bogie_vehicles_body_mass() -> None:
    """A run's static wheel load is per wheel for any kind: the coach at its own wheel load
    is the coach; 10 % more per wheel is carried by the body alone (four wheels per rail);
    a payload is on the whole vehicle, as the datasheet's body mass is."""
    from app.services.errors import Invalid
    from app.services.vehicles.loads import loaded_vehicle
    from engine.vehicle import GRAVITY

    coach = PASSENGER_COACH
    wheel = float(coach.static_wheel_loads()[0])
    same = loaded_vehicle(coach, static_wheel_load_n=wheel)
    assert same.body_mass_kg == pytest.approx(coach.body_mass_kg)
    heavier = loaded_vehicle(coach, static_wheel_load_n=1.1 * wheel)
    extra = 2 * 4 * 0.1 * wheel / GRAVITY  # two rails of four wheels
    assert heavier.body_mass_kg == pytest.approx(coach.body_mass_kg + extra)
    assert float(heavier.static_wheel_loads()[0]) == pytest.approx(1.1 * wheel)
    loaded = loaded_vehicle(coach, payload_kg=1000.0)
    assert loaded.body_mass_kg == pytest.approx(coach.body_mass_kg + 1000.0)
    with pytest.raises(Invalid) as e:
        loaded_vehicle(coach, static_wheel_load_n=5000.0)
    assert e.value.facts["field"] == "static_wheel_load_n"
