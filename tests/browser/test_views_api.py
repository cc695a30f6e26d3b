"""The chart views the dashboard draws from (``/api/v1/views``), checked over HTTP.

No browser here: these pin down the numbers behind the pages (decimation keeps every dip,
the heatmap is the true lowest level per bin, zones merge the same dip across runs, the CSV
preview is the engine's reading) and the errors of bad windows.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator

import numpy as np
import pytest
from browser.bigtrack import BigTrack, fill_big_track

from app.core.config import REPO_ROOT, Settings
from app.main import create_app
from app.services.views.charts import minmax_decimate

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    from starlette.testclient import TestClient


@pytest.fixture(scope="module")
def small_track(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[TestClient, BigTrack]]:
    """An app over a generated 3-run, 2 km track whose whole profile is stored."""
    data = tmp_path_factory.mktemp("views")
    url = f"sqlite:///{data / 'trackprofile.db'}"
    track = fill_big_track(
        url, name="Small line", n_runs=3, length_m=2000.0, n_zones=6, detect_prob=1.0,
        false_alarms_per_run=1, profile_from_m=0.0, profile_to_m=2000.0, seed=3,
    )  # fmt: skip
    settings = Settings(
        data_dir=data, database_url=url, static_dir=REPO_ROOT / "static", start_worker=False
    )
    with TestClient(create_app(settings)) as client:
        yield client, track


def test_minmax_decimation_keeps_extremes_and_gaps() -> None:
    """Decimated columns keep each bucket's lowest and highest value (so the deepest dip and
    the highest peak survive), stay within the point budget, and keep no-data buckets empty."""
    rng = np.random.default_rng(1)
    x = np.arange(100_000) * 0.25
    level = rng.normal(0, 0.02, x.size)
    level[61_234] = -0.9
    level[7_777] = 0.7
    front = level.copy()
    front[:5000] = np.nan
    xd, cols, decimated = minmax_decimate(x, {"level": level, "front": front}, 2000)
    assert decimated and xd.size <= 2000 and cols["level"].size == xd.size
    assert np.nanmin(cols["level"]) == -0.9 and np.nanmax(cols["level"]) == 0.7
    assert np.all(np.diff(xd) >= 0)
    assert np.isnan(cols["front"][0]) and np.isfinite(cols["front"][-1])
    short_x, short, dec = minmax_decimate(x[:500], {"level": level[:500]}, 2000)
    assert not dec and np.array_equal(short["level"], level[:500])


@pytest.mark.slow
def test_heatmap_is_the_lowest_level_per_run_and_bin(
    small_track: tuple[TestClient, BigTrack],
) -> None:
    """Each heatmap cell equals the minimum of that run's stored level over the bin."""
    client, _ = small_track
    body = client.get(
        "/api/v1/views/tracks/Small line/chainage-map",
        params={"from_m": 300, "to_m": 800, "bins": 50},
    ).json()
    heat = body["heatmap"]
    assert heat["bin_m"] == pytest.approx(10.0) and len(heat["x"]) == 50
    assert len(heat["z"]) == len(body["runs"]) == 3
    for run, row in zip(body["runs"], heat["z"], strict=True):
        prof = client.get(f"/api/v1/runs/{run['id']}/profile", params={"from_m": 300, "to_m": 800})
        p = prof.json()
        x = np.asarray(p["chainage_m"])
        y = np.asarray(p["level_mm"], dtype=float)
        for k in (0, 17, 49):
            sel = (x >= 300 + 10 * k) & (x < 310 + 10 * k)
            assert row[k] == pytest.approx(float(y[sel].min()), abs=1e-4)


def test_zones_merge_the_same_dip_across_runs(small_track: tuple[TestClient, BigTrack]) -> None:
    """Every generated zone (detected on all 3 runs) is one zone seen 3 of 3 times; one-off
    false alarms rank below them."""
    client, track = small_track
    body = client.get("/api/v1/views/tracks/Small line/chainage-map").json()
    zones = body["zones"]
    assert sum(body["runs"][i]["n_soft_spots"] for i in range(3)) == len(body["spots"]["peak_m"])
    for peak in track.zone_peaks_m:
        hit = [z for z in zones if z["start_m"] <= peak <= z["end_m"]]
        assert len(hit) == 1 and hit[0]["runs_seen"] == 3 and hit[0]["runs_total"] == 3
    recurring = [z["severity"] for z in zones if z["runs_seen"] == 3]
    one_offs = [z["severity"] for z in zones if z["runs_seen"] == 1]
    assert one_offs and min(recurring) > 0 and max(one_offs) < max(recurring)


