"""Positions from GNSS through the API (issue 11): centerline endpoints and runs uploaded with
fixes and no start chainage.

The track's GeoJSON centerline starts at chainage 11 900 m and bends (1 200 m radius); one
simulated 1 km pass at 30 m/s is logged twice with different sensor noise: once as the
baseline (true start chainage, the track's reference), once with 10 Hz fixes (1.5 m white
noise, ~1 m wandering bias) and a speed 0.6 % too high, uploaded without a start chainage.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from starlette.testclient import TestClient

from app.main import create_app
from engine.detect import robust_baseline
from engine.logio import write_run_csv
from engine.synthetic import REALISTIC_SENSOR, SyntheticRun, make_run, to_runlog
from engine.track import SoftZone
from support.app_fixtures import make_settings
from support.gnss import (
    LINE_START_CHAINAGE_M,
    RUN_OFFSET_M,
    centerline_geojson,
    csv_with_fixes,
    gnss_fixes,
    plan_xy,
    to_lonlat,
    with_fixes,
)

from .api_support import assert_zones_match, row_counts, upload

OFF = LINE_START_CHAINAGE_M + RUN_OFFSET_M  # simulated position 0 on the line's chainage
ZONES = (SoftZone(300, 306, 0.5), SoftZone(640, 645, 0.4))
SENSOR = dataclasses.replace(REALISTIC_SENSOR, sample_rate_hz=500.0)
GEOJSON = "application/geo+json"


def put_line(client: TestClient, track: str, body: Any, ctype: str = GEOJSON, **params: Any):  # type: ignore[no-untyped-def]
    data = body if isinstance(body, bytes | str) else json.dumps(body)
    return client.put(
        f"/api/v1/tracks/{track}/centerline",
        content=data,
        headers={"Content-Type": ctype},
        params=params,
    )


@dataclasses.dataclass(frozen=True)
class Pass:
    syn: SyntheticRun
    baseline_csv: bytes
    gnss_csv: bytes
    true_line_chainage: np.ndarray


@pytest.fixture(scope="module")
def one_pass() -> Pass:
    """The 1 km pass: the baseline CSV and the GNSS CSV (other noise, speed 0.6 % high)."""
    syn = make_run(
        length=1040.0, zones=ZONES, speed=30.0, sensor=SENSOR, sim_rate_hz=500.0, jitter=0.05,
        seed=7,
    )  # fmt: skip
    buf = io_csv(syn.log)
    other = to_runlog(syn.sim, SENSOR, seed=99)
    true = OFF + syn.sim.x_body[: other.n]
    lat, lon = gnss_fixes(true, other.time_s, bias_m=0.71, bias_tau_s=10.0, seed=0)
    gnss = csv_with_fixes(with_fixes(other, lat, lon, speed_factor=1.006))
    return Pass(syn, buf, gnss, true)


def io_csv(log: Any) -> bytes:
    import io

    b = io.StringIO()
    write_run_csv(log, b, digits=8)
    return b.getvalue().encode()


@pytest.fixture(scope="module")
def gnss_track(
    tmp_path_factory: pytest.TempPathFactory, one_pass: Pass
) -> Iterator[tuple[TestClient, dict[str, Any], dict[str, Any]]]:
    """Track 'Bend' with its centerline, the baseline run and the GNSS-placed run."""
    with TestClient(create_app(make_settings(tmp_path_factory.mktemp("gnss")))) as c:
        assert c.post("/api/v1/tracks", json={"name": "Bend"}).status_code == 201
        r = put_line(c, "Bend", centerline_geojson())
        assert r.status_code == 201, r.text
        base = upload(
            c, one_pass.baseline_csv, track="Bend",
            start_chainage_m=OFF + one_pass.syn.start_chainage_m,
            recorded_at="2026-01-01T08:00:00Z",
        )  # fmt: skip
        assert base.status_code == 201, base.text
        run = upload(c, one_pass.gnss_csv, track="Bend", recorded_at="2026-02-01T08:00:00Z")
        assert run.status_code == 201, run.text
        yield c, base.json(), run.json()


def test_gnss_run_is_placed_on_the_track_chainage(
    gnss_track: tuple[TestClient, dict[str, Any], dict[str, Any]], one_pass: Pass
) -> None:
    """Done means: no start chainage, the fit finds direction and scale (speed 0.6 % high),
    the chainage error stays below 1 m from end to end, and the run's JSON reports the fit."""
    client, _, run = gnss_track
    got = client.get(f"/api/v1/runs/{run['id']}").json()
    pos = got["positioning"]
    assert pos["method"] == "gnss" and pos["direction"] == "increasing"
    assert pos["scale"] == pytest.approx(1 / 1.006, abs=0.0015)
    assert pos["n_used"] >= 0.9 * pos["n_fixes"] and pos["n_fixes"] > 300
    assert pos["residual_rms_m"] < 3.0 and pos["offset_median_m"] < 4.0
    true = one_pass.true_line_chainage
    odo_end = 1.006 * (true[-1] - true[0])
    placed_start, placed_end = (
        pos["start_chainage_m"],
        pos["start_chainage_m"] + pos["scale"] * odo_end,
    )
    assert abs(placed_start - true[0]) < 1.0, (placed_start, true[0])
    assert abs(placed_end - true[-1]) < 1.0, (placed_end, true[-1])
    assert got["start_chainage_m"] == pytest.approx(placed_start)
    base = client.get(f"/api/v1/runs/{gnss_track[1]['id']}").json()
    assert base["positioning"] is None


