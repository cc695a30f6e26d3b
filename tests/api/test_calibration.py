"""Vehicle calibration through the API: versions, reprocessing in place, health, bad requests.

Runs are made with the engine's forward model (fixed seeds, realistic sensor written at
500 Hz) by a coach that is NOT what it is registered as: pitch inertia +30 %, suspension
-25 %, body +10 % against the Table 1 parameters it is registered with.
"""

from __future__ import annotations

import dataclasses
import io
import time
from datetime import UTC, datetime
from typing import Any

import pytest
from starlette.testclient import TestClient

from api.api_support import assert_zones_match, row_counts, sql, upload, wait_done
from engine.logio import write_run_csv
from engine.synthetic import REALISTIC_SENSOR, make_run
from engine.track import SoftZone
from engine.vehicle import TABLE1

SENSOR = dataclasses.replace(REALISTIC_SENSOR, sample_rate_hz=500.0)
REAL = TABLE1.replace(Is=TABLE1.Is * 1.3, ks1=TABLE1.ks1 * 0.75, ks2=TABLE1.ks2 * 0.75,
                      ms=TABLE1.ms * 1.1)  # fmt: skip
ZONES = [
    [SoftZone(90, 96, 0.5), SoftZone(170, 173, 0.6), SoftZone(240, 248, 0.4)],
    [SoftZone(100, 104, 0.6), SoftZone(160, 166, 0.45), SoftZone(230, 236, 0.55)],
    [SoftZone(95, 101, 0.55), SoftZone(175, 180, 0.5), SoftZone(245, 249, 0.6)],
]


def _csv_runs(vehicle, seed: int, n: int = 3) -> list[dict[str, Any]]:
    out = []
    for i in range(n):
        run = make_run(length=320.0, zones=ZONES[i], speed=(22.0, 25.0, 28.0)[i], sensor=SENSOR,
                       sim_rate_hz=1000.0, jitter=0.05, seed=seed + i, vehicle=vehicle)  # fmt: skip
        buf = io.StringIO()
        write_run_csv(run.log, buf, digits=8)
        zones = [{"start_m": z.start_m, "end_m": z.end_m} for z in ZONES[i]]
        out.append({"csv": buf.getvalue().encode(), "start": run.start_chainage_m, "zones": zones})
    return out


@pytest.fixture(scope="module")
def coach_runs() -> list[dict[str, Any]]:
    """Three runs of the real coach (registered as Table 1)."""
    return _csv_runs(REAL, 500)


@pytest.fixture(scope="module")
def healthy_runs() -> list[dict[str, Any]]:
    """Three runs of a vehicle that is exactly Table 1."""
    return _csv_runs(TABLE1, 600)


def _register(c: TestClient, name: str) -> None:
    r = c.post("/api/v1/vehicles", json={"name": name, "params": TABLE1.to_dict()})
    assert r.status_code == 201, r.text
    assert r.json()["version"] == 1


def _upload(
    c: TestClient, runs, vehicle: str, month: int = 1, tag: str = "", **load: float
) -> list[int]:
    ids = []
    for i, r in enumerate(runs):
        when = f"2026-{month:02d}-0{i + 1}T08:00:00"
        resp = upload(c, r["csv"], track=f"line-{tag}{month}-{i}", vehicle=vehicle,
                      start_chainage_m=r["start"], recorded_at=when, **load)  # fmt: skip
        assert resp.status_code in (200, 201), resp.text
        run = wait_done(c, resp.json()["id"])
        assert run["status"] == "done" and run["vehicle_version"] == 1, run
        ids.append(run["id"])
    return ids


def _wait_calibration(c: TestClient, vehicle: str, cal_id: int, timeout: float = 180.0):
    deadline = time.monotonic() + timeout
    while True:
        cal = c.get(f"/api/v1/vehicles/{vehicle}/calibrations/{cal_id}").json()
        if cal["status"] != "running" or time.monotonic() > deadline:
            return cal
        time.sleep(0.1)


def _wait_version(c: TestClient, run_id: int, version: int, timeout: float = 120.0):
    deadline = time.monotonic() + timeout
    while True:
        run = c.get(f"/api/v1/runs/{run_id}").json()
        if (run["status"] != "processing" and run["vehicle_version"] == version) or (
            time.monotonic() > deadline
        ):
            return run
        time.sleep(0.1)


