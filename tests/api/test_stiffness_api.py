"""Geometry vs stiffness through the API: wheel force per run, declared loads, vehicle presets,
reference surveys (and their bad inputs), the track's stiffness endpoint and the honesty
message where one wheel load cannot separate geometry from stiffness.

The accuracy of the separation itself is checked end to end in
``test_geometry_separation.py``; here the contracts: fields, units, errors naming the field,
column and row, nothing stored on a bad input, windows and CSV.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from starlette.testclient import TestClient

from app.core.config import Settings
from engine.vehicle import PRESETS

from .api_support import row_counts, upload

TRACK = "stiff line"


@pytest.fixture
def stored(client: TestClient, synthetic_run: dict[str, Any]) -> dict[str, Any]:
    """One straight-rail table1 run (160 m, a 50 % zone at 70-75 m) on TRACK."""
    r = upload(
        client, synthetic_run["csv"], track=TRACK,
        start_chainage_m=synthetic_run["start_chainage_m"],
    )  # fmt: skip
    assert r.status_code == 201, r.text
    return dict(r.json())


def survey_csv(client: TestClient, run_id: int, shift_m: float = 0.0, step: int = 1) -> bytes:
    """A survey made of a stored run's own profile (chainage shifted by ``shift_m``)."""
    prof = client.get(f"/api/v1/runs/{run_id}/profile").json()
    x = np.asarray(prof["chainage_m"])[::step] + shift_m
    y = np.array([np.nan if v is None else v for v in prof["level_mm"]])[::step]
    ok = np.isfinite(y)
    rows = [f"{a:.3f},{b:.5f}" for a, b in zip(x[ok], y[ok], strict=True)]
    lines = ["chainage_m,level_mm", *rows]
    return ("\n".join(lines) + "\n").encode()


def post_survey(client: TestClient, data: bytes, **fields: Any) -> Any:
    form = {k: str(v) for k, v in fields.items() if v is not None}
    return client.post(
        f"/api/v1/tracks/{TRACK}/surveys", files={"file": ("survey.csv", data, "text/csv")},
        data=form,
    )  # fmt: skip


def test_run_carries_wheel_force_per_axle(client: TestClient, stored: dict[str, Any]) -> None:
    """The profile endpoint serves each axle's wheel force (N) beside the level, in JSON and
    CSV; the run reports its mean wheel force, about Table 1's static wheel load."""
    rid = stored["id"]
    js = client.get(
        f"/api/v1/runs/{rid}/profile", params={"include": "front_force_n,rear_force_n"}
    ).json()
    front = np.array([np.nan if v is None else v for v in js["front_force_n"]])
    rear = np.array([np.nan if v is None else v for v in js["rear_force_n"]])
    f1, f2 = PRESETS["table1"].static_axle_loads()
    assert np.nanmedian(front) == pytest.approx(f1, rel=0.05)
    assert np.nanmedian(rear) == pytest.approx(f2, rel=0.05)
    assert stored["mean_wheel_force_n"] == pytest.approx(0.5 * (f1 + f2), rel=0.05)
    csv = client.get(
        f"/api/v1/runs/{rid}/profile",
        params={"include": "front_force_n", "format": "csv", "from_m": 60, "to_m": 61},
    ).text.splitlines()
    assert csv[0] == "chainage_m,level_mm,front_force_n"
    assert float(csv[1].split(",")[2]) == pytest.approx(f1, rel=0.05)


