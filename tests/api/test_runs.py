"""Runs: uploads (multipart, raw IMU, gzip, JSON), reading results, listing, deleting, repeats."""

from __future__ import annotations

import gzip
import io

import numpy as np
import pytest
from starlette.testclient import TestClient

from api.api_support import (
    assert_zones_match,
    example,
    row_counts,
    sample,
    stored_points,
    to_raw_imu,
    upload,
)

SAMPLES = ["sample_clean_exact", "sample_noisy"]


@pytest.mark.parametrize("name", SAMPLES)
def test_sample_upload_finds_the_true_soft_zones(client: TestClient, name: str) -> None:
    """Each shared sample run, uploaded as a file, gives its true soft zones within ±1.5 m."""
    data, truth = sample(name)
    r = upload(
        client,
        data,
        f"{name}.csv",
        track="line A",
        start_chainage_m=truth["start_chainage_m"],
        direction=truth["direction"],
    )
    assert r.status_code == 201, r.text
    run = r.json()
    assert run["status"] == "done"
    assert run["duplicate"] is False
    assert run["original_filename"] == f"{name}.csv"
    assert run["sample_rate_hz"] == pytest.approx(truth["sample_rate_hz"])
    assert run["n_samples"] == data.count(b"\n") - 1
    assert run["speed_min_mps"] == pytest.approx(truth["speed"])
    assert run["quality"]["coverage_m"] > 0.6 * truth["track"]["length"]
    spots = client.get(f"/api/v1/runs/{run['id']}/soft-spots").json()
    assert_zones_match(spots, truth["zones"])
    for spot, zone in zip(spots, truth["zones"], strict=True):
        assert spot["start_m"] <= spot["peak_m"] <= spot["end_m"]
        assert spot["depth_mm"] > 0
        assert abs(spot["stiffness_loss_pct"] - 100 * zone["stiffness_loss"]) <= 10


def _renamed(raw: bytes, names: tuple[str, ...], delimiter: str) -> bytes:
    """A raw log under other column names and another delimiter (values untouched)."""
    header, body = raw.split(b"\n", 1)
    assert header.count(b",") == len(names) - 1
    return (delimiter.join(names) + "\n").encode() + body.replace(b",", delimiter.encode())


def test_raw_imu_log_with_unit_options(client: TestClient) -> None:
    """A logger's format (epoch s, g with gravity, deg/s, km/h) under its own column names is
    read with the column/unit options and gives the true zones (the repository's example)."""
    data, truth = example()
    raw = _renamed(data, ("t_epoch", "acc_vert", "rate_pitch", "v"), ";")
    r = upload(
        client,
        raw,
        "logger.csv",
        track="raw",
        start_chainage_m=truth["start_chainage_m"],
        time_column="t_epoch",
        accel_column="acc_vert",
        pitch_rate_column="rate_pitch",
        speed_column="v",
        time_unit="epoch_s",
        accel_unit="g",
        pitch_rate_unit="deg/s",
        speed_unit="km/h",
        gravity="included",
    )
    assert r.status_code == 201, r.text
    run = r.json()
    # epoch time shifted to 0 (1 kHz); km/h converted
    assert run["duration_s"] == pytest.approx((truth["n_samples"] - 1) / 1000, abs=0.01)
    assert run["speed_max_mps"] == pytest.approx(truth["speed_mps"], rel=1e-6)
    assert run["options"]["csv"]["accel_unit"] == "g"
    assert_zones_match(client.get(f"/api/v1/runs/{run['id']}/soft-spots").json(), truth["zones"])


def test_raw_imu_log_recognised_from_its_header(client: TestClient) -> None:
    """The documented raw format (timestamp, az_g, gyro_y_dps, speed_kmh) needs no options:
    the repository's example log gives its true zones as it is."""
    data, truth = example()
    r = upload(client, data, "raw.csv", track="raw", start_chainage_m=truth["start_chainage_m"])
    assert r.status_code == 201, r.text
    assert_zones_match(
        client.get(f"/api/v1/runs/{r.json()['id']}/soft-spots").json(), truth["zones"]
    )