def test_gnss_run_zones_and_profile_match_the_truth(
    gnss_track: tuple[TestClient, dict[str, Any], dict[str, Any]], one_pass: Pass
) -> None:
    """Done means: after alignment against the baseline, every zone's ends within +-1.5 m of
    the truth on the line's chainage and the profile within 0.05 mm RMS against its baseline
    (the score of engine.synthetic: residual about a 40 m robust baseline vs the truth's)."""
    client, _, run = gnss_track
    spots = client.get(f"/api/v1/runs/{run['id']}/soft-spots").json()
    truth = [{"start_m": z.start_m + OFF, "end_m": z.end_m + OFF} for z in ZONES]
    assert_zones_match([s for s in spots if s["depth_mm"] > 0], truth, tol_m=1.5)
    p = client.get(f"/api/v1/runs/{run['id']}/profile").json()
    g = np.asarray(p["chainage_m"], dtype=float)
    lv = np.array([np.nan if v is None else v for v in p["level_mm"]])
    step = float(g[1] - g[0])
    t = one_pass.syn.true_profile(g - OFF)
    t_res = t - robust_baseline(t, step, 40.0)
    e_res = lv - robust_baseline(lv, step, 40.0)
    ok = np.isfinite(t_res) & np.isfinite(e_res)
    assert ok.sum() > 800 / step
    rms = float(np.sqrt(np.mean((e_res[ok] - t_res[ok]) ** 2)))
    assert rms < 0.05, rms


def test_a_gnss_placed_run_can_be_the_reference(tmp_path: Path, one_pass: Pass) -> None:
    """On a fresh track the GNSS run comes first: it is the track's reference (offset 0)."""
    with TestClient(create_app(make_settings(tmp_path))) as c:
        c.post("/api/v1/tracks", json={"name": "Fresh"})
        assert put_line(c, "Fresh", centerline_geojson()).status_code == 201
        r = upload(c, one_pass.gnss_csv, track="Fresh")
        assert r.status_code == 201, r.text
        got = c.get(f"/api/v1/runs/{r.json()['id']}").json()
        assert got["alignment"]["status"] == "reference"
        assert got["positioning"]["method"] == "gnss"


@pytest.fixture
def lined(tmp_path: Path) -> Iterator[TestClient]:
    with TestClient(create_app(make_settings(tmp_path))) as c:
        c.post("/api/v1/tracks", json={"name": "Line"})
        assert put_line(c, "Line", centerline_geojson()).status_code == 201
        yield c


@pytest.fixture(scope="module")
def short_pass() -> SyntheticRun:
    return make_run(length=240.0, speed=30.0, sim_rate_hz=500.0, start_chainage_m=20.0)


