"""A track is created with its first run in one transaction, and deleted with all its runs."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from starlette.testclient import TestClient

from api.api_support import row_counts, upload, wait_done


def test_rejected_upload_leaves_no_track(client: TestClient, settings: Any) -> None:
    """A new track named by an upload the service rejects is not created."""
    before = row_counts(settings)
    r = upload(client, b"time_s,accel_z_mps2\n0,1\n", track="UX line", start_chainage_m=0)
    assert r.status_code == 422, r.text
    assert client.get("/api/v1/tracks/UX line").status_code == 404
    assert row_counts(settings) == before


def test_upload_creates_the_track_with_the_given_properties(
    client: TestClient, synthetic_run: dict[str, Any]
) -> None:
    """track_description/rail/k_nominal/spacing describe a track the upload creates."""
    r = upload(
        client, synthetic_run["csv"], track="New line", start_chainage_m=12,
        track_description="km 3-7", track_rail="S49", track_k_nominal=6e7, track_spacing=0.65,
    )  # fmt: skip
    assert r.status_code in (201, 202), r.text
    t = client.get("/api/v1/tracks/New line").json()
    assert (t["description"], t["rail"], t["k_nominal"], t["spacing"]) == (
        "km 3-7", "S49", 6e7, 0.65,
    )  # fmt: skip
    bad = upload(client, synthetic_run["csv"], track="Other", start_chainage_m=12,
                 track_k_nominal=-1)  # fmt: skip
    assert bad.status_code == 422 and client.get("/api/v1/tracks/Other").status_code == 404


def test_delete_track_removes_its_runs_and_derived_data(
    client: TestClient, settings: Any, synthetic_run: dict[str, Any]
) -> None:
    """DELETE /tracks/{name} removes the track, its runs and every row derived from them;
    another track's data stays."""
    empty = row_counts(settings)
    keep = upload(client, synthetic_run["csv"], track="Keep", start_chainage_m=12)
    wait_done(client, keep.json()["id"])
    kept = row_counts(settings)
    for start in (12, 13):
        r = upload(client, synthetic_run["csv"], track="Gone/1", start_chainage_m=start)
        assert wait_done(client, r.json()["id"])["status"] == "done"
    gone_id = client.get("/api/v1/tracks", params={"limit": 10}).json()["data"][0]["id"]
    assert client.get(f"/api/v1/tracks/{gone_id}").json()["name"] == "Gone/1"
    r = client.delete(f"/api/v1/tracks/{gone_id}")
    assert r.status_code == 204, r.text
    assert client.get(f"/api/v1/tracks/{gone_id}").status_code == 404
    assert client.delete(f"/api/v1/tracks/{gone_id}").status_code == 404
    # Only the other track's rows (and the preset vehicle the uploads registered) remain.
    after = row_counts(settings)
    assert {t: n for t, n in after.items() if n != kept[t]} == {}, (empty, kept, after)
    assert client.get("/api/v1/runs", params={"track": "Keep"}).json()["count"] == 1


def test_delete_track_needs_an_admin_key_when_keys_are_on(start_app: Any) -> None:
    """With keys required for writes, DELETE without a key is 401 and changes nothing."""
    c = start_app(require_api_key=True)
    r = c.delete("/api/v1/tracks/1")
    assert r.status_code == 401


def assert_recorded_at(client: TestClient, data: bytes, first: datetime) -> None:
    """The preview reports ``first`` as the file's recording time and an upload without
    recorded_at stores it; a recorded_at given with the upload wins."""
    pv = client.post("/api/v1/views/csv-preview", files={"file": ("a.csv", data, "text/csv")})
    assert pv.status_code == 200, pv.text
    assert datetime.fromisoformat(pv.json()["recorded_at"]) == first, pv.json()
    r = upload(client, data, track="Clock", start_chainage_m=12)
    assert r.status_code in (201, 202), r.text
    assert datetime.fromisoformat(r.json()["recorded_at"]) == first
    # another log (a trailing blank line): the same bytes again would be the stored run
    given = upload(client, data + b"\n", track="Clock", start_chainage_m=13,
                   recorded_at="2025-11-20T08:00:00Z")  # fmt: skip
    assert given.json()["recorded_at"].startswith("2025-11-20T08:00:00")


def test_recorded_at_comes_from_the_files_epoch_timestamps(
    client: TestClient, synthetic_run: dict[str, Any]
) -> None:
    """A log timed in epoch seconds is stored as recorded at its first sample (the preview
    says so too); a recorded_at given with the upload wins; relative times give none."""
    from api.api_support import RAW_EPOCH0, to_raw_imu

    raw = to_raw_imu(synthetic_run["csv"])
    assert_recorded_at(client, raw, datetime.fromtimestamp(RAW_EPOCH0, UTC))
    rel = client.post("/api/v1/views/csv-preview",
                      files={"file": ("b.csv", synthetic_run["csv"], "text/csv")})  # fmt: skip
    assert rel.json()["recorded_at"] is None


def test_recorded_at_comes_from_an_iso_date_time_column(
    client: TestClient, synthetic_run: dict[str, Any]
) -> None:
    """A log with a wall-clock column of ISO 8601 date-times beside its relative times is
    stored as recorded at the first row's (the offset converted to UTC; the preview says so);
    a recorded_at given with the upload still wins."""
    lines = synthetic_run["csv"].decode().splitlines()
    clocked = "\n".join(
        [f"utc,{lines[0]}"] + [f"2025-11-03T10:15:00.000+01:00,{row}" for row in lines[1:]]
    ).encode()
    assert_recorded_at(client, clocked, datetime(2025, 11, 3, 9, 15, tzinfo=UTC))
