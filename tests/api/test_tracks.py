"""Tracks: create, list, read by id or name; bad bodies are refused and store nothing."""

from __future__ import annotations

import pytest
from starlette.testclient import TestClient

from api.api_support import row_counts


def test_create_and_read_track(client: TestClient) -> None:
    """A created track is listed and readable by id and by name with its properties (SI)."""
    r = client.post(
        "/api/v1/tracks",
        json={"name": "Line 12 up", "description": "km 3-7", "k_nominal": 6e7, "spacing": 0.65},
    )
    assert r.status_code == 201, r.text
    t = r.json()
    assert t["name"] == "Line 12 up"
    assert t["k_nominal"] == 6e7
    assert t["spacing"] == 0.65
    assert t["rail"] == "UIC60"
    assert t["EI"] == pytest.approx(210e9 * 3.055e-5)
    assert t["n_runs"] == 0
    by_id = client.get(f"/api/v1/tracks/{t['id']}").json()
    by_name = client.get("/api/v1/tracks/Line 12 up").json()
    assert by_id == by_name == t
    listing = client.get("/api/v1/tracks").json()
    assert listing["count"] == 1
    assert [x["name"] for x in listing["data"]] == ["Line 12 up"]


def test_track_listing_is_paginated(client: TestClient) -> None:
    """limit/offset page through tracks sorted by name; count is the total."""
    for name in ("c", "a", "b"):
        assert client.post("/api/v1/tracks", json={"name": name}).status_code == 201
    page = client.get("/api/v1/tracks", params={"limit": 2, "offset": 1}).json()
    assert page["count"] == 3
    assert [t["name"] for t in page["data"]] == ["b", "c"]


def test_duplicate_track_name_conflicts(client: TestClient, settings) -> None:
    """A second track with the same name is a 409 naming the field; nothing is added."""
    assert client.post("/api/v1/tracks", json={"name": "L1"}).status_code == 201
    before = row_counts(settings)
    r = client.post("/api/v1/tracks", json={"name": "L1"})
    assert r.status_code == 409
    assert r.json()["detail"]["field"] == "name"
    assert row_counts(settings) == before


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"name": "x", "k_nominal": -5}, "k_nominal"),
        ({"name": "x", "spacing": 0}, "spacing"),
        ({"name": "x", "EI": "stiff"}, "EI"),
        ({"name": ""}, "name"),
        ({"name": "a\nb"}, "name"),
        ({"description": "no name"}, "name"),
        ({"name": "x", "colour": "red"}, "colour"),
        ([1, 2, 3], None),
    ],
)
def test_bad_track_bodies_are_refused(client: TestClient, settings, body, field) -> None:
    """Bad values, missing names, unknown keys and wrong shapes are 422 naming the field."""
    before = row_counts(settings)
    r = client.post("/api/v1/tracks", json=body)
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert detail["message"]
    if field is not None:
        assert detail["field"] == field
    assert row_counts(settings) == before


def test_markup_in_names_is_kept_as_text(client: TestClient) -> None:
    """A name with markup is stored and returned verbatim (the dashboard shows it as text)."""
    name = "<script>alert(1)</script>"
    r = client.post("/api/v1/tracks", json={"name": name})
    assert r.status_code == 201
    assert client.get(f"/api/v1/tracks/{r.json()['id']}").json()["name"] == name


def test_unknown_track_is_404(client: TestClient) -> None:
    """Reading a track that does not exist is a 404 naming it."""
    r = client.get("/api/v1/tracks/nowhere")
    assert r.status_code == 404
    assert "nowhere" in r.json()["detail"]["message"]