def _short_csv(syn: SyntheticRun, **kw: Any) -> bytes:
    true = OFF + syn.sim.x_body[: syn.log.n]
    lat, lon = gnss_fixes(true, syn.log.time_s, **kw)
    return csv_with_fixes(with_fixes(syn.log, lat, lon))


def test_uploads_that_cannot_be_placed_are_refused_and_store_nothing(
    lined: TestClient, short_pass: SyntheticRun, tmp_path: Path
) -> None:
    """Fixes 50 m off the line, a log with no fixes and no start chainage, fixes of another
    line: each a 422 naming the problem; nothing is stored."""
    settings = lined.app.state.ctx.settings  # type: ignore[attr-defined]
    before = row_counts(settings)
    r = upload(lined, _short_csv(short_pass, lateral_m=50.0, seed=1), track="Line")
    assert r.status_code == 422, r.text
    d = r.json()["detail"]
    assert d["kind"] == "FixesOffLine" and 45 < d["median_offset_m"] < 55
    assert "from the track's centerline" in d["message"]

    r = upload(lined, io_csv(short_pass.log), track="Line")
    assert r.status_code == 422
    d = r.json()["detail"]
    assert d["field"] == "start_chainage_m" and "no GNSS fixes" in d["message"]

    # another line: crosses this one at right angles, the run drives along it
    n = short_pass.log.n
    x0, y0 = plan_xy(np.array([450.0]))
    dist = short_pass.sim.x_body[:n] - short_pass.sim.x_body[0] - 120.0
    lon, lat = to_lonlat(x0 + 0.5 * dist, y0 - 0.866 * dist)
    keep = np.zeros(n, bool)
    keep[::50] = True
    lat, lon = np.where(keep, lat, np.nan), np.where(keep, lon, np.nan)
    r = upload(lined, csv_with_fixes(with_fixes(short_pass.log, lat, lon)), track="Line")
    assert r.status_code == 422, r.text
    assert r.json()["detail"]["kind"] in ("FixesOffLine", "FixesDoNotFollowLine")
    assert row_counts(settings) == before


def test_without_a_centerline_the_start_chainage_is_still_needed(
    tmp_path: Path, short_pass: SyntheticRun
) -> None:
    with TestClient(create_app(make_settings(tmp_path))) as c:
        c.post("/api/v1/tracks", json={"name": "Plain"})
        r = upload(c, _short_csv(short_pass, seed=2), track="Plain")
        assert r.status_code == 422
        assert "has no centerline" in r.json()["detail"]["message"]
        # with a start chainage the fixes are simply carried along
        ok = upload(c, _short_csv(short_pass, seed=2), track="Plain", start_chainage_m=100.0)
        assert ok.status_code == 201, ok.text
        assert c.get(f"/api/v1/runs/{ok.json()['id']}").json()["positioning"] is None


# ---- centerline endpoints ------------------------------------------------------------------------


def test_a_track_says_whether_it_has_a_centerline(lined: TestClient) -> None:
    """GET /tracks and /tracks/{track} carry has_centerline, so a client need not ask for a
    centerline that answers 404 (the track page did, and the browser logged an error)."""
    lined.post("/api/v1/tracks", json={"name": "Bare"})
    flags = {t["name"]: t["has_centerline"] for t in lined.get("/api/v1/tracks").json()["data"]}
    assert flags == {"Line": True, "Bare": False}
    assert lined.get("/api/v1/tracks/Line").json()["has_centerline"] is True
    assert lined.get("/api/v1/tracks/Bare").json()["has_centerline"] is False
    assert lined.delete("/api/v1/tracks/Line/centerline").status_code == 204
    assert lined.get("/api/v1/tracks/Line").json()["has_centerline"] is False