def test_raw_imu_from_a_canonical_sample_gives_its_zones(client: TestClient) -> None:
    """A shared sample rewritten in the raw format gives the zones of the canonical file."""
    data, truth = sample("sample_noisy")
    r = upload(
        client, to_raw_imu(data), "raw.csv", track="raw", start_chainage_m=truth["start_chainage_m"]
    )
    assert r.status_code == 201, r.text
    assert_zones_match(
        client.get(f"/api/v1/runs/{r.json()['id']}/soft-spots").json(), truth["zones"]
    )


def test_wrong_unit_option_changes_the_result(client: TestClient) -> None:
    """Unit options are applied, not ignored: reading deg/s as rad/s makes the log unusable
    (or gives different soft spots), so the options visibly matter."""
    raw, truth = example()
    r = upload(
        client,
        raw,
        "raw.csv",
        track="raw",
        start_chainage_m=truth["start_chainage_m"],
        pitch_rate_unit="rad/s",
    )
    if r.status_code == 201:
        spots = client.get(f"/api/v1/runs/{r.json()['id']}/soft-spots").json()
        with pytest.raises(AssertionError):
            assert_zones_match(spots, truth["zones"])
    else:
        assert r.status_code == 422


def test_gzip_upload_is_accepted(client: TestClient, synthetic_run) -> None:
    """A gzip-compressed CSV is read like the plain file."""
    r = upload(
        client,
        gzip.compress(synthetic_run["csv"]),
        "run.csv.gz",
        track="gz",
        start_chainage_m=synthetic_run["start_chainage_m"],
    )
    assert r.status_code == 201, r.text
    assert r.json()["n_samples"] == synthetic_run["n_samples"]
    assert_zones_match(
        client.get(f"/api/v1/runs/{r.json()['id']}/soft-spots").json(), synthetic_run["zones"]
    )


def test_json_body_with_columns(client: TestClient, synthetic_run) -> None:
    """A pipeline may send canonical SI arrays as JSON; the run is processed like an upload."""
    a = np.loadtxt(io.BytesIO(synthetic_run["csv"]), delimiter=",", skiprows=1)
    body = {
        "track": "json",
        "start_chainage_m": synthetic_run["start_chainage_m"],
        "recorded_at": "2025-06-01T08:30:00+02:00",
        "columns": {
            "time_s": a[:, 0].tolist(),
            "accel_z_mps2": a[:, 1].tolist(),
            "pitch_rate_radps": a[:, 2].tolist(),
            "speed_mps": a[:, 3].tolist(),
        },
    }
    r = client.post("/api/v1/runs", json=body)
    assert r.status_code == 201, r.text
    run = r.json()
    assert run["source"] == "json"
    assert run["recorded_at"].startswith("2025-06-01T06:30:00")  # stored in UTC
    assert_zones_match(
        client.get(f"/api/v1/runs/{run['id']}/soft-spots").json(), synthetic_run["zones"]
    )


def test_json_columns_with_chainage_instead_of_speed(client: TestClient, synthetic_run) -> None:
    """With an odometer column (chainage_m) neither speed nor start chainage is needed."""
    a = np.loadtxt(io.BytesIO(synthetic_run["csv"]), delimiter=",", skiprows=1)
    dt = np.diff(a[:, 0], prepend=a[0, 0])
    chainage = synthetic_run["start_chainage_m"] + np.cumsum(a[:, 3] * dt)
    body = {
        "track": "odo",
        "columns": {
            "time_s": a[:, 0].tolist(),
            "accel_z_mps2": a[:, 1].tolist(),
            "pitch_rate_radps": a[:, 2].tolist(),
            "chainage_m": chainage.tolist(),
        },
    }
    r = client.post("/api/v1/runs", json=body)
    assert r.status_code == 201, r.text
    assert r.json()["start_chainage_m"] is None
    assert_zones_match(
        client.get(f"/api/v1/runs/{r.json()['id']}/soft-spots").json(), synthetic_run["zones"]
    )