@pytest.mark.slow
def test_calibration_with_apply_makes_a_version_and_reprocesses_in_place(
    client: TestClient, coach_runs
) -> None:
    """POST calibrate (apply) -> 202; the calibration finds I_s up and k_s down beyond their
    uncertainty, becomes version 2 (made by the calibration), and every run is reprocessed
    under its own id with version 2, finding its zones within ±1.5 m and nothing else."""
    _register(client, "coach")
    ids = _upload(client, coach_runs, "coach")
    r = client.post("/api/v1/vehicles/coach/calibrate", json={"apply": True})
    assert r.status_code == 202, r.text
    assert r.json()["status"] == "running"
    cal = _wait_calibration(client, "coach", r.json()["id"])
    assert cal["status"] == "done", cal
    assert cal["runs_used"] == ids and cal["vehicle_version"] == 1
    assert cal["significant"] and cal["applied"] and cal["applied_version"] == 2, cal
    fitted = {f["name"]: f for f in cal["fitted"]}
    assert fitted["Is"]["change"] > 3 * fitted["Is"]["sd"] > 0
    assert fitted["ks1"]["change"] < -3 * fitted["ks1"]["sd"] < 0
    for f in cal["fitted"]:  # applied: significant and inside the fit's range, else registered
        assert f["applied"] == (f["significant"] and not f["at_bound"]), f
        for name, value in (f["after"] if f["applied"] else f["before"]).items():
            assert cal["params"][name] == pytest.approx(value, rel=1e-9), (name, f)
    assert fitted["Is"]["applied"]
    assert cal["objective_after"] < 0.8 * cal["objective_before"]
    assert "ms" in cal["not_identified"]
    assert abs((cal["params"]["Is"] / cal["params"]["ms"]) / (REAL.Is / REAL.ms) - 1) <= 0.1
    versions = client.get("/api/v1/vehicles/coach/versions").json()
    assert versions["current"] == 2
    assert [(v["version"], v["source"], v["calibration_id"]) for v in versions["data"]] == [
        (2, "calibration", cal["id"]), (1, "created", None),
    ]  # fmt: skip
    assert versions["data"][1]["params"] == TABLE1.to_dict()
    assert client.get("/api/v1/vehicles/coach").json()["params"]["Is"] == cal["params"]["Is"]
    for run_id, run in zip(ids, coach_runs, strict=True):
        state = _wait_version(client, run_id, 2)
        assert state["status"] == "done" and state["vehicle_version"] == 2, state
        spots = client.get(f"/api/v1/runs/{run_id}/soft-spots").json()
        assert_zones_match(spots, run["zones"])
    listed = client.get("/api/v1/vehicles/coach/calibrations").json()
    assert [c["id"] for c in listed["data"]] == [cal["id"]]


@pytest.mark.slow
def test_runs_with_a_declared_payload_are_calibrated_at_their_mass(client: TestClient) -> None:
    """Three runs of the registered coach carrying 35 % of its body mass, uploaded with that
    payload_kg: the calibration compares each at the mass it was inverted with, finds nothing
    significant and leaves the registration (without the payload the fit reads the heavier body
    as a suspension 20-35 % softer: tests/engine/test_calibration.py)."""
    payload = 0.35 * TABLE1.ms
    runs = _csv_runs(TABLE1.with_body_mass(TABLE1.ms + payload), 700)
    _register(client, "laden")
    ids = _upload(client, runs, "laden", tag="laden", payload_kg=payload)
    r = client.post("/api/v1/vehicles/laden/calibrate", json={"apply": True})
    assert r.status_code == 202, r.text
    cal = _wait_calibration(client, "laden", r.json()["id"])
    assert cal["status"] == "done" and cal["runs_used"] == ids, cal
    assert cal["significant"] is False and cal["applied"] is False, cal["message"]
    assert all(abs(f["change"]) < 0.05 for f in cal["fitted"]), cal["fitted"]
    assert not any(f["applied"] for f in cal["fitted"]), cal["fitted"]
    assert client.get("/api/v1/vehicles/laden").json()["version"] == 1


@pytest.mark.slow
def test_matching_vehicle_automatic_calibration_changes_nothing(start_app, healthy_runs) -> None:
    """With automatic calibration every 3 runs, a vehicle that matches its registration is
    calibrated once, the result says 'no significant change' and is not applied."""
    c = start_app(auto_calibrate_runs=3)
    _register(c, "fit")
    ids = _upload(c, healthy_runs, "fit")
    deadline = time.monotonic() + 60
    while not (listed := c.get("/api/v1/vehicles/fit/calibrations").json())["data"]:
        assert time.monotonic() < deadline, "no automatic calibration"
        time.sleep(0.1)
    cal = _wait_calibration(c, "fit", listed["data"][0]["id"])
    assert cal["status"] == "done" and cal["automatic"] and cal["runs_used"] == ids, cal
    assert cal["significant"] is False and cal["applied"] is False
    assert "no significant change" in cal["message"]
    assert cal["details"]["apply_note"] == "not applied: no significant change"
    assert c.get("/api/v1/vehicles/fit").json()["version"] == 1
    assert all(c.get(f"/api/v1/runs/{i}").json()["vehicle_version"] == 1 for i in ids)


@pytest.mark.slow
def test_suspension_losing_stiffness_is_a_health_alert(
    client: TestClient, healthy_runs, coach_runs
) -> None:
    """Month 1 on the registered suspension, month 2 on one 25 % softer (and heavier pitch):
    the vehicle's health shows alerts for k_s1 and k_s2 from -> to, since month 2."""
    _register(client, "loco")
    m1 = _upload(client, healthy_runs, "loco", month=1, tag="h")
    m2 = _upload(client, coach_runs, "loco", month=2, tag="h")
    for ids in (m1, m2):
        r = client.post("/api/v1/vehicles/loco/calibrate", json={"run_ids": ids})
        assert r.status_code == 202, r.text
        assert _wait_calibration(client, "loco", r.json()["id"])["status"] == "done"
    health = client.get("/api/v1/vehicles/loco/health").json()
    alerts = {a["parameter"]: a for a in health["alerts"]}
    assert {"ks1", "ks2"} <= set(alerts), health
    ks1 = alerts["ks1"]
    assert ks1["after"] < ks1["before"] and ks1["change"] < -0.15 and ks1["sigmas"] > 3
    assert ks1["since"].startswith("2026-02-01") and ks1["vehicle"] == "loco"
    assert len(health["history"]) >= 6
    assert client.get("/api/v1/vehicles/loco").json()["version"] == 1  # not applied


