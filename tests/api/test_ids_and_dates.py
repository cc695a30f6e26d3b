"""Ids and dates at their edges (issue 16, Medium 8 and 10, and item 11's epoch reading).

The probe got 500s from Unicode digits as a track/vehicle reference (``str.isdigit`` then
``int``; ``'٣'`` even resolved to track 3), a 5000-digit id, and date-times whose offset takes
them outside years 1..9999 in UTC (an upload with such ``recorded_at`` was inverted fully,
then 500); ``recorded_to=0.5`` was read as an epoch time.
"""

from __future__ import annotations

import pytest

from api.api_support import row_counts, upload

REFS = ["²", "٣", "①", "３", "9" * 5000, "0" * 40 + "3"]


@pytest.mark.parametrize("ref", REFS)
def test_unicode_digits_and_huge_numbers_are_names_not_ids(client, ref) -> None:
    """Each reference is 4xx on every way of giving a track or vehicle, never track 3."""
    for i in range(4):
        assert client.post("/api/v1/tracks", json={"name": f"line {i}"}).status_code == 201
    answers = [
        client.get(f"/api/v1/tracks/{ref}"),
        client.get(f"/api/v1/tracks/{ref}/report"),
        client.get(f"/api/v1/tracks/{ref}/profile"),
        client.get("/api/v1/runs", params={"track": ref}),
        client.get(f"/api/v1/vehicles/{ref}"),
        client.get(f"/api/v1/runs/{ref}"),
    ]
    for r in answers:
        assert 400 <= r.status_code < 500, (r.request.url, r.status_code, r.text[:200])
        assert r.json()["detail"]["message"]
    assert client.get("/api/v1/tracks/3").json()["name"] == "line 2"


def test_unicode_digit_names_address_their_own_track(client) -> None:
    """'٣' is a name like any other: it may be created and is found by name, not as id 3."""
    for i in range(4):
        client.post("/api/v1/tracks", json={"name": f"line {i}"})
    r = client.post("/api/v1/tracks", json={"name": "٣"})
    assert r.status_code == 201, r.text
    assert client.get("/api/v1/tracks/٣").json()["id"] == r.json()["id"] != 3
    assert client.post("/api/v1/tracks", json={"name": "42"}).status_code == 422  # ASCII: an id


EDGES = ["0001-01-01T00:00:00+23:59", "9999-12-31T23:59:59-23:59"]


@pytest.mark.parametrize("when", EDGES)
def test_dates_beyond_utc_are_422(client, settings, synthetic_run, when) -> None:
    """Filters, alerts and an upload's recorded_at at the edges of the date range with an
    offset are 422 naming the field, and the upload is refused before anything is inverted
    or stored."""
    for name in ("recorded_from", "recorded_to"):
        r = client.get("/api/v1/runs", params={name: when})
        assert r.status_code == 422 and r.json()["detail"]["field"] == name, r.text
    client.post("/api/v1/tracks", json={"name": "L"})
    r = client.get("/api/v1/tracks/L/alerts", params={"since": when})
    assert r.status_code == 422 and r.json()["detail"]["field"] == "since"
    before = row_counts(settings)
    r = upload(client, synthetic_run["csv"], track="L", start_chainage_m=12, recorded_at=when)
    assert r.status_code == 422 and r.json()["detail"]["field"] == "recorded_at", r.text
    r = client.post("/api/v1/simulate", json={"recorded_at": when, "length_m": 200})
    assert r.status_code == 422 and r.json()["detail"]["field"] == "recorded_at", r.text
    assert row_counts(settings) == before


@pytest.mark.parametrize("value", ["0.5", "1700000000", "-1"])
def test_numbers_are_not_read_as_epoch_times(client, value) -> None:
    r = client.get("/api/v1/runs", params={"recorded_to": value})
    assert r.status_code == 422, r.text
    assert "ISO 8601" in r.json()["detail"]["message"]
    assert client.get("/api/v1/runs", params={"recorded_to": "2026-03-01"}).status_code == 200
