"""Simulating with an IMU grade, and the detection limit a run reports from its own noise."""

from __future__ import annotations

import pytest
from starlette.testclient import TestClient

from api.api_support import row_counts

BODY = {"track": "grades", "length_m": 240, "speed_mps": 25, "zones": [{"start_m": 100,
        "end_m": 103, "loss": 0.5}], "seed": 3}  # fmt: skip


@pytest.mark.slow
def test_limit_falls_as_the_noise_falls(client: TestClient) -> None:
    """The same track logged by a consumer, industrial and fibre-optic IMU: each run's
    GET /runs/{id} reports its detection limit for 3 m and 6 m zones, lower for the quieter
    sensor; the measured noise is the grade's (sensors.md, 1 kHz)."""
    limits = {}
    noise = {}
    for grade in ("consumer-mems", "industrial-mems", "fibre-optic"):
        r = client.post("/api/v1/simulate", json={**BODY, "sensor_grade": grade})
        assert r.status_code == 201, r.text
        run = client.get(f"/api/v1/runs/{r.json()['run']['id']}").json()
        lim = run["detection_limit"]
        assert lim["zone_length_m"] == [3.0, 6.0]
        assert lim["threshold_mm"] > 0
        limits[grade] = lim["min_loss_pct"]
        noise[grade] = run["quality"]["noise_accel_mps2"]
    assert noise["consumer-mems"] > 0.04 and noise["fibre-optic"] < 0.006, noise
    for i in range(2):
        c, ind, f = (limits[g][i] for g in ("consumer-mems", "industrial-mems", "fibre-optic"))
        assert (c is None or c > ind) and ind > f, limits


def test_grade_or_sensor_not_both_and_unknown_grades(client: TestClient, settings) -> None:
    """An unknown grade, or a grade with explicit sensor figures, is a 422 naming
    sensor_grade; nothing is stored. The grades are listed with their figures."""
    before = row_counts(settings)
    for body in ({**BODY, "sensor_grade": "military"},
                 {**BODY, "sensor_grade": "fibre-optic", "sensor": "ideal"}):  # fmt: skip
        r = client.post("/api/v1/simulate", json=body)
        assert r.status_code == 422, r.text
        assert r.json()["detail"]["field"] == "sensor_grade", r.json()
    assert row_counts(settings) == before
    grades = client.get("/api/v1/simulate/sensor-grades").json()
    assert list(grades) == ["fibre-optic", "tactical-mems", "industrial-mems", "consumer-mems"]
    assert grades["consumer-mems"]["accel_density_ug"] == 230.0
    spec = client.get("/openapi.json").json()
    prop = spec["components"]["schemas"]["SimulateRequest"]["properties"]["sensor_grade"]
    assert "industrial-mems" in prop["enum"]
