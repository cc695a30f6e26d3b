"""Vehicles: the Table 1 vehicle from the start, creating others, bad parameter sets refused."""

from __future__ import annotations

import pytest
from starlette.testclient import TestClient

from api.api_support import row_counts
from engine.vehicle import TABLE1


def test_table1_vehicle_exists_from_the_start(client: TestClient) -> None:
    """A new database holds the paper's Table 1 vehicle as 'table1', with its exact values."""
    listing = client.get("/api/v1/vehicles").json()
    assert listing["count"] == 1
    v = listing["data"][0]
    assert v["name"] == "table1"
    assert v["params"] == TABLE1.to_dict()
    assert client.get("/api/v1/vehicles/table1").json() == v
    assert client.get(f"/api/v1/vehicles/{v['id']}").json() == v


def test_create_vehicle_nested_and_flat(client: TestClient) -> None:
    """Parameters may be nested in 'params' or given at top level; missing ones are Table 1."""
    r = client.post("/api/v1/vehicles", json={"name": "heavy", "params": {"ms": 30000.0}})
    assert r.status_code == 201, r.text
    assert r.json()["params"]["ms"] == 30000.0
    assert r.json()["params"]["Is"] == TABLE1.Is
    r = client.post("/api/v1/vehicles", json={"name": "short", "d1": 3.0, "d2": 3.5})
    assert r.status_code == 201, r.text
    assert (r.json()["params"]["d1"], r.json()["params"]["d2"]) == (3.0, 3.5)
    assert client.get("/api/v1/vehicles").json()["count"] == 3


def test_sensor_position_is_a_vehicle_parameter(client: TestClient) -> None:
    """``params.sensor_x_m`` (m ahead of the body CG, default 0) is stored and served; a
    position behind the CG is negative."""
    assert client.get("/api/v1/vehicles/table1").json()["params"]["sensor_x_m"] == 0.0
    r = client.post("/api/v1/vehicles", json={"name": "imu-behind", "sensor_x_m": -2.5})
    assert r.status_code == 201, r.text
    assert client.get("/api/v1/vehicles/imu-behind").json()["params"]["sensor_x_m"] == -2.5


def test_conflicting_nested_and_flat_value_is_refused(client: TestClient) -> None:
    """The same parameter given twice with different values is a 422, not a silent choice."""
    r = client.post("/api/v1/vehicles", json={"name": "x", "ms": 1.0, "params": {"ms": 2.0}})
    assert r.status_code == 422
    assert "ms" in r.json()["detail"]["message"]


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"name": "neg", "params": {"ms": -16200}}, "params.ms"),
        ({"name": "zero", "kt1": 0}, "params.kt1"),
        ({"name": "damp", "params": {"cs1": -1}}, "params.cs1"),
        ({"name": "text", "params": {"mu1": "heavy"}}, "params.mu1"),
        ({"name": "typo", "params": {"mass": 1}}, "params.mass"),
        ({"name": "imu", "params": {"sensor_x_m": 20.0}}, "params.sensor_x_m"),
        ({"params": {}}, "name"),
    ],
)
def test_bad_vehicle_is_refused(client: TestClient, settings, body, field) -> None:
    """A negative mass, zero stiffness, text or unknown parameter is a 422 naming it."""
    before = row_counts(settings)
    r = client.post("/api/v1/vehicles", json=body)
    assert r.status_code == 422, r.text
    assert r.json()["detail"]["field"] == field
    assert row_counts(settings) == before


def test_duplicate_vehicle_conflicts(client: TestClient) -> None:
    """The name of an existing vehicle (table1 included) cannot be reused."""
    r = client.post("/api/v1/vehicles", json={"name": "table1"})
    assert r.status_code == 409


def test_unknown_vehicle_is_404(client: TestClient) -> None:
    """Reading a vehicle that does not exist is a 404."""
    assert client.get("/api/v1/vehicles/999").status_code == 404
