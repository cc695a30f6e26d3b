"""Positions from GNSS, hardened (issue 28): bodies the centerline and survey routes could not
read answer 4xx naming the problem and store nothing; a CSV chainage far from the line's
length and a run steadily beside its track are refused; the lateral offset is reported; the
request schemas say what the routes take.

The track 'Line' has the synthetic bent centerline of tests/support/gnss.py (chainage from
11 900 m); runs are a simulated 240 m pass at 30 m/s with 10 Hz fixes.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from starlette.testclient import TestClient

from app.main import create_app
from engine.positioning import LATERAL_TOLERANCE_M
from engine.synthetic import SyntheticRun, make_run
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

from .api_support import row_counts, upload

OFF = LINE_START_CHAINAGE_M + RUN_OFFSET_M
GEOJSON = "application/geo+json"
BIG_FIELD = "1" * 140_000  # over the csv module's 128 KB field limit


def put_line(client: TestClient, body: str, ctype: str = GEOJSON) -> Any:
    return client.put(
        "/api/v1/tracks/Line/centerline", content=body, headers={"Content-Type": ctype}
    )


@pytest.fixture
def lined(tmp_path: Path) -> Iterator[TestClient]:
    import json

    with TestClient(create_app(make_settings(tmp_path))) as c:
        c.post("/api/v1/tracks", json={"name": "Line"})
        assert put_line(c, json.dumps(centerline_geojson())).status_code == 201
        yield c


@pytest.fixture(scope="module")
def short_pass() -> SyntheticRun:
    return make_run(length=240.0, speed=30.0, sim_rate_hz=500.0, start_chainage_m=20.0)


def _csv_rows(factor: float) -> str:
    s = np.arange(0.0, 1000.0, 10.0)
    lon, lat = to_lonlat(*plan_xy(s))
    rows = "\n".join(
        f"{factor * c:.3f},{b:.9f},{a:.9f}" for c, a, b in zip(s, lon, lat, strict=True)
    )
    return "chainage_m,lat,lon\n" + rows + "\n"


@pytest.mark.parametrize(
    ("body", "ctype", "field", "words"),
    [
        ("[" * 500_000 + "]" * 500_000, GEOJSON, "body", "nested too deeply"),
        ('{"type": "LineString", "coordinates": [[1' + "0" * 4999 + ", 50], [10, 50.01]]}",
         GEOJSON, "body", "integer of 5000 digits"),
        ("chainage_m,lat,lon\n0,50," + BIG_FIELD + "\n10,50.0001,10\n", "text/csv", "body",
         "line 2: not a readable CSV row"),
        (_csv_rows(1.39), "text/csv", "chainage_m",
         "runs 1376.1 m along the line but the line is 990.0 m long"),
    ],
    ids=["nested-500000", "int-5000-digits", "csv-field-140KB", "chainage-39pc-long"],
)  # fmt: skip
def test_unreadable_centerlines_answer_422_naming_the_problem_and_store_nothing(
    lined: TestClient, body: str, ctype: str, field: str, words: str
) -> None:
    """What answered 500 (deep nesting, a 5 000-digit integer, a CSV field over 128 KB) and a
    CSV chainage 39 % longer than the line: 422 with the field and the reason; the stored
    line is unchanged."""
    before = lined.get("/api/v1/tracks/Line/centerline").json()
    r = put_line(lined, body, ctype)
    assert r.status_code == 422, r.text[:500]
    detail = r.json()["detail"]
    assert words in detail["message"] and detail["field"] == field
    assert lined.get("/api/v1/tracks/Line/centerline").json() == before


def test_a_csv_chainage_within_5_percent_of_the_length_is_kept(lined: TestClient) -> None:
    r = put_line(lined, _csv_rows(1.02), "text/csv")
    assert r.status_code == 200, r.text
    assert r.json()["end_chainage_m"] == pytest.approx(1.02 * 990.0)


def _survey_csv() -> str:
    x = np.arange(0.0, 300.0, 0.25)
    return "chainage_m,level_mm\n" + "\n".join(f"{c:.2f},{0.1 * np.sin(c / 5):.4f}" for c in x)


def test_survey_csv_field_over_128_kb_and_empty_json_csv_answer_422(lined: TestClient) -> None:
    """A survey CSV with a field over 128 KB (multipart and JSON) is 422 naming the row; a
    JSON survey with "csv": "" says the CSV is empty (not "Field required"); nothing stored."""
    settings = lined.app.state.ctx.settings  # type: ignore[attr-defined]
    before = row_counts(settings)
    bad = _survey_csv().replace("\n0.25,", "\n" + BIG_FIELD + ",", 1)
    url = "/api/v1/tracks/Line/surveys"
    r = lined.post(url, files={"file": ("s.csv", bad.encode(), "text/csv")},
                   data={"wheel_load_n": "60000"})  # fmt: skip
    assert r.status_code == 422, r.text[:500]
    d = r.json()["detail"]
    assert (
        d["field"] == "file" and d["row"] == 3 and "row 3: not a readable CSV row" in d["message"]
    )
    r = lined.post(url, json={"wheel_load_n": 60000, "csv": bad})
    assert r.status_code == 422 and r.json()["detail"]["row"] == 3, r.text[:500]
    r = lined.post(url, json={"wheel_load_n": 60000, "csv": ""})
    assert r.status_code == 422, r.text
    d = r.json()["detail"]
    assert "the survey CSV is empty" in d["message"] and "required" not in d["message"]
    assert row_counts(settings) == before
    # the same survey without the long field is stored
    assert lined.post(url, json={"wheel_load_n": 60000, "csv": _survey_csv()}).status_code == 201


def _gnss_csv(syn: SyntheticRun, lateral_m: float, seed: int) -> bytes:
    true = OFF + syn.sim.x_body[: syn.log.n]
    lat, lon = gnss_fixes(true, syn.log.time_s, lateral_m=lateral_m, bias_m=0.5, seed=seed)
    return csv_with_fixes(with_fixes(syn.log, lat, lon))


def test_a_run_8_m_beside_the_line_is_refused_and_a_placed_run_reports_its_offset(
    lined: TestClient, short_pass: SyntheticRun
) -> None:
    """Fixes a steady 8 m to the right (the neighbouring track?): 422 FixesBesideLine with the
    signed offset, nothing stored. A run 1 m to the left is placed and GET /runs/{id} reports
    its lateral offset (+1 m: left, looking towards increasing chainage)."""
    settings = lined.app.state.ctx.settings  # type: ignore[attr-defined]
    before = row_counts(settings)
    r = upload(lined, _gnss_csv(short_pass, -8.0, seed=3), track="Line")
    assert r.status_code == 422, r.text
    d = r.json()["detail"]
    assert d["kind"] == "FixesBesideLine" and d["field"] == "file"
    assert -8.8 < d["lateral_offset_m"] < -7.2 and 7.2 < d["median_offset_m"] < 8.8
    assert "to its right" in d["message"] and "neighbouring track" in d["message"]
    assert f"at most {LATERAL_TOLERANCE_M:g} m" in d["message"]
    assert row_counts(settings) == before

    r = upload(lined, _gnss_csv(short_pass, 1.0, seed=4), track="Line")
    assert r.status_code == 201, r.text
    pos = lined.get(f"/api/v1/runs/{r.json()['id']}").json()["positioning"]
    assert 0.3 < pos["lateral_offset_m"] < 2.0  # the 7 s run's GNSS bias: +-0.5 m per axis
    assert pos["n_considered"] <= pos["n_fixes"] and pos["n_used"] <= pos["n_considered"]


def test_request_schemas_say_what_the_routes_take(lined: TestClient) -> None:
    """The centerline body is a GeoJSON LineString / Feature / FeatureCollection schema with
    [lon, lat] positions, or a CSV string; the survey multipart body takes no other fields."""
    spec = lined.get("/openapi.json").json()
    body = spec["paths"]["/api/v1/tracks/{track}/centerline"]["put"]["requestBody"]["content"]
    geo = body["application/geo+json"]["schema"]
    assert [s["title"] for s in geo["oneOf"]] == ["LineString", "Feature", "FeatureCollection"]
    coords = geo["oneOf"][0]["properties"]["coordinates"]
    assert coords["minItems"] == 2 and coords["items"]["minItems"] == 2
    assert body["text/csv"]["schema"]["type"] == "string"
    assert "chainage_m" in body["text/csv"]["schema"]["description"]
    survey = spec["paths"]["/api/v1/tracks/{track}/surveys"]["post"]["requestBody"]["content"]
    assert survey["multipart/form-data"]["schema"]["additionalProperties"] is False
    r = lined.post(
        "/api/v1/tracks/Line/surveys",
        files={"file": ("s.csv", _survey_csv().encode(), "text/csv")},
        data={"wheel_load_n": "60000", "colour": "red"},
    )
    assert r.status_code == 422 and "colour" in r.text, r.text


def test_placement_holds_a_processing_slot_and_keeps_to_the_budget(
    tmp_path: Path, short_pass: SyntheticRun, monkeypatch: pytest.MonkeyPatch
) -> None:
    """GNSS placement is a processing stage: it runs holding a processing slot (no slot is
    free while it runs; the service has one by default), and a placement past the processing
    budget is 422 BudgetExceeded naming the stage, nothing stored."""
    import json

    import app.services.run_lifecycle.accept as accept

    body = _gnss_csv(short_pass, 0.0, seed=4)
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    with TestClient(create_app(make_settings(tmp_path / "a", workers=1))) as c:
        c.post("/api/v1/tracks", json={"name": "Line"})
        assert put_line(c, json.dumps(centerline_geojson())).status_code == 201
        slots = c.app.state.ctx.slots  # type: ignore[attr-defined]
        free_while_placing: list[bool] = []
        place = accept.place_by_gnss

        def spy(*args: Any, **kwargs: Any) -> Any:
            free = slots.acquire(blocking=False)
            if free:
                slots.release()
            free_while_placing.append(free)
            return place(*args, **kwargs)

        monkeypatch.setattr(accept, "place_by_gnss", spy)
        assert upload(c, body, track="Line").status_code == 201
        assert free_while_placing == [False]

    settings = make_settings(tmp_path / "b", processing_budget_s=1e-6)
    with TestClient(create_app(settings)) as c:
        c.post("/api/v1/tracks", json={"name": "Line"})
        assert put_line(c, json.dumps(centerline_geojson())).status_code == 201
        before = row_counts(settings)
        r = upload(c, body, track="Line")
        assert r.status_code == 422, r.text
        d = r.json()["detail"]
        assert d["kind"] == "BudgetExceeded" and "GNSS placement took longer" in d["message"]
        assert "projecting the GNSS fixes" in d["message"]
        assert row_counts(settings) == before
