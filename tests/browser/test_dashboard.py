"""The dashboard in a real browser: upload a run, read its profile, the track map, simulate.

Each test drives Debian's Chromium against the service started by ``live_server`` and checks
what a user sees: Plotly traces drawn, soft spots shaded and labelled, tables filled, errors
naming the column and row, user text shown as text. Screenshots of each page (1366x768) are
written to docs/screenshots when UPDATE_SCREENSHOTS=1 is set.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from browser.harness import (
    SAMPLE_START_M,
    SAMPLE_ZONES,
    LiveServer,
    start_server,
    stop_server,
    wait_for_plot,
)

pytestmark = pytest.mark.browser

TRACK = "Demo line"


@pytest.fixture(scope="module")
def uploaded_run(browser: Any, live_server: LiveServer, sample_csv: Path, screenshots: Path) -> int:
    """The sample run uploaded once through the page (screenshot of the filled upload form)."""
    context = browser.new_context(viewport={"width": 1366, "height": 768})
    page = context.new_page()
    try:
        page.goto(f"{live_server.url}/#/upload")
        page.set_input_files("#file-input", str(sample_csv))
        page.wait_for_selector("#preview-table")
        page.fill("#track-input", TRACK)
        page.dispatch_event("#track-input", "input")
        page.fill("#start-chainage", str(SAMPLE_START_M))
        page.screenshot(path=str(screenshots / "upload.png"), full_page=True)
        page.select_option("#vehicle-select", "table1")  # the form asks among several
        page.click("#upload-button")
        page.wait_for_url(re.compile(r".*#/runs/\d+$"), timeout=60_000)
        return int(page.url.rsplit("/", 1)[1])
    finally:
        context.close()


@pytest.fixture(scope="module")
def demo_track(live_server: LiveServer, uploaded_run: int) -> list[int]:
    """The demo track with four more (simulated) monthly runs beside the uploaded one.

    The simulated runs pass the same two zones as the sample (the first deepening from 35 %
    to 50 % loss), so the chainage map has zones seen on several runs.
    """
    ids = [uploaded_run]
    with live_server.api() as api:
        for k, loss in enumerate((0.35, 0.4, 0.45, 0.5)):
            r = api.post(
                "/api/v1/simulate?wait=true",
                json={
                    "track": TRACK,
                    "length_m": 500,
                    "speed_mps": 18.0 + 2.0 * k,
                    "zones": [
                        {"start_m": 140, "end_m": 146, "loss": loss},
                        {"start_m": 333, "end_m": 337, "loss": 0.35},
                    ],
                    "start_chainage_m": SAMPLE_START_M,
                    "sensor": "realistic",
                    "seed": 11 + k,
                    "recorded_at": f"2025-{8 + k:02d}-15T09:30:00Z",
                },
            )
            assert r.status_code in (200, 201), r.text
            assert r.json()["run"]["status"] == "done"
            ids.append(r.json()["run"]["id"])
    return ids


def test_upload_page_previews_and_recognises_columns(
    page: Any, live_server: LiveServer, sample_csv: Path
) -> None:
    """Choosing a file shows its first rows and which column is time, accel, pitch rate, speed."""
    page.goto(f"{live_server.url}/#/upload")
    page.set_input_files("#file-input", str(sample_csv))
    page.wait_for_selector("#preview-table")
    # The role badges come with the service's answer, after the table's first drawing.
    page.wait_for_function(
        "() => document.querySelector('#recognised-note')"
        "?.textContent.includes('Recognised by the service')"
    )
    headers = page.locator("#preview-table thead th").all_inner_texts()
    assert len(headers) == 4
    joined = " | ".join(headers)
    for role in ("Time", "Vertical acceleration", "Pitch rate", "Speed"):
        assert role in joined, f"{role} not recognised in {joined!r}"
    assert page.locator("#preview-table tbody tr").count() == 10
    note = page.locator("#recognised-note").inner_text()
    assert "time_s" in note and "pitch_rate_radps" in note
    # Optional roles the file lacks (chainage, the load-weigh column) are not asked for.
    assert "Not recognised" not in note, note
    assert page.locator("#map-wheel_load-column").count() == 1
    assert "Automatic: time_s" in page.locator("#map-time-column").inner_text()
    page.watch.assert_clean()


def test_uploaded_run_shows_profile_with_shaded_labelled_soft_spots(
    page: Any, live_server: LiveServer, uploaded_run: int, screenshots: Path
) -> None:
    """The run view draws the profile, one shaded band and one label per soft spot, both zones."""
    with live_server.api() as api:
        spots = api.get(f"/api/v1/runs/{uploaded_run}/soft-spots").json()
    assert len(spots) >= 2
    for a, b in SAMPLE_ZONES:  # both true zones found (the "done means")
        assert any(s["end_m"] >= a and s["start_m"] <= b for s in spots), (a, b, spots)

    page.goto(f"{live_server.url}/#/runs/{uploaded_run}")
    wait_for_plot(page, "#profile-plot")
    info = page.evaluate(
        """() => {
            const gd = document.getElementById('profile-plot');
            return {
                traces: gd.data.map(t => ({name: t.name, n: (t.x || []).length})),
                shapes: (gd.layout.shapes || []).map(s => [s.x0, s.x1]),
                labels: (gd.layout.annotations || []).map(a => a.text),
                drawnShapes: gd.querySelectorAll('.shapelayer path').length,
            };
        }"""
    )
    fused = [t for t in info["traces"] if t["name"] == "Fused level"]
    assert fused and fused[0]["n"] > 100
    assert len(info["shapes"]) >= len(spots)
    assert info["drawnShapes"] >= len(spots)
    for s in spots:
        assert any(
            abs(x0 - s["start_m"]) < 1e-6 and abs(x1 - s["end_m"]) < 1e-6
            for x0, x1 in info["shapes"]
        )
    assert len(info["labels"]) == len(spots)
    # each spot's peak marker sits on the drawn fused line, at the spot's deepest point
    peaks = page.evaluate(
        """() => { const gd = document.getElementById('profile-plot');
                   const f = gd.data.find(t => t.name === 'Fused level');
                   const p = gd.data.find(t => t.meta === 'peaks');
                   return { fx: f.x, fy: f.y, px: p.x, py: p.y }; }"""
    )
    assert peaks["px"] == pytest.approx([s["peak_m"] for s in spots])
    line = np.interp(peaks["px"], peaks["fx"], np.asarray(peaks["fy"], dtype=float))
    assert peaks["py"] == pytest.approx(list(line), abs=1e-9)
    for s, text in zip(spots, info["labels"], strict=True):
        assert f"{s['depth_mm']:.2f} mm" in text and f"{s['stiffness_loss_pct']:.0f} %" in text
    assert page.locator("#spots-table tbody tr").count() == len(spots)
    assert page.locator("#run-quality dt").count() >= 3
    assert "2 soft spots" in page.locator("#run-summary").inner_text() or len(spots) != 2
    wait_for_plot(page, "#signals-plot", 2)
    page.screenshot(path=str(screenshots / "run.png"), full_page=True)

    page.check("#toggle-axles")
    page.wait_for_function(
        "() => document.getElementById('profile-plot').data.some(t => t.name === 'Rear axle')"
    )
    names = page.evaluate("() => document.getElementById('profile-plot').data.map(t => t.name)")
    assert "Front axle" in names and "Rear axle" in names
    page.uncheck("#toggle-axles")
    page.wait_for_function(
        "() => !document.getElementById('profile-plot').data.some(t => t.name === 'Rear axle')"
    )
    page.watch.assert_clean()


def test_run_view_downloads_profile_and_soft_spots(
    page: Any, live_server: LiveServer, uploaded_run: int
) -> None:
    """The download buttons give the profile CSV and the soft spots as CSV and as JSON."""
    page.goto(f"{live_server.url}/#/runs/{uploaded_run}")
    wait_for_plot(page, "#profile-plot")
    with page.expect_download() as dl:
        page.click("#download-profile")
    text = Path(dl.value.path()).read_text()
    assert text.splitlines()[0].startswith("chainage_m")
    assert len(text.splitlines()) > 100
    with page.expect_download() as dl:
        page.click("#download-spots-csv")
    lines = Path(dl.value.path()).read_text().splitlines()
    assert lines[0] == "start_m,end_m,peak_m,depth_mm,stiffness_loss_pct"
    with page.expect_download() as dl:
        page.click("#download-spots-json")
    data = json.loads(Path(dl.value.path()).read_text())
    assert len(data) == len(lines) - 1 >= 2
    page.watch.assert_clean()


@pytest.mark.slow
def test_track_view_draws_chainage_map_and_zone_table(
    page: Any, live_server: LiveServer, demo_track: list[int], screenshots: Path
) -> None:
    """The track view maps every soft spot of every run of the track and lists the defects of
    the register they form; the deep zone is seen on every run; a defect opens its profile
    across runs; the table sorts by a column."""
    with live_server.api() as api:
        n_spots = sum(len(api.get(f"/api/v1/runs/{i}/soft-spots").json()) for i in demo_track)
        zones = api.get(f"/api/v1/views/tracks/{TRACK}/chainage-map").json()["zones"]
        defects = api.get(f"/api/v1/tracks/{TRACK}/defects").json()
    deep = [z for z in zones if z["end_m"] >= 140 and z["start_m"] <= 146]
    assert len(deep) == 1 and deep[0]["runs_seen"] == len(demo_track)

    page.goto(f"{live_server.url}/#/")
    page.click(f"#track-list >> text={TRACK}")
    wait_for_plot(page, "#chainage-map")
    drawn = page.evaluate(
        """() => {
            const gd = document.getElementById('chainage-map');
            const t = gd.data.find(d => d.meta === 'spots');
            return {markers: t ? t.x.length : 0, rows: gd.layout.yaxis.categoryarray.length,
                    points: gd.querySelectorAll('.scatterlayer .point').length};
        }"""
    )
    assert drawn["markers"] == n_spots and drawn["points"] >= n_spots
    assert drawn["rows"] == len(demo_track)
    rows = page.locator("#zone-table tbody tr")
    # the register answers after the chart is drawn (it detects on the combined passes too)
    page.wait_for_function(
        "n => document.querySelectorAll('#zone-table tbody tr').length === n", arg=len(defects)
    )
    assert rows.count() == len(defects)
    seen = f"single pass: {len(demo_track)} passes"  # the evidence column
    assert any(seen in t for t in rows.all_inner_texts()), rows.all_inner_texts()
    wait_for_plot(page, "#zone-plot")  # the top-ranked zone is shown at once
    deep_row = page.locator("#zone-table tbody tr", has_text="0+140.")  # km+m
    deep_row.first.get_by_role("button").click()
    page.wait_for_function(
        "() => document.getElementById('zone-info').textContent.startsWith('Zone 0+14')"
    )
    zone_traces = page.evaluate(
        "() => document.getElementById('zone-plot').data"
        ".filter(t => String(t.meta).startsWith('run-')).length"
    )
    assert zone_traces == len(demo_track)
    peak_header = page.locator("#zone-table thead th", has_text="Peak")
    peak_header.get_by_role("button").click()
    assert peak_header.get_attribute("aria-sort") == "ascending"
    cells = page.locator("#zone-table tbody tr td:nth-child(5)").all_inner_texts()
    peaks = [1000 * float(c.split("+")[0]) + float(c.split("+")[1]) for c in cells]  # km+m
    assert peaks == sorted(peaks)
    page.fill("#alerts-since", "2025-01-01")  # the morning pull, as shown in the screenshot
    page.click("#alerts-show")
    page.wait_for_selector("#alerts-table tbody tr")
    page.wait_for_timeout(400)
    page.evaluate("() => window.scrollTo(0, 0)")
    page.screenshot(path=str(screenshots / "track.png"), full_page=True)
    page.watch.assert_clean()


def test_home_lists_tracks_and_runs(
    page: Any, live_server: LiveServer, uploaded_run: int, demo_track: list[int], screenshots: Path
) -> None:
    """The start page lists the track and the run, each linking to its view."""
    page.goto(f"{live_server.url}/#/")
    page.wait_for_selector("#runs-table")
    assert page.locator(f"#runs-table a[href='#/runs/{uploaded_run}']").count() == 1
    assert page.locator("#track-list a", has_text=TRACK).count() == 1
    page.screenshot(path=str(screenshots / "home.png"), full_page=True)
    page.watch.assert_clean()


def test_simulate_page_shows_recovered_profile_next_to_truth(
    page: Any, live_server: LiveServer, screenshots: Path
) -> None:
    """A simulation draws the recovered profile and the truth, and finds the zone put in."""
    page.goto(f"{live_server.url}/#/simulate")
    page.fill("#sim-length", "250")
    second_zone = page.locator("#sim-zones tbody tr").nth(1)
    second_zone.get_by_role("button", name="Remove this zone").click()
    page.click("#simulate-button")
    wait_for_plot(page, "#sim-profile-plot", 2)
    names = page.evaluate("() => document.getElementById('sim-profile-plot').data.map(t => t.name)")
    assert names[:2] == ["Recovered", "Truth"]
    shapes = page.evaluate(
        "() => document.getElementById('sim-profile-plot').layout.shapes.map(s => s.name)"
    )
    assert "true-zone" in shapes and "soft-spot" in shapes
    compare = page.locator("#sim-compare tbody tr")
    assert compare.count() == 1
    assert "found" in compare.first.inner_text()
    wait_for_plot(page, "#sim-signals-plot", 2)
    page.screenshot(path=str(screenshots / "simulate.png"), full_page=True)
    page.watch.assert_clean()


def test_simulate_page_names_invalid_inputs(page: Any, live_server: LiveServer) -> None:
    """A zone beyond the track is refused in the page, naming the zone, before any request."""
    page.goto(f"{live_server.url}/#/simulate")
    page.fill("#sim-length", "150")
    page.click("#simulate-button")
    msg = page.locator("#sim-status")
    msg.wait_for()
    assert "200–204 m is outside the track" in msg.inner_text()
    assert page.locator("#sim-zones [aria-invalid=true]").count() >= 1
    page.watch.assert_clean()


def test_upload_error_names_column_and_row(
    page: Any, live_server: LiveServer, tmp_path: Path
) -> None:
    """A file with text in a number column is refused with the column and line shown."""
    bad = tmp_path / "bad.csv"
    rows = ["time_s,accel_z_mps2,pitch_rate_radps,speed_mps"]
    rows += [f"{i / 1000:.3f},0.01,0.0001,20" for i in range(200)]
    rows[51] = "0.050,oops,0.0001,20"
    bad.write_text("\n".join(rows) + "\n")
    page.goto(f"{live_server.url}/#/upload")
    page.set_input_files("#file-input", str(bad))
    page.wait_for_selector("#preview-table")
    page.fill("#track-input", "Error line")
    page.fill("#start-chainage", "0")
    # The preview already saw the bad value: the upload needs an explicit "upload anyway".
    page.check("#ignore-problems")
    page.select_option("#vehicle-select", "table1")  # the form asks among several
    page.click("#upload-button")
    status = page.locator("#upload-status.error")
    status.wait_for()
    text = status.inner_text()
    assert "accel_z_mps2" in text and "Column: accel_z_mps2" in text
    assert "Row: 52" in text
    assert page.url.endswith("#/upload")
    assert page.locator("#map-accel-column[aria-invalid=true]").count() == 1
    page.watch.assert_clean()


SCRIPT_NAMES = ("<script>alert(1)</script>", '<img src=x onerror="alert(2)">')


@pytest.mark.parametrize("name", SCRIPT_NAMES)
def test_markup_in_track_name_is_shown_as_text(
    page: Any, live_server: LiveServer, sample_csv: Path, name: str
) -> None:
    """A track named like markup is shown literally on every page; no script runs, no dialog."""
    with live_server.api() as api:
        r = api.post(
            "/api/v1/runs?wait=true",
            files={"file": ("run.csv", sample_csv.read_bytes(), "text/csv")},
            data={"track": name, "start_chainage_m": str(SAMPLE_START_M)},
        )
        assert r.status_code in (200, 201), r.text
        run_id = r.json()["id"]
    page.goto(f"{live_server.url}/#/")
    page.wait_for_selector("#track-list")
    assert page.locator("#track-list a", has_text=name).count() == 1
    page.goto(f"{live_server.url}/#/runs/{run_id}")
    wait_for_plot(page, "#profile-plot")
    assert page.locator("#run-track-link").inner_text() == name
    page.click("#run-track-link")
    wait_for_plot(page, "#chainage-map")
    assert page.locator("#track-title .track-name").inner_text() == name
    page.goto(f"{live_server.url}/#/upload")
    page.wait_for_selector("#track-list option", state="attached")
    assert page.evaluate("() => document.querySelectorAll('main script, main img').length") == 0
    page.wait_for_timeout(300)
    page.watch.assert_clean()


@pytest.mark.parametrize("width,height", [(1366, 768), (1920, 1080)])
def test_pages_fit_the_screen_without_horizontal_scrolling(
    browser: Any, live_server: LiveServer, uploaded_run: int, width: int, height: int
) -> None:
    """Every page fits a 1366x768 laptop and a large monitor without sideways scrolling."""
    context = browser.new_context(viewport={"width": width, "height": height})
    page = context.new_page()
    try:
        for route, ready in (
            ("/", "#runs-table"),
            ("/upload", "#upload-button"),
            (f"/runs/{uploaded_run}", "#profile-plot .main-svg"),
            (f"/tracks/{TRACK}", "#chainage-map .main-svg"),
            ("/simulate", "#simulate-button"),
        ):
            page.goto(f"{live_server.url}/#{route}")
            page.wait_for_selector(ready)
            scroll = page.evaluate("() => document.documentElement.scrollWidth")
            assert scroll <= width, f"{route} is {scroll} px wide in a {width} px window"
    finally:
        context.close()


def test_controls_are_labelled_and_reachable_by_keyboard(
    page: Any, live_server: LiveServer
) -> None:
    """Every form control has an accessible name, and Tab reaches the file chooser and upload."""
    page.goto(f"{live_server.url}/#/upload")
    page.wait_for_selector("#upload-button")
    unnamed = page.evaluate(
        """() => [...document.querySelectorAll('main input, main select, main button')]
            .filter(el => !(el.labels && el.labels.length) && !el.getAttribute('aria-label')
                          && !(el.textContent || '').trim())
            .map(el => el.outerHTML.slice(0, 80))"""
    )
    assert unnamed == []
    reached = set()
    for _ in range(60):
        page.keyboard.press("Tab")
        reached.add(page.evaluate("() => document.activeElement && document.activeElement.id"))
    assert {"file-input", "track-input", "upload-button"} <= reached
    outline = page.evaluate(
        """() => { const b = document.getElementById('upload-button'); b.focus();
                   return getComputedStyle(b).outlineStyle; }"""
    )
    assert outline != "none"
    assert page.locator("#announcer[aria-live=polite]").count() == 1


def raw_imu_csv(canonical: Path, dest: Path, names: tuple[str, str, str, str]) -> None:
    """Rewrite a canonical run as a raw IMU log: epoch s, g with gravity, deg/s, km/h."""
    import numpy as np

    t, a, q, v = np.loadtxt(canonical, delimiter=",", skiprows=1, unpack=True)[:4]
    g = 9.80665
    cols = np.column_stack([1763800000.0 + t, (a + g) / g, np.degrees(q), 3.6 * v])
    fmt = ["%.4f", "%.9g", "%.9g", "%.6g"]
    np.savetxt(dest, cols, delimiter=",", header=",".join(names), comments="", fmt=fmt)


def test_raw_imu_log_is_recognised_and_processed(
    page: Any, live_server: LiveServer, sample_csv: Path, tmp_path: Path
) -> None:
    """A logger's own names and units (epoch s, g with gravity, deg/s, km/h) are recognised in
    the preview and the upload finds the same two zones."""
    raw = tmp_path / "logger.csv"
    raw_imu_csv(sample_csv, raw, ("timestamp", "az_g", "gyro_y_dps", "speed_kmh"))
    page.goto(f"{live_server.url}/#/upload")
    page.set_input_files("#file-input", str(raw))
    page.wait_for_selector("#preview-table")
    page.wait_for_function(
        "() => document.getElementById('recognised-note').textContent.includes('by the service')"
    )
    badges = " ".join(page.locator("#preview-table thead .badge").all_inner_texts())
    for unit in ("epoch_s", "g", "deg/s", "km/h"):
        assert unit in badges, badges
    assert "included" in page.locator("#map-gravity").inner_text()
    page.fill("#track-input", "Raw logger line")
    page.fill("#start-chainage", str(SAMPLE_START_M))
    page.select_option("#vehicle-select", "table1")  # the form asks among several
    page.click("#upload-button")
    page.wait_for_url(re.compile(r".*#/runs/\d+$"), timeout=60_000)
    wait_for_plot(page, "#profile-plot")
    shapes = page.evaluate(
        "() => document.getElementById('profile-plot').layout.shapes.map(s => [s.x0, s.x1])"
    )
    for a, b in SAMPLE_ZONES:
        assert any(x1 >= a and x0 <= b for x0, x1 in shapes), (a, b, shapes)
    page.watch.assert_clean()


def test_unrecognised_columns_are_mapped_by_hand(
    page: Any, live_server: LiveServer, sample_csv: Path, tmp_path: Path
) -> None:
    """With meaningless column names the page says so; choosing columns and units by hand
    makes the upload work."""
    raw = tmp_path / "channels.csv"
    raw_imu_csv(sample_csv, raw, ("ch1", "ch2", "ch3", "ch4"))
    page.goto(f"{live_server.url}/#/upload")
    page.set_input_files("#file-input", str(raw))
    page.wait_for_selector("#preview-table")
    page.wait_for_function(
        "() => document.getElementById('recognised-note').textContent.includes('Not recognised')"
    )
    for role, column, unit in (
        ("time", "ch1", "epoch_s"),
        ("accel", "ch2", "g"),
        ("pitch_rate", "ch3", "deg/s"),
        ("speed", "ch4", "km/h"),
    ):
        page.select_option(f"#map-{role}-column", column)
        page.select_option(f"#map-{role}-unit", unit)
    page.select_option("#map-gravity", "included")
    page.wait_for_function(
        "() => !document.getElementById('recognised-note').textContent.includes('Not recognised')"
    )
    page.fill("#track-input", "Hand-mapped line")
    page.fill("#start-chainage", str(SAMPLE_START_M))
    page.select_option("#vehicle-select", "table1")  # the form asks among several
    page.click("#upload-button")
    page.wait_for_url(re.compile(r".*#/runs/\d+$"), timeout=60_000)
    wait_for_plot(page, "#profile-plot")
    assert page.locator("#spots-table tbody tr").count() >= 2
    page.watch.assert_clean()


def test_new_vehicle_is_created_and_selected(page: Any, live_server: LiveServer) -> None:
    """The vehicle form creates a vehicle through the API and selects it for the upload; a
    missing name is refused in the page."""
    page.goto(f"{live_server.url}/#/upload")
    page.wait_for_selector("#vehicle-select option", state="attached")
    page.click(".new-vehicle summary")
    page.click("#create-vehicle")
    assert "name" in page.locator(".new-vehicle .message").inner_text()
    page.fill("#vehicle-name", "Inspection car 2")
    page.fill("#veh-ms", "18000")
    page.click("#create-vehicle")
    page.wait_for_function(
        "() => document.getElementById('vehicle-select').value === 'Inspection car 2'"
    )
    with live_server.api() as api:
        v = api.get("/api/v1/vehicles/Inspection car 2").json()
    assert v["params"]["ms"] == 18000
    page.watch.assert_clean()


@pytest.mark.slow
def test_background_processing_is_followed_until_done(
    page: Any, sample_csv: Path, tmp_path: Path
) -> None:
    """When the service queues the run (202), the page shows the upload complete, follows the
    processing and opens the run once it is done."""
    server = start_server(tmp_path, settings={"TRACKPROFILE_INLINE_MAX_SAMPLES": "0"})
    try:
        answers: list[int] = []
        page.on(
            "response",
            lambda r: (
                answers.append(r.status)
                if r.request.method == "POST" and r.url.endswith("/api/v1/runs")
                else None
            ),
        )
        page.goto(f"{server.url}/#/upload")
        page.set_input_files("#file-input", str(sample_csv))
        page.wait_for_selector("#preview-table")
        page.fill("#track-input", "Queued line")
        page.fill("#start-chainage", str(SAMPLE_START_M))
        # Record what the progress labels say while the page changes (it is one document).
        page.evaluate(
            """() => {
                window.__progress = [];
                const box = document.querySelector('.progress-box');
                new MutationObserver(() => {
                    if (!box.hidden) window.__progress.push(box.innerText);
                }).observe(box, {subtree: true, childList: true, characterData: true,
                                 attributes: true});
            }"""
        )
        page.select_option("#vehicle-select", "table1")  # the form asks among several
        page.click("#upload-button")
        page.wait_for_url(re.compile(r".*#/runs/\d+$"), timeout=60_000)
        seen = " / ".join(page.evaluate("() => window.__progress"))
        assert "Upload 100 %" in seen and "Processing done" in seen
        # the run's stage while it was followed: queued, inverting or storing
        assert re.search(r"(Waiting to be processed|Processing|Storing the result) \(\d+ s\)", seen)
        assert answers == [202]
        wait_for_plot(page, "#profile-plot")
        assert page.locator("#spots-table tbody tr").count() >= 2
        page.watch.assert_clean()
    finally:
        stop_server(server)