def test_json_body_with_csv_text_and_options(client: TestClient, synthetic_run) -> None:
    """A pipeline may send the CSV text in JSON, with the same column/unit options."""
    raw = to_raw_imu(synthetic_run["csv"]).decode()
    body = {
        "track": "json",
        "start_chainage_m": synthetic_run["start_chainage_m"],
        "csv": raw,
        "accel_unit": "g",
        "gravity": "included",
        "filename": "../../etc/passwd",
    }
    r = client.post("/api/v1/runs", json=body)
    assert r.status_code == 201, r.text
    assert r.json()["original_filename"] == "passwd"  # kept as data, never as a path
    assert_zones_match(
        client.get(f"/api/v1/runs/{r.json()['id']}/soft-spots").json(), synthetic_run["zones"]
    )


@pytest.fixture
def stored_run(client: TestClient, synthetic_run) -> dict:
    """The synthetic run, uploaded and processed."""
    r = upload(
        client, synthetic_run["csv"], track="T1", start_chainage_m=synthetic_run["start_chainage_m"]
    )
    assert r.status_code == 201, r.text
    return r.json()


def test_profile_json_full_and_window(client: TestClient, stored_run) -> None:
    """The profile is on a regular 0.25 m grid; a window returns exactly the points inside."""
    rid = stored_run["id"]
    full = client.get(f"/api/v1/runs/{rid}/profile").json()
    assert set(full) == {"run_id", "chainage_offset_m", "n", "chainage_m", "level_mm"}
    x = np.array(full["chainage_m"])
    assert full["n"] == x.size == len(full["level_mm"]) > 400
    assert np.allclose(np.diff(x), 0.25)
    assert x[0] <= stored_run["chainage_min_m"] and x[-1] >= stored_run["chainage_max_m"]
    win = client.get(f"/api/v1/runs/{rid}/profile", params={"from_m": 60, "to_m": 80}).json()
    wx = np.array(win["chainage_m"])
    assert wx[0] == 60.0 and wx[-1] == 80.0 and wx.size == 81
    inside = (x >= 60) & (x <= 80)
    assert win["level_mm"] == [v for v, k in zip(full["level_mm"], inside, strict=True) if k]
    # the soft zone is a dip of the fused level
    lvl = np.array(win["level_mm"], dtype=float)
    assert 70 <= wx[np.nanargmin(lvl)] <= 76


def test_profile_extra_arrays_on_request(client: TestClient, stored_run) -> None:
    """?include= adds the axle levels and the baseline; the fused level is their mean where
    both axles passed; unknown names are a 422."""
    rid = stored_run["id"]
    url = f"/api/v1/runs/{rid}/profile"
    one = client.get(url, params={"include": "baseline_mm"}).json()
    assert set(one) >= {"baseline_mm"} and "front_level_mm" not in one
    p = client.get(url, params={"include": "all"}).json()
    n = p["n"]
    assert len(p["front_level_mm"]) == len(p["rear_level_mm"]) == len(p["baseline_mm"]) == n
    both = [
        (lv, f, r)
        for lv, f, r in zip(p["level_mm"], p["front_level_mm"], p["rear_level_mm"], strict=True)
        if f is not None and r is not None
    ]
    assert len(both) > n / 2
    assert all(abs(lv - 0.5 * (f + r)) < 1e-9 for lv, f, r in both)
    bad = client.get(url, params={"include": "rear_level_mm,wheels"})
    assert bad.status_code == 422
    assert bad.json()["detail"]["field"] == "include"


