"""Physical ranges of track and vehicle parameters (issue 16, Medium 5 and 10).

The probe made a track with a 1 cm support spacing (one upload held the only processing slot
for 297 s), 1e-300 m (every upload and simulate on it 500), EI 1e308 (500), k 1e-300 (stiffness
fit not positive definite), and vehicles with 1e308 masses or contact stiffness (runs stored
'done' without a profile). Each is now a 422 naming the parameter; a track stored before the
ranges existed is refused where it is used, with a 422, never a 500.
"""

from __future__ import annotations

import pytest

from api.api_support import row_counts, sql, upload

TRACKS = [
    ("spacing", 0.01), ("spacing", 1e-300), ("EI", 1e308), ("k_nominal", 1e-300),
    ("k_nominal", 1e308), ("mass_per_m", 1e-9), ("c_support", 1e30),
]  # fmt: skip
VEHICLES = [("ms", 1e308), ("kt1", 1e308), ("mu1", 1e-300), ("d1", 1e-6), ("cs1", 1e300)]


@pytest.mark.parametrize(("name", "value"), TRACKS)
def test_track_parameters_outside_their_range_are_422(client, settings, name, value) -> None:
    before = row_counts(settings)
    r = client.post("/api/v1/tracks", json={"name": "L1", name: value})
    assert r.status_code == 422, r.text
    assert r.json()["detail"]["field"] == name
    assert row_counts(settings) == before


@pytest.mark.parametrize(("name", "value"), VEHICLES)
def test_vehicle_parameters_outside_their_range_are_422(client, settings, name, value) -> None:
    before = row_counts(settings)
    r = client.post("/api/v1/vehicles", json={"name": "v1", "params": {name: value}})
    assert r.status_code == 422, r.text
    assert r.json()["detail"]["field"] == f"params.{name}"
    assert row_counts(settings) == before


def test_the_ranges_are_in_the_schema(client) -> None:
    schemas = client.get("/openapi.json").json()["components"]["schemas"]
    spacing = schemas["TrackCreate"]["properties"]["spacing"]
    assert (spacing["minimum"], spacing["maximum"]) == (0.3, 1.5)
    ms = schemas["VehicleParamsSchema"]["properties"]["ms"]
    assert (ms["minimum"], ms["maximum"]) == (500.0, 5e5)


def test_a_track_stored_out_of_range_is_refused_where_used(client, settings, synthetic_run):
    """A track whose spacing was stored as 1e-300 (before the ranges) still reads, and an
    upload or simulate on it is a 422 naming the parameter, storing nothing."""
    assert client.post("/api/v1/tracks", json={"name": "Old"}).status_code == 201
    sql(settings, "UPDATE tracks SET spacing = 1e-300 WHERE name = 'Old'")
    assert client.get("/api/v1/tracks/Old").json()["spacing"] == 1e-300
    before = row_counts(settings)
    r = upload(client, synthetic_run["csv"], track="Old", start_chainage_m=12)
    assert r.status_code == 422, r.text
    assert "spacing" in r.json()["detail"]["message"]
    r = client.post("/api/v1/simulate", json={"track": "Old", "length_m": 200, "zones": []})
    assert r.status_code == 422, r.text
    assert "spacing" in r.json()["detail"]["message"]
    assert row_counts(settings) == before