def test_declared_load_sets_the_wheel_force(
    client: TestClient, synthetic_run: dict[str, Any], settings: Settings
) -> None:
    """A measured static wheel load (N) or a payload (kg) changes the run's wheel force by
    what it declares; both at once, a negative payload or a wheel load below the axles'
    own weight are 422 naming the field, and nothing is stored."""
    f1, f2 = PRESETS["table1"].static_axle_loads()
    r = upload(
        client, synthetic_run["csv"], track="loads", static_wheel_load_n=120_000,
        start_chainage_m=synthetic_run["start_chainage_m"],
    )  # fmt: skip
    assert r.status_code == 201, r.text
    assert r.json()["static_wheel_load_n"] == 120_000
    assert r.json()["mean_wheel_force_n"] == pytest.approx(120_000, rel=0.03)
    r = upload(
        client, synthetic_run["csv"], track="loads 2", payload_kg=4000,
        start_chainage_m=synthetic_run["start_chainage_m"],
    )  # fmt: skip
    assert r.status_code == 201, r.text
    assert r.json()["mean_wheel_force_n"] == pytest.approx(0.5 * (f1 + f2) + 2000 * 9.81, rel=0.03)
    before = row_counts(settings)
    for fields, field in (
        ({"payload_kg": 100, "static_wheel_load_n": 90_000}, None),
        ({"payload_kg": -5}, "payload_kg"),
        ({"static_wheel_load_n": 5_000}, "static_wheel_load_n"),
        ({"static_wheel_load_n": "heavy"}, "static_wheel_load_n"),
    ):
        r = upload(
            client, synthetic_run["csv"], track="loads 3",
            start_chainage_m=synthetic_run["start_chainage_m"], **fields,
        )  # fmt: skip
        assert r.status_code == 422, (fields, r.text)
        detail = r.json()["detail"]
        if field is not None:
            assert detail["field"] == field, detail
        assert "payload_kg" in detail["message"] or "static_wheel_load_n" in detail["message"]
    assert row_counts(settings) == before


def test_vehicle_presets_by_name(client: TestClient, synthetic_run: dict[str, Any]) -> None:
    """The engine's presets are listed, usable as a vehicle name in an upload (stored on first
    use with the preset's parameters) and as a starting point of a new vehicle."""
    presets = client.get("/api/v1/vehicles/presets").json()
    assert set(presets) >= {"table1", "heavy"}
    assert presets["heavy"]["ms"] == PRESETS["heavy"].ms
    r = upload(
        client, synthetic_run["csv"], track="preset line", vehicle="heavy",
        start_chainage_m=synthetic_run["start_chainage_m"],
    )  # fmt: skip
    assert r.status_code == 201, r.text
    assert r.json()["vehicle"] == "heavy"
    heavy = client.get("/api/v1/vehicles/heavy").json()
    assert heavy["params"] == pytest.approx(PRESETS["heavy"].to_dict())
    r = client.post(
        "/api/v1/vehicles", json={"name": "loco 7", "preset": "heavy", "params": {"ms": 40000}}
    )
    assert r.status_code == 201, r.text
    assert r.json()["params"]["ms"] == 40000
    assert r.json()["params"]["kt1"] == PRESETS["heavy"].kt1
    r = client.post("/api/v1/vehicles", json={"name": "loco 8", "preset": "steam"})
    assert r.status_code == 422
    assert r.json()["detail"]["field"] == "preset"
    r = upload(
        client, synthetic_run["csv"], track="preset line", vehicle="no such",
        start_chainage_m=synthetic_run["start_chainage_m"],
    )  # fmt: skip
    assert r.status_code == 422
    assert "heavy" in r.json()["detail"]["message"]