def test_centerline_put_get_plan_delete(lined: TestClient) -> None:
    r = lined.get("/api/v1/tracks/Line/centerline")
    assert r.status_code == 200 and r.headers["content-type"].startswith(GEOJSON)
    f = r.json()
    assert f["type"] == "Feature" and f["geometry"]["type"] == "LineString"
    assert f["properties"]["start_chainage_m"] == LINE_START_CHAINAGE_M
    assert f["properties"]["end_chainage_m"] == pytest.approx(
        LINE_START_CHAINAGE_M + 1400, abs=0.05
    )
    assert len(f["properties"]["chainage_m"]) == len(f["geometry"]["coordinates"]) == 281
    plan = lined.get("/api/v1/tracks/Line/centerline/plan").json()
    assert len(plan["x_m"]) == 281
    span = np.hypot(np.ptp(plan["x_m"]), np.ptp(plan["y_m"]))
    assert 1200 < span < 1400  # the bend shortens the chord
    # replace with a plain LineString and a start chainage as query parameter: 200
    line = centerline_geojson(start_chainage_m=0.0)["geometry"]
    r = put_line(lined, "Line", line, "application/json", start_chainage_m=500.0)
    assert r.status_code == 200, r.text
    assert r.json()["start_chainage_m"] == 500.0 and r.json()["source"] == "geojson"
    # a CSV with explicit chainage
    coords = line["coordinates"]
    rows = "\n".join(f"{1000 + 5 * i},{la},{lo}" for i, (lo, la) in enumerate(coords))
    r = put_line(lined, "Line", "chainage_m,lat,lon\n" + rows + "\n", "text/csv")
    assert r.status_code == 200, r.text
    assert r.json()["start_chainage_m"] == 1000.0 and r.json()["source"] == "csv"
    assert lined.delete("/api/v1/tracks/Line/centerline").status_code == 204
    assert lined.get("/api/v1/tracks/Line/centerline").status_code == 404
    assert lined.delete("/api/v1/tracks/Line/centerline").status_code == 404
    assert put_line(lined, "Nowhere", line).status_code == 404


def _ls(coords: list[list[float]]) -> dict[str, Any]:
    return {"type": "LineString", "coordinates": coords}


@pytest.mark.parametrize(
    ("body", "ctype", "status", "words"),
    [
        (_ls([[10.0, 50.0]]), GEOJSON, 422, "1 point"),
        (_ls([[10, 50], [10.01, 50.01], [10.01, 50], [10, 50.01]]), GEOJSON, 422, "crosses itself"),
        (_ls([[50.0, 100.0], [50.01, 100.01]]), GEOJSON, 422, "swapped"),
        (_ls([[10.0, 50.0], [200.0, 50.0]]), GEOJSON, 422, "outside -180 to 180"),
        ({"type": "Point", "coordinates": [10.0, 50.0]}, GEOJSON, 422, "got type 'Point'"),
        ("{not json", GEOJSON, 422, "not valid JSON"),
        ("chainage_m,lat,lon\n0,50,10\n10,95,10\n", "text/csv", 422, "latitude 95"),
        ("chainage_m,lat,lon\n0,50,10\n", "text/csv", 422, "1 point"),
        ("<xml/>", "application/xml", 415, "unsupported content type"),
    ],
)  # fmt: skip
def test_bad_centerlines_are_refused_naming_the_problem_and_store_nothing(
    lined: TestClient, body: Any, ctype: str, status: int, words: str
) -> None:
    before = lined.get("/api/v1/tracks/Line/centerline").json()
    r = put_line(lined, "Line", body, ctype)
    assert r.status_code == status, r.text
    assert words in r.json()["detail"]["message"]
    assert lined.get("/api/v1/tracks/Line/centerline").json() == before


def test_a_10_mb_centerline_body_is_refused_with_413(lined: TestClient) -> None:
    coords = ",".join("[10.0,50.0]" for _ in range(10_000_000 // 12))
    body = '{"type":"LineString","coordinates":[' + coords + "]}"
    assert len(body) > 10_000_000
    r = put_line(lined, "Line", body)
    assert r.status_code == 413
    assert lined.get("/api/v1/tracks/Line/centerline").json()["properties"]["n_vertices"] == 281


def test_centerline_writes_need_a_key_when_keys_are_required(tmp_path: Path) -> None:
    """The access check runs before the body is read: 401 without a key."""
    with TestClient(create_app(make_settings(tmp_path, require_api_key=True))) as c:
        r = put_line(c, "Any", centerline_geojson())
        assert r.status_code == 401
