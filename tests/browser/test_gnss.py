"""Positions from GNSS in the dashboard (issue 11): the centerline uploaded on the track page,
a log with lat/lon columns uploaded without a start chainage, the plan view with the defect
marked and linked to the register."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from browser.harness import LiveServer, axe_source, axe_violations
from playwright.sync_api import expect

from engine.synthetic import make_run
from engine.track import SoftZone
from support.gnss import (
    LINE_START_CHAINAGE_M,
    RUN_OFFSET_M,
    centerline_geojson,
    csv_with_fixes,
    gnss_fixes,
    with_fixes,
)

pytestmark = pytest.mark.browser

TRACK = "GNSS bend"


@pytest.fixture(scope="module")
def gnss_files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The centerline GeoJSON and a 240 m run with a soft zone, 10 Hz fixes, no chainage."""
    d = tmp_path_factory.mktemp("gnss-files")
    line = d / "bend.geojson"
    line.write_text(json.dumps(centerline_geojson()))
    syn = make_run(
        length=240.0, zones=(SoftZone(120, 126, 0.5),), speed=30.0, sim_rate_hz=500.0,
        start_chainage_m=20.0,
    )  # fmt: skip
    true = LINE_START_CHAINAGE_M + RUN_OFFSET_M + syn.sim.x_body[: syn.log.n]
    lat, lon = gnss_fixes(true, syn.log.time_s, white_m=1.0, bias_m=0.3, seed=3)
    run = d / "gnss_run.csv"
    run.write_bytes(csv_with_fixes(with_fixes(syn.log, lat, lon)))
    return line, run