def test_profile_csv_matches_json(client: TestClient, stored_run) -> None:
    """?format=csv gives the same points as JSON: chainage_m,level_mm by default (like the
    engine's profile.csv), the other columns with ?include=all."""
    rid = stored_run["id"]
    params = {"from_m": 50, "to_m": 55}
    js = client.get(f"/api/v1/runs/{rid}/profile", params={**params, "include": "all"}).json()
    r = client.get(f"/api/v1/runs/{rid}/profile", params={**params, "format": "csv"})
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("text/csv")
    lines = r.text.strip().splitlines()
    assert lines[0] == "chainage_m,level_mm"
    rows = [ln.split(",") for ln in lines[1:]]
    assert [float(r[0]) for r in rows] == js["chainage_m"]
    assert [float(r[1]) for r in rows] == pytest.approx(js["level_mm"], abs=1e-6)
    r = client.get(
        f"/api/v1/runs/{rid}/profile", params={**params, "format": "csv", "include": "all"}
    )
    lines = r.text.strip().splitlines()
    assert lines[0] == (
        "chainage_m,level_mm,front_level_mm,rear_level_mm,baseline_mm,front_force_n,rear_force_n"
    )
    base = [float(ln.split(",")[4]) for ln in lines[1:]]
    assert base == pytest.approx(js["baseline_mm"], abs=1e-6)
    force = [float(ln.split(",")[5]) for ln in lines[1:]]
    assert force == pytest.approx(js["front_force_n"], abs=1e-6)


def test_profile_window_must_be_ordered(client: TestClient, stored_run) -> None:
    """to_m before from_m is a 422 naming to_m."""
    r = client.get(f"/api/v1/runs/{stored_run['id']}/profile", params={"from_m": 9, "to_m": 1})
    assert r.status_code == 422
    assert r.json()["detail"]["field"] == "to_m"


def test_soft_spots_json_and_csv(client: TestClient, stored_run) -> None:
    """Soft spots come as the documented objects, and as CSV with the same numbers; on a
    straight-rail run the stiffness losses stay, labelled as single-pass figures."""
    rid = stored_run["id"]
    spots = client.get(f"/api/v1/runs/{rid}/soft-spots").json()
    assert spots and set(spots[0]) == {
        "start_m", "end_m", "peak_m", "depth_mm", "stiffness_loss_pct", "stiffness_basis",
        "message",
    }  # fmt: skip
    assert all(s["stiffness_basis"] == "single pass" and s["message"] is None for s in spots)
    assert all(s["stiffness_loss_pct"] is not None for s in spots)
    assert stored_run["n_soft_spots"] == len(spots)
    r = client.get(f"/api/v1/runs/{rid}/soft-spots", params={"format": "csv"})
    lines = r.text.strip().splitlines()
    assert lines[0] == "start_m,end_m,peak_m,depth_mm,stiffness_loss_pct"
    assert len(lines) == len(spots) + 1
    assert float(lines[1].split(",")[0]) == pytest.approx(spots[0]["start_m"], abs=1e-3)


def test_signals_are_decimated_keeping_peaks(client: TestClient, stored_run, synthetic_run):
    """Raw signals come back against time, at most 5000 points, with the extremes preserved."""
    sig = client.get(f"/api/v1/runs/{stored_run['id']}/signals").json()
    a = np.loadtxt(io.BytesIO(synthetic_run["csv"]), delimiter=",", skiprows=1)
    assert sig["n_samples"] == a.shape[0]
    n = len(sig["time_s"])
    assert sig["decimated"] == (a.shape[0] > 5000)
    assert n <= 5000
    assert len(sig["accel_z_mps2"]) == len(sig["pitch_rate_radps"]) == len(sig["speed_mps"]) == n
    assert max(sig["accel_z_mps2"]) == pytest.approx(a[:, 1].max())
    assert min(sig["pitch_rate_radps"]) == pytest.approx(a[:, 2].min())
    assert sig["time_s"][0] == 0 and sig["time_s"][-1] == pytest.approx(a[-1, 0] - a[0, 0])