def test_survey_is_stored_aligned_listed_and_deleted(
    client: TestClient, stored: dict[str, Any], settings: Settings
) -> None:
    """A survey at another wheel load is aligned to the track (its chainage error found),
    listed, contributes to the stiffness answer with its load, and is deleted."""
    data = survey_csv(client, stored["id"], shift_m=1.5)
    r = post_survey(client, data, wheel_load_n=150_000, name="EM 250 2026-03")
    assert r.status_code == 201, r.text
    survey = r.json()
    assert survey["alignment_status"] == "aligned"
    assert survey["chainage_offset_m"] == pytest.approx(-1.5, abs=0.3)
    assert survey["wheel_load_n"] == 150_000
    assert (survey["band_min_m"], survey["band_max_m"]) == (3.0, 25.0)
    again = post_survey(client, data, wheel_load_n=150_000)
    assert again.status_code == 200 and again.json()["duplicate"] is True
    listed = client.get(f"/api/v1/tracks/{TRACK}/surveys").json()
    assert [s["id"] for s in listed] == [survey["id"]]
    st = client.get(f"/api/v1/tracks/{TRACK}/stiffness").json()
    kinds = {(c["kind"], c["id"]): c for c in st["contributors"]}
    assert kinds[("survey", survey["id"])]["mean_force_n"] == pytest.approx(150_000)
    run_c = kinds[("run", stored["id"])]
    assert run_c["vehicle"] == "table1"
    assert run_c["mean_force_n"] == pytest.approx(stored["mean_wheel_force_n"], rel=0.02)
    assert max(v for v in st["load_ratio"] if v is not None) > 1.5
    # realigning the track (python -m app realign) aligns the survey again, to the same place
    from app.db.session import Database
    from app.services.track.surveys import realign_surveys

    db = Database(settings.sqlalchemy_url)
    try:
        with db.session() as s:
            (again,) = realign_surveys(s, stored["track_id"])
            s.commit()
            assert again.chainage_offset_m == pytest.approx(survey["chainage_offset_m"], abs=0.01)
    finally:
        db.engine.dispose()
    st2 = client.get(f"/api/v1/tracks/{TRACK}/stiffness").json()
    assert {(c["kind"], c["id"]) for c in st2["contributors"]} == set(kinds)
    r = client.delete(f"/api/v1/tracks/{TRACK}/surveys/{survey['id']}")
    assert r.status_code == 204
    assert client.get(f"/api/v1/tracks/{TRACK}/surveys").json() == []
    st = client.get(f"/api/v1/tracks/{TRACK}/stiffness").json()
    assert [c["kind"] for c in st["contributors"]] == ["run"]
    assert client.delete(f"/api/v1/tracks/{TRACK}/surveys/{survey['id']}").status_code == 404


def _bad_surveys(good: bytes) -> list[tuple[str, bytes, dict[str, Any], dict[str, Any]]]:
    lines = good.decode().splitlines()
    swapped = lines[:]
    swapped[40], swapped[41] = swapped[41], swapped[40]
    nan = lines[:]
    nan[30] = nan[30].split(",")[0] + ",nan"
    absurd = lines[:]
    absurd[25] = absurd[25].split(",")[0] + ",350"
    text = lines[:]
    text[12] = text[12].split(",")[0] + ",0.2mm"

    def csv(rows: list[str]) -> bytes:
        return ("\n".join(rows) + "\n").encode()

    load = {"wheel_load_n": 150_000}
    return [
        ("missing level column", csv([ln.split(",")[0] for ln in lines]), load,
         {"column": "level_mm", "row": 1}),
        ("missing chainage column", csv(["x,level_mm", *lines[1:]]), load,
         {"column": "chainage_m", "row": 1}),
        ("non-monotonic chainage", csv(swapped), load, {"column": "chainage_m", "row": 42}),
        ("NaN level", csv(nan), load, {"column": "level_mm", "row": 31}),
        ("absurd level", csv(absurd), load, {"column": "level_mm", "row": 26}),
        ("level with text", csv(text), load, {"column": "level_mm", "row": 13}),
        ("no wheel load", good, {}, {"field": "wheel_load_n"}),
        ("wheel load not a number", good, {"wheel_load_n": "lots"}, {"field": "wheel_load_n"}),
        ("band upside down", good, {**load, "band_min_m": 30, "band_max_m": 3}, {}),
        ("empty file", b"", load, {"field": "file"}),
    ]  # fmt: skip