@pytest.mark.slow
def test_centerline_upload_gnss_run_and_plan_view(
    page: Any, live_server: LiveServer, gnss_files: tuple[Path, Path]
) -> None:
    line, run = gnss_files
    # a newcomer creates the track on the home page (no run needed), which opens its page
    page.goto(f"{live_server.url}/#/")
    page.fill("#new-track-name", TRACK)
    page.click("#new-track-create")
    page.wait_for_url(re.compile(r".*#/tracks/\d+$"))
    # the track page offers the centerline upload while the track has none
    page.wait_for_selector("#centerline-upload")
    assert "has no centerline" in page.locator("#plan-info").inner_text()
    page.set_input_files("#centerline-file", str(line))
    page.click("#centerline-upload")
    page.wait_for_selector("#plan-plot .main-svg")
    stored = page.locator("#plan-card .message.success").inner_text()
    assert "Centerline stored: 281 vertices" in stored

    # the upload page recognises lat/lon and lets the start chainage be empty
    page.goto(f"{live_server.url}/#/upload")
    page.set_input_files("#file-input", str(run))
    page.wait_for_selector("#preview-table")
    # the role badges come with the service's preview (the engine's reading of the columns)
    expect(page.locator("#preview-table thead")).to_contain_text("Latitude", timeout=30_000)
    expect(page.locator("#preview-table thead")).to_contain_text("Longitude")
    page.fill("#track-input", TRACK)
    page.dispatch_event("#track-input", "input")
    # the note first says the log has fixes (the preview), then, once the track's centerline
    # is known (debounced request), that the run is placed by them
    expect(page.locator("#gnss-note")).to_contain_text("placed by its fixes", timeout=30_000)
    assert page.input_value("#start-chainage") == ""
    page.select_option("#vehicle-select", "table1")  # the form asks among several
    page.click("#upload-button")
    page.wait_for_url(re.compile(r".*#/runs/\d+$"), timeout=60_000)
    run_id = int(page.url.rsplit("/", 1)[1])
    with live_server.api() as api:
        got = api.get(f"/api/v1/runs/{run_id}").json()
    assert got["positioning"]["method"] == "gnss", got
    assert abs(got["start_chainage_m"] - (LINE_START_CHAINAGE_M + RUN_OFFSET_M + 20.0)) < 1.5
    # the run page shows the placement: method, fixes used/rejected, residual, scale, offset
    page.wait_for_selector("#run-placement-facts")
    facts = page.locator("#run-placement-facts").inner_text()
    pos = got["positioning"]
    assert "GNSS fixes fitted" in facts and f"{pos['n_used']} of {pos['n_fixes']}" in facts
    for label in ("Residual (RMS)", "Odometer scale", "Lateral offset"):
        assert label in facts

    # the plan view marks the defect; clicking it opens the defect in the register
    page.goto(f"{live_server.url}/#/tracks/{TRACK}")
    page.wait_for_selector("#zone-table")
    page.wait_for_selector("#plan-plot .scatterlayer .trace:nth-of-type(2) .point")
    points = page.locator("#plan-plot .scatterlayer .trace:nth-of-type(2) .point")
    assert points.count() == 1
    # chainage marks in km+m and the run's stretch with its ends; the centerline covers it
    names = page.evaluate("() => document.getElementById('plan-plot').data.map(t => t.name)")
    assert "Chainage (km+m)" in names, names
    assert any(f"run {run_id} (" in str(n) for n in names), names
    assert page.locator("#plan-flag").is_hidden()
    # the run's trace is its placed stretch on the centerline (not its raw fixes): it starts
    # and ends at the run's aligned extent, and every point of it lies on the line
    traces = page.evaluate(
        """() => document.getElementById('plan-plot').data.map(t => ({name: t.name,
            x: [...t.x], y: [...t.y], c: t.customdata ? [...t.customdata] : null}))"""
    )
    trace = next(t for t in traces if str(t["name"]).startswith(f"run {run_id} ("))
    with live_server.api() as api:
        track_id = api.get(f"/api/v1/tracks/{TRACK}").json()["id"]
        view = api.get(f"/api/v1/views/tracks/{track_id}/chainage-map?zones=false").json()
        placed = next(r for r in view["runs"] if r["id"] == run_id)
        plan = api.get(f"/api/v1/tracks/{track_id}/centerline/plan").json()
    assert trace["c"][0] == pytest.approx(placed["chainage_min_m"], abs=1e-6)
    assert trace["c"][-1] == pytest.approx(placed["chainage_max_m"], abs=1e-6)
    line = np.column_stack([plan["x_m"], plan["y_m"]])
    for p in np.column_stack([trace["x"], trace["y"]]):
        a, b = line[:-1], line[1:]
        t = np.clip(np.einsum("ij,ij->i", p - a, b - a) / np.einsum("ij,ij->i", b - a, b - a), 0, 1)
        assert np.min(np.hypot(*(a + t[:, None] * (b - a) - p).T)) < 0.01
    page.locator("#plan-card").scroll_into_view_if_needed()
    box = points.first.bounding_box()
    assert box is not None
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.click(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    expect(page.locator("#plan-info")).to_contain_text("is open in the register", timeout=15_000)
    expect(page.locator("#zone-info")).not_to_have_text("", timeout=15_000)
    # axe: no serious or critical violation on the track page with its plan view drawn
    src = axe_source()
    for width in (1280, 390):
        page.set_viewport_size({"width": width, "height": 900})
        page.goto(f"{live_server.url}/#/tracks/{TRACK}")
        page.wait_for_selector("#plan-plot .main-svg")
        assert not axe_violations(page, src), (width, axe_violations(page, src))
    page.watch.assert_clean()


def test_a_track_without_centerline_asks_for_none(page: Any, live_server: LiveServer) -> None:
    """The track page of a track without a centerline says it has none and asks the service
    for nothing that answers 404 (the browser's console logged each such request as an error
    before the track said ``has_centerline``)."""
    with live_server.api() as api:
        r = api.post(
            "/api/v1/simulate?wait=true",
            json={"track": "No line", "length_m": 220, "speed_mps": 22.0, "seed": 6,
                  "zones": [{"start_m": 100, "end_m": 105, "loss": 0.5}]},
        )  # fmt: skip
        assert r.status_code in (200, 201), r.text
        tid = r.json()["run"]["track_id"]
    failed: list[str] = []
    page.on("response", lambda resp: failed.append(resp.url) if resp.status >= 400 else None)
    page.goto(f"{live_server.url}/#/tracks/{tid}")
    expect(page.locator("#plan-info")).to_contain_text("This track has no centerline")
    page.wait_for_load_state("networkidle")
    assert failed == []
    page.watch.assert_clean()