def test_run_metadata_and_listing(client: TestClient, synthetic_run) -> None:
    """Runs are listed newest first, filtered by track, status and time, and paginated."""
    csv = synthetic_run["csv"]
    start = synthetic_run["start_chainage_m"]
    ids = []
    for track, when, tweak in (
        ("north", "2025-01-01T00:00:00Z", b""),
        ("north", "2025-03-01T00:00:00Z", b"\n"),
        ("south", "2025-02-01T00:00:00Z", b""),
    ):
        r = upload(client, csv + tweak, track=track, start_chainage_m=start, recorded_at=when)
        assert r.status_code == 201, r.text
        ids.append(r.json()["id"])
    all_runs = client.get("/api/v1/runs").json()
    assert all_runs["count"] == 3
    assert [r["id"] for r in all_runs["data"]] == [ids[1], ids[2], ids[0]]
    north = client.get("/api/v1/runs", params={"track": "north"}).json()
    assert {r["id"] for r in north["data"]} == {ids[0], ids[1]}
    tid = north["data"][0]["track_id"]
    assert client.get("/api/v1/runs", params={"track": str(tid)}).json()["count"] == 2
    window = client.get(
        "/api/v1/runs",
        params={"recorded_from": "2025-01-15T00:00:00Z", "recorded_to": "2025-02-15T00:00:00Z"},
    ).json()
    assert [r["id"] for r in window["data"]] == [ids[2]]
    assert client.get("/api/v1/runs", params={"status": "failed"}).json()["count"] == 0
    page = client.get("/api/v1/runs", params={"limit": 1, "offset": 1}).json()
    assert page["count"] == 3 and [r["id"] for r in page["data"]] == [ids[2]]
    assert client.get("/api/v1/tracks/north").json()["n_runs"] == 2
    assert client.get("/api/v1/runs", params={"track": "nowhere"}).status_code == 404


def test_delete_run_removes_its_data(client: TestClient, settings, synthetic_run) -> None:
    """DELETE removes the run with its profile, soft spots and signals; then it is 404."""
    empty = row_counts(settings)
    r = upload(
        client, synthetic_run["csv"], track="T", start_chainage_m=synthetic_run["start_chainage_m"]
    )
    rid = r.json()["id"]
    stored = row_counts(settings)
    assert sum(stored_points(settings).values()) > 400 and stored["soft_spots"] >= 1
    assert client.delete(f"/api/v1/runs/{rid}").status_code == 204
    after = row_counts(settings)
    assert after == {**empty, "tracks": 1}  # the track stays
    assert client.get(f"/api/v1/runs/{rid}").status_code == 404
    assert client.delete(f"/api/v1/runs/{rid}").status_code == 404
    assert client.get(f"/api/v1/runs/{rid}/profile").status_code == 404


def test_same_file_twice_is_stored_once(client: TestClient, settings, synthetic_run) -> None:
    """Resending a file to the same track returns the stored run (200, duplicate) and adds
    nothing; the same file on another track is another run."""
    start = synthetic_run["start_chainage_m"]
    first = upload(client, synthetic_run["csv"], track="T", start_chainage_m=start)
    assert first.status_code == 201
    before = row_counts(settings)
    again = upload(client, synthetic_run["csv"], track="T", start_chainage_m=start)
    assert again.status_code == 200
    assert again.json()["id"] == first.json()["id"]
    assert again.json()["duplicate"] is True
    assert row_counts(settings) == before
    other = upload(client, synthetic_run["csv"], track="U", start_chainage_m=start)
    assert other.status_code == 201
    assert other.json()["id"] != first.json()["id"]


def test_idempotency_key(client: TestClient, settings, synthetic_run) -> None:
    """A repeated Idempotency-Key returns the first run; reused for other content it is a 409
    that stores nothing."""
    start = synthetic_run["start_chainage_m"]
    key = {"Idempotency-Key": "pipeline-42"}
    first = upload(client, synthetic_run["csv"], track="T", start_chainage_m=start, headers=key)
    assert first.status_code == 201
    before = row_counts(settings)
    again = upload(client, synthetic_run["csv"], track="T", start_chainage_m=start, headers=key)
    assert (again.status_code, again.json()["id"]) == (200, first.json()["id"])
    other = upload(
        client, synthetic_run["csv"] + b"\n", track="T", start_chainage_m=start, headers=key
    )
    assert other.status_code == 409
    assert other.json()["detail"]["field"] == "Idempotency-Key"
    assert row_counts(settings) == before


def test_unknown_run_is_404_everywhere(client: TestClient) -> None:
    """Every per-run endpoint answers 404 for a run that does not exist."""
    for path in ("", "/profile", "/soft-spots", "/signals"):
        r = client.get(f"/api/v1/runs/12345{path}")
        assert r.status_code == 404, path
        assert "12345" in r.json()["detail"]["message"]
