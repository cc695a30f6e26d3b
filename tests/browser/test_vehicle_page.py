"""The vehicle page in a real browser: parameters and versions, calibrations with the plot of
the fit, suspension-health alerts, and the calibrate button.

A vehicle registered as Table 1 logs two runs in January with a suspension 25 % softer than
registered (and a heavier pitch inertia), then two runs in February as registered: the two
calibrations (from each month's runs) disagree on k_s far beyond their uncertainty, which the
page shows as health alerts. Runs come from the engine's forward model (fixed seeds).
"""

from __future__ import annotations

import dataclasses
import io
import time
from pathlib import Path
from typing import Any

import pytest
from browser.harness import LiveServer, axe_source, axe_violations, wait_for_plot

from engine.logio import write_run_csv
from engine.synthetic import REALISTIC_SENSOR, make_run
from engine.track import SoftZone
from engine.vehicle import TABLE1

SENSOR = dataclasses.replace(REALISTIC_SENSOR, sample_rate_hz=500.0)
SOFT = TABLE1.replace(Is=TABLE1.Is * 1.3, ks1=TABLE1.ks1 * 0.75, ks2=TABLE1.ks2 * 0.75)
NAME = "bt-coach"


def _upload(api: Any, vehicle, month: int, seed: int) -> list[int]:
    ids = []
    for i in range(2):
        run = make_run(length=300.0, zones=[SoftZone(120, 126, 0.5), SoftZone(200, 204, 0.6)],
                       speed=(23.0, 27.0)[i], sensor=SENSOR, sim_rate_hz=1000.0, jitter=0.05,
                       seed=seed + i, vehicle=vehicle)  # fmt: skip
        buf = io.StringIO()
        write_run_csv(run.log, buf, digits=8)
        r = api.post(
            "/api/v1/runs",
            files={"file": ("run.csv", buf.getvalue().encode(), "text/csv")},
            data={
                "track": f"{NAME}-{month}-{i}",
                "vehicle": NAME,
                "start_chainage_m": str(run.start_chainage_m),
                "recorded_at": f"2026-{month:02d}-1{i}T09:00:00",
            },  # fmt: skip
        )
        assert r.status_code in (200, 201), r.text
        ids.append(r.json()["id"])
    return ids


def _calibrate(api: Any, run_ids: list[int]) -> None:
    r = api.post(f"/api/v1/vehicles/{NAME}/calibrate", json={"run_ids": run_ids})
    assert r.status_code == 202, r.text
    deadline = time.monotonic() + 120
    while (
        api.get(f"/api/v1/vehicles/{NAME}/calibrations/{r.json()['id']}").json()["status"]
        == "running"
    ):
        assert time.monotonic() < deadline
        time.sleep(0.2)


@pytest.mark.slow
def test_vehicle_page_shows_versions_calibrations_health_and_calibrates(
    page: Any, live_server: LiveServer, screenshots: Path
) -> None:
    """The page lists the parameters (version 1), both calibrations with their objective and
    the plot of the fit, health alerts on k_s1/k_s2 (from -> to, since February); the
    Calibrate button queues a third calibration that appears when done; axe finds no serious
    or critical violation on the page."""
    with live_server.api() as api:
        r = api.post("/api/v1/vehicles", json={"name": NAME, "params": TABLE1.to_dict()})
        assert r.status_code == 201, r.text
        jan = _upload(api, SOFT, 1, 700)
        feb = _upload(api, TABLE1, 2, 710)
        _calibrate(api, jan)
        _calibrate(api, feb)
    page.goto(f"{live_server.url}/#/vehicles")
    page.click(f"#vehicle-list a:text-is('{NAME}')")
    page.wait_for_selector("#calibrations-table")
    assert "version 1" in page.inner_text("#vehicle-params h2")
    assert "111193" in page.inner_text("#params-table")
    rows = page.locator("#calibrations-table tbody tr")
    assert rows.count() == 2
    assert "done" in rows.nth(0).inner_text() and "→" in rows.nth(0).inner_text()
    alerts = page.inner_text("#health-alerts")
    assert "ks1" in alerts and "ks2" in alerts and "2026-02" in alerts
    wait_for_plot(page, "#calibration-plot", min_traces=3)
    assert page.locator("#versions-table tbody tr").count() == 1
    page.screenshot(path=str(screenshots / "vehicle.png"), full_page=True)
    assert axe_violations(page, axe_source()) == []

    page.click("#calibrate")
    page.wait_for_function(
        "() => document.querySelectorAll('#calibrations-table tbody tr').length === 3"
        " && document.querySelector('#calibrations-table tbody tr').dataset.status === 'done'",
        timeout=120_000,
    )
    assert "4" in page.locator("#calibrations-table tbody tr").nth(0).inner_text()
    # a run says which vehicle version produced its results, and links to the vehicle
    page.goto(f"{live_server.url}/#/runs/{jan[0]}")
    page.wait_for_selector("#run-vehicle-link")
    assert "parameters version 1" in page.inner_text("main")
    page.click("#run-vehicle-link")
    page.wait_for_selector("#calibrations-table")
    page.watch.assert_clean()


def _fitted(name: str, change: float, applied: bool | None) -> dict[str, Any]:
    return {"name": name, "change": change, "sd": 0.01, "identified": True,
            "significant": applied is not False, "at_bound": False, "applied": applied,
            "before": {}, "after": {}}  # fmt: skip


def test_a_parameter_kept_as_registered_is_marked_in_the_calibrations(
    page: Any, live_server: LiveServer
) -> None:
    """In an applied calibration, a fitted parameter that was not applied (not significant or
    at the fit's bound) is marked "kept as registered" beside its change; one that was applied,
    and every parameter of a calibration stored before ``applied`` was recorded (null), is not."""
    with live_server.api() as api:
        r = api.post("/api/v1/vehicles", json={"name": "bt-kept", "params": TABLE1.to_dict()})
        assert r.status_code == 201, r.text
    common = {"status": "done", "automatic": False, "created_at": "2026-03-01T10:00:00Z",
              "runs_used": [1, 2], "objective_before": 0.2, "objective_after": 0.1,
              "apply": True, "applied": True, "applied_version": 2, "message": "",
              "details": None}  # fmt: skip
    items = [
        {**common, "id": 2, "fitted": [_fitted("Is", 0.12, True), _fitted("ks1", 2.3, False)]},
        {**common, "id": 1, "fitted": [_fitted("Is", 0.10, None), _fitted("ks1", 0.01, None)]},
    ]
    page.route(
        "**/api/v1/vehicles/bt-kept/calibrations",
        lambda route: route.fulfill(json={"data": items}),
    )
    page.goto(f"{live_server.url}/#/vehicles/bt-kept")
    page.wait_for_selector("#calibrations-table")
    rows = page.locator("#calibrations-table tbody tr")
    newest, older = rows.nth(0).inner_text(), rows.nth(1).inner_text()
    assert "ks1 +230.0 % ± 1.0 % (kept as registered)" in newest, newest
    assert "Is +12.0 % ± 1.0 % (kept" not in newest, newest
    assert "kept as registered" not in older, older