def test_bad_surveys_are_422_naming_column_and_row(
    client: TestClient, stored: dict[str, Any], settings: Settings
) -> None:
    """Every bad survey is answered 422 naming the column and row (or the field), and nothing
    is stored: every table keeps its row count."""
    good = survey_csv(client, stored["id"])
    before = row_counts(settings)
    for what, data, fields, expect in _bad_surveys(good):
        r = post_survey(client, data, **fields)
        assert r.status_code == 422, (what, r.text)
        detail = r.json()["detail"]
        for k, v in expect.items():
            assert detail.get(k) == v, (what, detail)
        assert detail["message"], what
    assert row_counts(settings) == before
    r = client.post(f"/api/v1/tracks/{TRACK}/surveys", json={"csv": good.decode()})
    assert r.status_code == 422 and r.json()["detail"]["field"] == "wheel_load_n"
    r = client.post("/api/v1/tracks/nowhere/surveys", json={"csv": "x", "wheel_load_n": 1e5})
    assert r.status_code == 404


def test_one_load_is_not_separable_and_says_so(client: TestClient, stored: dict[str, Any]):
    """With one vehicle's runs only, the stiffness answer has no stiffness or geometry
    figure, no soft spot, and the message in plain words (JSON and CSV)."""
    st = client.get(f"/api/v1/tracks/{TRACK}/stiffness").json()
    assert st["n"] > 400 and st["separable"] is False
    assert st["message"].startswith("Geometry and stiffness are not separable at ")
    assert "different, or a survey, would separate them" in st["message"]
    assert any(s["reason"] == "load" for s in st["not_separable"])
    assert all(v is None for v in st["k_rel"]) and all(v is None for v in st["geometry_mm"])
    assert st["soft_spots"] == []
    csv = client.get(f"/api/v1/tracks/{TRACK}/stiffness", params={"format": "csv"}).text
    first, header = csv.splitlines()[:2]
    assert first == f"# {st['message']}"
    assert header.startswith("chainage_m,k_rel,k_rel_lo,k_rel_hi,geometry_mm")


def test_stiffness_window(client: TestClient, stored: dict[str, Any]) -> None:
    """from_m/to_m select a window (inclusive, 0.25 m grid); to_m before from_m is 422
    naming to_m; an unknown track 404."""
    url = f"/api/v1/tracks/{TRACK}/stiffness"
    st = client.get(url, params={"from_m": 50, "to_m": 60}).json()
    assert st["chainage_m"][0] == 50 and st["chainage_m"][-1] == 60 and st["n"] == 41
    assert len(st["k_rel"]) == len(st["separable_at"]) == 41
    csv = client.get(url, params={"from_m": 50, "to_m": 60, "format": "csv"}).text
    assert len([ln for ln in csv.splitlines() if not ln.startswith("#")]) == 42
    r = client.get(url, params={"from_m": 60, "to_m": 50})
    assert r.status_code == 422 and r.json()["detail"]["field"] == "to_m"
    assert client.get("/api/v1/tracks/nowhere/stiffness").status_code == 404
    empty = client.get(url, params={"from_m": 5000, "to_m": 6000}).json()
    assert empty["n"] == 0 and empty["message"] is None


def test_simulate_with_a_preset_and_rail_geometry(client: TestClient) -> None:
    """POST /simulate takes a vehicle preset by name and a rail-geometry spectrum with its
    seed: the run is inverted with the heavy vehicle's wheel load, and over that rough rail its
    dips come by depth only, with the message; an unknown spectrum is 422 naming the field."""
    spectra = client.get("/api/v1/simulate/spectra").json()
    assert "german-low" in spectra
    body = {
        "track": "rough", "vehicle": "heavy", "length_m": 300, "speed_mps": 24,
        "zones": [{"start_m": 150, "end_m": 157, "loss": 0.5}], "start_chainage_m": 12,
        "irregularity": {"spectrum": "german-low", "seed": 3},
    }  # fmt: skip
    r = client.post("/api/v1/simulate", json=body)
    assert r.status_code == 201, r.text
    run = r.json()["run"]
    assert run["vehicle"] == "heavy"
    assert run["mean_wheel_force_n"] == pytest.approx(
        sum(PRESETS["heavy"].static_axle_loads()) / 2, rel=0.05
    )
    assert run["stiffness_basis"] == "not separable"
    assert run["stiffness_message"].startswith("dips: geometry and stiffness not separable")
    spots = client.get(f"/api/v1/runs/{run['id']}/soft-spots").json()
    assert all(s["stiffness_loss_pct"] is None for s in spots)
    r = client.post("/api/v1/simulate", json={**body, "irregularity": {"spectrum": "bumpy"}})
    assert r.status_code == 422
    assert r.json()["detail"]["field"] == "irregularity.spectrum"