def test_manual_edit_is_a_version_and_reprocesses(client: TestClient, healthy_runs) -> None:
    """PATCH parameters: version 2 (source manual), the run reprocessed with it; a no-op edit
    or an unknown parameter is refused and changes nothing."""
    _register(client, "edit")
    [run_id] = _upload(client, healthy_runs[:1], "edit")
    r = client.patch("/api/v1/vehicles/edit", json={"params": {"ms": 17000.0}, "note": "weighed"})
    assert r.status_code == 200, r.text
    assert r.json()["version"] == 2 and r.json()["params"]["ms"] == 17000.0
    assert _wait_version(client, run_id, 2)["status"] == "done"
    v = client.get("/api/v1/vehicles/edit/versions").json()["data"][0]
    assert (v["source"], v["note"], v["params"]["ms"]) == ("manual", "weighed", 17000.0)
    for params, field in (({"ms": 17000.0}, "params"), ({"mass": 1.0}, "params"),
                          ({"ks1": -1}, "params.ks1")):  # fmt: skip
        r = client.patch("/api/v1/vehicles/edit", json={"params": params})
        assert r.status_code == 422 and r.json()["detail"]["field"] == field, r.text
    assert client.get("/api/v1/vehicles/edit").json()["version"] == 2


def test_bad_calibration_requests(client: TestClient, settings, healthy_runs) -> None:
    """Unknown vehicle 404; runs of another vehicle, unknown runs, no runs, unknown fit, bad
    load 422 naming the field; unknown calibration 404; nothing stored."""
    _register(client, "empty")
    _register(client, "other")
    [other_run] = _upload(client, healthy_runs[:1], "other")
    before = row_counts(settings)
    cases = [
        ("/api/v1/vehicles/nope/calibrate", {}, 404, "vehicle"),
        ("/api/v1/vehicles/empty/calibrate", {}, 422, "run_ids"),
        ("/api/v1/vehicles/empty/calibrate", {"run_ids": [other_run]}, 422, "run_ids"),
        ("/api/v1/vehicles/empty/calibrate", {"run_ids": [99999]}, 422, "run_ids"),
        ("/api/v1/vehicles/empty/calibrate", {"run_ids": []}, 422, "run_ids"),
        ("/api/v1/vehicles/other/calibrate", {"fit": ["mass"]}, 422, "fit"),
        ("/api/v1/vehicles/other/calibrate", {"fit": ["ks", "ks1"]}, 422, "fit"),
        ("/api/v1/vehicles/other/calibrate", {"load_kg": -3}, 422, "load_kg"),
        ("/api/v1/vehicles/other/calibrate", {"apply": "maybe"}, 422, "apply"),
    ]
    for url, body, status, field in cases:
        r = client.post(url, json=body)
        assert r.status_code == status, (url, body, r.text)
        assert r.json()["detail"]["field"] == field, (body, r.json())
    assert (
        "another vehicle"
        in client.post("/api/v1/vehicles/empty/calibrate", json={"run_ids": [other_run]}).json()[
            "detail"
        ]["message"]
    )
    assert row_counts(settings) == before
    r = client.get("/api/v1/vehicles/other/calibrations/12345")
    assert r.status_code == 404
    assert client.get("/api/v1/vehicles/nope/health").status_code == 404


def test_calibration_of_a_dead_worker_is_taken_over(start_app, settings, healthy_runs) -> None:
    """A calibration claimed by a worker that stopped beating is resumed by another process
    (from the start) once its lease is over, like a run."""
    c = start_app(start_worker=False)
    _register(c, "resume")
    _upload(c, healthy_runs[:1], "resume")
    cal_id = c.post("/api/v1/vehicles/resume/calibrate", json={}).json()["id"]
    now = datetime.now(UTC).replace(tzinfo=None)
    sql(settings, "UPDATE calibrations SET status='running', claimed_by='elsewhere:1:abc', "
        "heartbeat_at=:now, attempts=1 WHERE id=:id", now=now, id=cal_id)  # fmt: skip
    assert c.get(f"/api/v1/vehicles/resume/calibrations/{cal_id}").json()["status"] == "running"
    other = start_app(lease_s=1.0)
    assert _wait_calibration(other, "resume", cal_id)["status"] == "done"
    [(owner, attempts)] = sql(
        settings, "SELECT claimed_by, attempts FROM calibrations WHERE id=:id", id=cal_id
    )
    assert owner != "elsewhere:1:abc" and attempts == 2