def test_run_profile_view_serves_windows_at_full_or_reduced_resolution(
    small_track: tuple[TestClient, BigTrack],
) -> None:
    """The whole 2 km profile is decimated to the budget; a 100 m window comes whole."""
    client, _ = small_track
    run_id = client.get("/api/v1/views/tracks/Small line/chainage-map").json()["runs"][0]["id"]
    whole = client.get(f"/api/v1/views/runs/{run_id}/profile", params={"max_points": 1000}).json()
    assert whole["decimated"] and whole["n_points"] == 8000 and len(whole["chainage_m"]) <= 1000
    part = client.get(
        f"/api/v1/views/runs/{run_id}/profile", params={"from_m": 1000, "to_m": 1100}
    ).json()
    assert not part["decimated"] and len(part["level_mm"]) == 401
    assert part["chainage_m"][0] == 1000 and part["chainage_m"][-1] == 1100


def test_window_of_all_runs_around_a_zone(small_track: tuple[TestClient, BigTrack]) -> None:
    """The zone window has one profile per run covering it, oldest first."""
    client, track = small_track
    a = float(round(track.zone_peaks_m[0])) - 30  # on the 0.25 m grid: 241 points inclusive
    body = client.get(
        "/api/v1/views/tracks/Small line/window", params={"from_m": a, "to_m": a + 60}
    ).json()
    runs = body["runs"]
    assert len(runs) == 3
    assert [r["recorded_at"] for r in runs] == sorted(r["recorded_at"] for r in runs)
    assert all(len(r["chainage_m"]) == 241 for r in runs)


@pytest.mark.parametrize(
    "path,params,status,field",
    [
        ("/api/v1/views/tracks/Small line/window", {"from_m": 0, "to_m": 20_000}, 422, "to_m"),
        ("/api/v1/views/tracks/Small line/window", {"from_m": 50, "to_m": 10}, 422, "to_m"),
        ("/api/v1/views/tracks/No such line/chainage-map", {}, 404, "track"),
        ("/api/v1/views/runs/999999/profile", {}, 404, "run_id"),
        ("/api/v1/views/tracks/Small line/chainage-map", {"bins": 3}, 422, "bins"),
    ],
)
def test_bad_windows_are_refused_by_name(
    small_track: tuple[TestClient, BigTrack],
    path: str,
    params: dict[str, float],
    status: int,
    field: str,
) -> None:
    """Bad windows and unknown tracks or runs answer 4xx naming the field."""
    client, _ = small_track
    r = client.get(path, params=params)
    assert r.status_code == status
    assert r.json()["detail"]["field"] == field


def test_wide_windows_have_no_heatmap_but_say_why(
    small_track: tuple[TestClient, BigTrack],
) -> None:
    """A window wider than 10 km serves the spots only, with the reason."""
    client, _ = small_track
    body = client.get(
        "/api/v1/views/tracks/Small line/chainage-map", params={"from_m": -20_000, "to_m": 2000}
    ).json()
    assert body["heatmap"] is None and "10 km" in body["heatmap_note"]
    assert len(body["spots"]["peak_m"]) > 0


def test_csv_preview_reads_raw_logger_names_and_units(
    small_track: tuple[TestClient, BigTrack],
) -> None:
    """The preview recognises a raw IMU log's columns and units, shows the user's explicit
    choice when given, and refuses an empty file."""
    client, _ = small_track
    head = "timestamp,az_g,gyro_y_dps,speed_kmh\n" + "".join(
        f"{1763800000 + i / 1000:.3f},1.0001,0.01,72.0\n" for i in range(20)
    )
    r = client.post("/api/v1/views/csv-preview", files={"file": ("h.csv", head.encode())})
    assert r.status_code == 200
    p = r.json()
    assert p["columns"] == ["timestamp", "az_g", "gyro_y_dps", "speed_kmh"]
    assert len(p["rows"]) == 10
    assert p["mapping"] == {
        "time": "timestamp", "accel": "az_g", "pitch_rate": "gyro_y_dps", "speed": "speed_kmh",
        "chainage": None, "wheel_load": None,
        "lat": None, "lon": None,
    }  # fmt: skip
    assert p["units"]["time"] == "epoch_s" and p["units"]["accel"] == "g"
    assert p["units"]["pitch_rate"] == "deg/s" and p["units"]["speed"] == "km/h"
    assert p["gravity"] == "included"
    r = client.post(
        "/api/v1/views/csv-preview",
        files={"file": ("h.csv", head.encode())},
        data={"speed_unit": "m/s", "time_column": ""},
    )
    assert r.json()["units"]["speed"] == "m/s"
    r = client.post("/api/v1/views/csv-preview", files={"file": ("e.csv", b"")})
    assert r.status_code == 422 and r.json()["detail"]["field"] == "file"