def _with_load_column(csv: bytes, header: str, value: str) -> bytes:
    lines = csv.decode().splitlines()
    return (
        "\n".join([f"{lines[0]},{header}"] + [f"{ln},{value}" for ln in lines[1:]]) + "\n"
    ).encode()


def test_load_weigh_column_sets_the_wheel_force(
    client: TestClient, synthetic_run: dict[str, Any], settings: Settings
) -> None:
    """A log's load-weigh column is the run's static wheel load (its median), unless the
    upload declares one; a load the vehicle cannot have is a 422 naming the column option,
    and nothing is stored."""
    csv = _with_load_column(synthetic_run["csv"], "wheel_load_kn", "120")
    start = synthetic_run["start_chainage_m"]
    r = upload(client, csv, track="weighed", start_chainage_m=start)
    assert r.status_code == 201, r.text
    assert r.json()["static_wheel_load_n"] == pytest.approx(120_000)
    assert r.json()["mean_wheel_force_n"] == pytest.approx(120_000, rel=0.03)
    r = upload(client, csv, track="weighed 2", start_chainage_m=start, static_wheel_load_n=100_000)
    assert r.status_code == 201, r.text
    assert r.json()["static_wheel_load_n"] == 100_000  # declared wins over the column
    r = upload(client, csv, track="weighed 3", start_chainage_m=start, payload_kg=0)
    assert r.json()["static_wheel_load_n"] is None  # a payload says the load instead
    before = row_counts(settings)
    light = _with_load_column(synthetic_run["csv"], "wheel_load_kn", "6")  # below the axles
    r = upload(client, light, track="weighed 4", start_chainage_m=start)
    assert r.status_code == 422, r.text
    assert r.json()["detail"]["field"] == "wheel_load_column"
    assert row_counts(settings) == before


def test_survey_bodies_that_are_not_a_survey_upload(client: TestClient, settings: Settings):
    """The survey intake refuses, naming what is wrong, and stores nothing: a content type it
    does not take (415 naming Content-Type), a form without its file part or with ``file`` as
    a text field (422 naming file), a JSON body that is not JSON (422)."""
    url = f"/api/v1/tracks/{TRACK}/surveys"
    before = row_counts(settings)
    r = client.post(
        url, content=b"chainage_m,level_mm\n0,0\n", headers={"content-type": "text/csv"}
    )
    assert r.status_code == 415, r.text
    assert r.json()["detail"]["field"] == "Content-Type"
    assert "multipart/form-data or application/json" in r.json()["detail"]["message"]
    r = client.post(
        url, files={"other": ("x.txt", b"x", "text/plain")}, data={"wheel_load_n": "1e5"}
    )
    assert r.status_code == 422 and r.json()["detail"]["field"] == "file", r.text
    assert "(the survey CSV)" in r.json()["detail"]["message"]
    r = client.post(url, files={"x": (None, b"")}, data={"file": "text", "wheel_load_n": "1e5"})
    assert r.status_code == 422 and r.json()["detail"]["field"] == "file", r.text
    assert "not a text field" in r.json()["detail"]["message"]
    r = client.post(url, content=b"{not json", headers={"content-type": "application/json"})
    assert r.status_code == 422, r.text
    assert row_counts(settings) == before
