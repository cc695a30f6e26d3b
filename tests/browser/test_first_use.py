# ruff: noqa: E501  (the JavaScript predicates stay one line each, as the browser runs them)
"""What a first-time user trips over (issue 14): each check fails without its fix.

One example run (examples/example_run.csv.gz, uploaded once) serves the run and track checks;
pages are checked with axe-core (no serious or critical violation), for share/cloud links on
charts, and for their first-paint timings (reported; the ceilings here are loose, the
measured numbers are in docs/benchmarks.md).
"""

from __future__ import annotations

import json
import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from browser.harness import (
    CHART_MARKS,
    LiveServer,
    axe_source,
    axe_violations,
    painted_s,
    wait_for_plot,
)

from support.samples import REPO

pytestmark = pytest.mark.browser

EXAMPLE = REPO / "examples" / "example_run.csv.gz"
TRUTH = json.loads((REPO / "examples" / "example_run.truth.json").read_text())
TRACK = "First use line"
HOME_CEILING_S = 2.0
CHART_CEILING_S = 6.0
"""Loose ceilings for loaded CI machines; the targets (0.5 s, 1.5 s) are reported."""
TIMINGS: dict[str, float] = {}

CLOUD_WORDS = ("cloud", "chart studio", "share", "edit in", "plotly.com", "plot.ly")


def dashboard_trace_types() -> set[str]:
    """Every plotly trace type the dashboard's scripts name (``type: "heatmap"``...): the
    plotly.js bundle served must have them all. Trace types are told from the other ``type:``
    keys (inputs, buttons, shapes) by the plotly package's list of them."""
    import plotly.graph_objects as go
    from plotly.basedatatypes import BaseTraceType

    classes = [getattr(go, n) for n in dir(go)]  # plotly.graph_objects loads them lazily
    known = {
        c.__name__.lower()
        for c in classes
        if isinstance(c, type) and issubclass(c, BaseTraceType) and c is not BaseTraceType
    }
    found = {"scatter"}  # a trace without a type is a scatter
    for js in (REPO / "static" / "js").rglob("*.js"):
        found |= set(re.findall(r"""\btype:\s*["'](\w+)["']""", js.read_text())) & known
    return found


@pytest.fixture(scope="module")
def axe() -> Iterator[str]:
    """axe-core's script; at the end of the module, the timings measured (docs/benchmarks.md)."""
    yield axe_source()
    print("\nfirst-paint timings:", json.dumps({k: round(v, 3) for k, v in TIMINGS.items()}))


@pytest.fixture(scope="module")
def example_run(live_server: LiveServer) -> dict[str, Any]:
    """The example log uploaded by the API (start chainage from its truth, no recorded_at)."""
    with live_server.api() as api:
        r = api.post(
            "/api/v1/runs?wait=true",
            files={"file": ("example_run.csv.gz", EXAMPLE.read_bytes(), "application/gzip")},
            data={"track": TRACK, "start_chainage_m": str(TRUTH["start_chainage_m"])},
        )
        assert r.status_code in (200, 201), r.text
        run = r.json()
        assert run["status"] == "done", run
        return run


def assert_no_cloud_links(page: Any) -> None:
    """No chart offers to send its data anywhere: no such modebar button or link, and each
    graph's config has the cloud features off."""
    page.hover(".js-plotly-plot .main-svg")  # show the modebar
    titles = page.eval_on_selector_all(
        ".modebar-btn, .js-plotly-plot a",
        "els => els.map(e => (e.getAttribute('data-title') || '') + ' ' + (e.textContent || '')"
        " + ' ' + (e.getAttribute('href') || ''))",
    )
    assert titles, "no modebar found"
    offending = [t for t in titles if any(w in t.lower() for w in CLOUD_WORDS)]
    assert not offending, offending
    configs = page.evaluate(
        """() => [...document.querySelectorAll('.js-plotly-plot')].map(gd => {
            const c = gd._context; return [c.showSendToCloud, c.plotlyServerURL]; })"""
    )
    # plotly.js 4 defaults: a "Share chart..." button, uploading to Plotly's cloud.
    assert configs and all(c == [False, ""] for c in configs), configs


PAGE_MODULES = ("/static/js/pages/",)


def assert_plotly_loads_with_the_page_module(page: Any, own: str) -> None:
    """On a cold visit of a page with charts, plotly.js is requested at navigation, before the
    shell's own imports (static/js/preload.js, run before the modules: not after them, nor
    after the page's module graph), and no other page's module is fetched (static/js/app.js
    imports a page's module when it is shown). ``own`` is the page's module directory or file
    under static/js/pages/."""
    entries = page.evaluate(
        """() => performance.getEntriesByType('resource').map(e =>
            [new URL(e.name).pathname, e.startTime, e.responseEnd])"""
    )
    plotly_start = next(start for path, start, _ in entries if "/vendor/plotly" in path)
    modules = [(path, end) for path, _, end in entries if path.startswith("/static/js/")]
    others = [p for p, _ in modules if p.startswith(PAGE_MODULES) and not p.startswith(own)]
    assert not others, f"modules of other pages loaded: {others}"
    shell_imports = min(
        s for p, s, _ in entries if p in ("/static/js/dom.js", "/static/js/plots.js")
    )
    assert plotly_start < shell_imports, (
        f"plotly.js requested at {plotly_start:.0f} ms, after the shell's imports ({shell_imports:.0f} ms)"
    )


def timed_goto(page: Any, url: str, ready: str) -> float:
    """Seconds from navigation to `ready` (a JS predicate) holding, as the test driver sees it."""
    t = time.perf_counter()
    page.goto(url)
    page.wait_for_function(ready)
    return time.perf_counter() - t


def test_home_shows_at_once_without_plotly_and_explains_the_first_step(
    page: Any, live_server: LiveServer, example_run: dict[str, Any], axe: str
) -> None:
    """Home: content shown without waiting for plotly (fetched only afterwards), a one-line
    intro and the first step; plurals; axe clean."""
    page.goto(f"{live_server.url}/#/upload")  # warm: the browser has the modules cached
    page.wait_for_selector("#upload-button")
    times = [
        timed_goto(
            page,
            f"{live_server.url}/?t={i}#/",
            "() => document.querySelector('#track-list li') && document.querySelector('#runs-table tbody tr')",
        )  # fmt: skip
        for i in range(3)
    ]
    TIMINGS["home content (s)"] = min(times)
    assert min(times) < HOME_CEILING_S, times
    # plotly.js is not needed for the content: fetched (for the next page) only after it shows.
    order = page.evaluate(
        """() => { const m = performance.getEntriesByName('home-content').pop();
            const p = performance.getEntriesByType('resource').find(e => e.name.includes('plotly'));
            return [m ? m.startTime : null, p ? p.startTime : null]; }"""
    )
    assert order[0] is not None and (order[1] is None or order[1] > order[0]), order
    assert "loaded profile" in page.inner_text("#intro")
    first = page.inner_text("#first-step")
    assert "upload a run log" in first and "start chainage" in first and "example_run" in first
    line = page.locator("#track-list li", has_text=TRACK).inner_text()
    assert "· 1 run" in line and "1 runs" not in line
    assert axe_violations(page, axe) == []
    page.watch.assert_clean()


def test_run_page_chart_is_fast_cached_local_explained_and_accessible(
    page: Any, live_server: LiveServer, example_run: dict[str, Any], axe: str
) -> None:
    """Run page: plotly.js comes compressed and cacheable by a versioned URL, the chart shows
    within the ceiling, no share/cloud link, the terms explained, one sign for the loss,
    numbers aligned under their headers; axe clean."""
    answers: list[Any] = []
    page.on("response", lambda r: answers.append(r) if "plotly" in r.url else None)
    url = f"{live_server.url}/#/runs/{example_run['id']}"
    ready = "() => { const gd = document.getElementById('profile-plot'); return gd && gd._fullLayout && gd.querySelector('.main-svg'); }"
    page.add_init_script(CHART_MARKS)
    cold = timed_goto(page, url, ready)
    cold_painted = painted_s(page, "profile-plot")
    assert cold_painted > 0
    assert_plotly_loads_with_the_page_module(page, "/static/js/pages/run.js")
    # The chart's data is asked for with the run (static/js/pages/run.js), not after its answer.
    api = page.evaluate(
        """() => performance.getEntriesByType('resource').filter(e => e.name.includes('/api/v1/'))
            .map(e => [new URL(e.name).pathname, e.startTime, e.responseEnd])"""
    )
    run_end = next(end for p, _, end in api if p == f"/api/v1/runs/{example_run['id']}")
    chart_starts = [s for p, s, _ in api if "/views/runs/" in p or p.endswith("/soft-spots")]
    assert len(chart_starts) == 2 and max(chart_starts) < run_end, api
    warm, warm_painted = min(
        (
            timed_goto(page, f"{live_server.url}/?t={i}#/runs/{example_run['id']}", ready),
            painted_s(page, "profile-plot"),
        )
        for i in range(2)
    )
    TIMINGS["run chart painted, first visit (s)"] = cold_painted
    TIMINGS["run chart painted, plotly cached (s)"] = warm_painted
    TIMINGS["run chart noticed by the driver, first visit (s)"] = cold
    TIMINGS["run chart noticed by the driver, plotly cached (s)"] = warm
    assert cold_painted < CHART_CEILING_S and warm < CHART_CEILING_S
    first = answers[0]
    # The dashboard's own plotly bundle (core and heatmap, 1.1 MB; not plotly's partial 1.5 MB
    # nor the full 4.8 MB: the cold first visit's time is mostly chromium evaluating it), with
    # every trace type the dashboard draws.
    assert re.search(r"/static/vendor/plotly-dashboard-[\d.]+\.min\.js$", first.url), first.url
    served = set(page.evaluate("() => Object.keys(Plotly.PlotSchema.get().traces)"))
    used = dashboard_trace_types()
    assert {"scatter", "heatmap"} <= used and used <= served, (used, served)
    headers = first.all_headers()
    assert headers.get("content-encoding") == "gzip"
    assert "immutable" in headers.get("cache-control", "") and headers.get("etag")
    assert int(headers.get("content-length", "0")) < 450_000
    assert_no_cloud_links(page)
    help_text = (
        page.inner_text("#profile-help")
        if page.locator("#profile-help[open]").count()
        else page.eval_on_selector("#profile-help", "e => e.textContent")
    )
    assert (
        "Baseline" in help_text
        and "measured from" in help_text
        and "nominal support stiffness" in help_text
    )
    labels = page.evaluate(
        "() => document.getElementById('profile-plot').layout.annotations.map(a => a.text)"
    )
    assert labels and all("% loss" in t and "−" not in t for t in labels), labels
    aligned = page.evaluate(
        """() => { const t = document.getElementById('spots-table');
            const th = t.querySelectorAll('thead th'), td = t.querySelectorAll('tbody tr:first-child > *');
            return [...th].map((h, i) => [getComputedStyle(h).textAlign, getComputedStyle(td[i]).textAlign]); }"""
    )
    assert all(a == b for a, b in aligned), aligned
    assert axe_violations(page, axe) == []
    page.watch.assert_clean()


def test_track_page_fits_a_phone_and_explains_a_single_run(
    browser: Any, live_server: LiveServer, example_run: dict[str, Any], axe: str
) -> None:
    """At 390x844 the chainage map's plot area keeps most of the width and the zone plot's
    legend goes below it; a defect seen once has no trend ("—"); plurals; axe clean."""
    context = browser.new_context(viewport={"width": 390, "height": 844})
    page = context.new_page()
    page.add_init_script(CHART_MARKS)
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    try:
        url = f"{live_server.url}/#/tracks/{example_run['track_id']}"
        t = time.perf_counter()
        page.goto(url)
        wait_for_plot(page, "#chainage-map", 2)
        noticed = time.perf_counter() - t
        map_painted = painted_s(page, "chainage-map")
        assert 0 < map_painted < CHART_CEILING_S
        TIMINGS["track chart at 390 px painted, first visit (s)"] = map_painted
        TIMINGS["track chart at 390 px noticed by the driver, first visit (s)"] = noticed
        assert_plotly_loads_with_the_page_module(page, "/static/js/pages/track/")
        wait_for_plot(page, "#zone-plot")
        width = page.evaluate("() => document.getElementById('chainage-map')._fullLayout._size.w")
        assert width >= 240, f"chainage map plot area only {width:.0f} px wide at 390 px"
        zone = page.evaluate(
            "() => { const l = document.getElementById('zone-plot')._fullLayout; return [l.legend.orientation, l._size.w]; }"
        )
        assert zone[0] == "h" and zone[1] >= 240, zone
        assert page.evaluate("() => document.documentElement.scrollWidth <= window.innerWidth + 1")
        row = page.locator("#zone-table tbody tr").first
        trend = row.locator("td.num").nth(-2).inner_text()  # the depth trend column
        assert trend == "—", trend
        assert "1 processed run " in page.inner_text("#track-lead") + " "
        assert re.search(r"\b2 single-run soft spots from 1 run\b", page.inner_text("#map-note"))
        assert_no_cloud_links(page)
        assert axe_violations(page, axe) == []
        assert not errors, errors
    finally:
        context.close()


def test_track_page_at_desktop_width_is_accessible(
    page: Any, live_server: LiveServer, example_run: dict[str, Any], axe: str
) -> None:
    """The track page at 1366 px, every section drawn (chainage map, zone plot, register,
    limits card), has no serious or critical axe violation."""
    page.goto(f"{live_server.url}/#/tracks/{example_run['track_id']}")
    wait_for_plot(page, "#chainage-map", 2)
    wait_for_plot(page, "#zone-plot")
    page.wait_for_selector("#zone-table tbody tr")
    page.wait_for_function("() => document.getElementById('limit-alert_depth_mm')?.dataset.bounds")
    page.wait_for_load_state("networkidle")
    assert axe_violations(page, axe) == []
    page.watch.assert_clean()


def test_upload_form_guides_a_first_time_user(
    page: Any, live_server: LiveServer, tmp_path: Path, axe: str
) -> None:
    """Start chainage empty and required, the recording time from the file's timestamps,
    errors next to the field in the form's words with the service's bounds, a preview with
    problems blocks the upload, a rejected upload marks its bar failed and leaves no track."""
    posts: list[str] = []
    page.on("request", lambda r: posts.append(r.url) if r.method == "POST" else None)
    page.goto(f"{live_server.url}/#/upload")
    page.wait_for_selector("#upload-button")
    assert (
        page.input_value("#start-chainage") == ""
        and page.get_attribute("#start-chainage", "required") is not None
    )
    assert "examples/example_run.csv.gz" in page.inner_text("#example-hint")
    assert axe_violations(page, axe) == []
    # The example: its recording time comes from its epoch timestamps.
    page.set_input_files("#file-input", str(EXAMPLE))
    page.wait_for_function("() => document.getElementById('recorded-at').value !== ''")
    assert page.input_value("#recorded-at").startswith(
        page.evaluate(
            "iso => { const d = new Date(iso); const p = n => String(n).padStart(2, '0'); return `${d.getFullYear()}-${p(d.getMonth() + 1)}-${p(d.getDate())}T${p(d.getHours())}`; }",
            TRUTH["recorded_at"],
        )
    )
    assert "From the file's timestamps" in page.inner_text("#recorded-at-hint")
    page.fill("#track-input", "UX line")
    page.dispatch_event("#track-input", "input")
    page.fill("#payload-kg", "-5")
    page.select_option("#vehicle-select", "table1")  # the form asks among several
    page.click("#upload-button")
    start_error = page.locator("#start-chainage-error")
    start_error.wait_for()
    assert (
        start_error.inner_text().startswith("⚠")
        or "Start chainage (m) is required" in start_error.inner_text()
    )
    assert "Start chainage (m) is required" in start_error.inner_text()
    payload_error = page.inner_text("#payload-kg-error")
    assert "Payload (kg) must be at least 0" in payload_error, payload_error
    assert page.get_attribute("#start-chainage", "aria-invalid") == "true"
    assert not [u for u in posts if u.endswith("/api/v1/runs") or u.endswith("/api/v1/tracks")]
    # A file the preview already finds wrong: the upload waits for an explicit "anyway".
    page.set_input_files(
        "#file-input",
        files=[{"name": "notes.csv", "mimeType": "text/csv", "buffer": b"hello\nworld\n"}],
    )
    page.wait_for_selector("#preview-warnings")
    page.fill("#start-chainage", "10")
    page.fill("#payload-kg", "")
    page.select_option("#vehicle-select", "table1")  # the form asks among several
    page.click("#upload-button")
    page.wait_for_selector("#upload-status.error")
    assert "Upload anyway" in page.inner_text("#upload-status")
    assert not [u for u in posts if u.endswith("/api/v1/runs")]
    page.check("#ignore-problems")
    page.select_option("#vehicle-select", "table1")  # the form asks among several
    page.click("#upload-button")
    page.wait_for_function("() => document.querySelector('.progress-box.failed')")
    assert page.inner_text(".progress-box").count("failed") >= 1
    assert "Upload failed" in page.inner_text(".progress-box")
    assert "100 %" not in page.inner_text(".progress-box")
    with live_server.api() as api:
        assert api.get("/api/v1/tracks/UX line").status_code == 404  # no track left behind
    assert axe_violations(page, axe) == []
    page.watch.assert_clean()


def test_track_is_deleted_from_its_page_after_confirmation(
    page: Any, live_server: LiveServer, axe: str, tmp_path: Path
) -> None:
    """ "Delete track…" asks in the page; confirming removes the track and its runs."""
    from engine.logio import write_run_csv
    from engine.synthetic import make_run

    run = make_run(length=120.0, speed=25.0, start_chainage_m=5.0, seed=2)
    path = tmp_path / "doomed.csv"
    write_run_csv(run.log, path, digits=8)
    with live_server.api() as api:
        r = api.post("/api/v1/runs?wait=true", files={"file": ("d.csv", path.read_bytes(), "text/csv")},
                     data={"track": "Doomed line", "start_chainage_m": "5"})  # fmt: skip
        assert r.status_code in (200, 201), r.text
        track_id, run_id = r.json()["track_id"], r.json()["id"]
    page.goto(f"{live_server.url}/#/tracks/{track_id}")
    page.click("#delete-track")
    box = page.locator("#delete-track-box")
    assert "1 run," in box.inner_text()
    assert axe_violations(page, axe) == []
    page.click("#delete-track-confirm")
    page.wait_for_url(re.compile(r".*#/$"))
    page.wait_for_selector("#track-list, #tracks-h")
    with live_server.api() as api:
        assert api.get(f"/api/v1/tracks/{track_id}").status_code == 404
        assert api.get(f"/api/v1/runs/{run_id}").status_code == 404
    page.watch.assert_clean()


def test_simulate_names_its_bands_stores_on_a_chosen_track_and_has_no_cloud_link(
    page: Any, live_server: LiveServer, axe: str
) -> None:
    """Simulate: the true zones and the detections are told apart and named in the legend,
    the run goes to the track chosen, no share/cloud link; axe clean."""
    page.goto(f"{live_server.url}/#/simulate")
    page.wait_for_selector("#simulate-button")
    assert axe_violations(page, axe) == []
    page.fill("#sim-track", "Sim choice line")
    page.click("#simulate-button")
    wait_for_plot(page, "#sim-profile-plot")
    names = page.evaluate("() => document.getElementById('sim-profile-plot').data.map(t => t.name)")
    assert "True soft zone" in names and "Detected soft spot" in names, names
    true_band = page.evaluate(
        "() => document.getElementById('sim-profile-plot').layout.shapes.filter(s => s.name === 'true-zone').map(s => [s.y0, s.y1])"
    )
    assert true_band and all(y0 >= 0.8 for y0, _ in true_band), true_band
    assert_no_cloud_links(page)
    with live_server.api() as api:
        assert api.get("/api/v1/tracks/Sim choice line").json()["n_runs"] == 1
    assert axe_violations(page, axe) == []
    page.watch.assert_clean()


@pytest.mark.slow
def test_vehicles_and_docs_pages_are_accessible_and_docs_lead_back(
    page: Any, live_server: LiveServer, axe: str
) -> None:
    page.goto(f"{live_server.url}/#/vehicles")
    page.wait_for_selector("main h1")
    page.wait_for_load_state("networkidle")
    assert axe_violations(page, axe) == []
    t = time.perf_counter()
    page.goto(f"{live_server.url}/docs")
    page.wait_for_selector(".swagger-ui .info")
    TIMINGS["/docs ready (s)"] = time.perf_counter() - t
    assert axe_violations(page, axe) == []
    page.click("#docs-back")
    page.wait_for_selector("#intro")
    page.watch.assert_clean()


def test_simulate_form_has_the_services_bounds(page: Any, live_server: LiveServer) -> None:
    """The simulate form's numbers carry the service's own bounds (its OpenAPI schema: km/h
    and % converted) and out-of-bounds values are refused in the page, in the form's words,
    before any request."""
    posts: list[str] = []
    page.on("request", lambda r: posts.append(r.url) if r.method == "POST" else None)
    page.goto(f"{live_server.url}/#/simulate")
    # The form is drawn after the page's module loads, which may come after the load event.
    page.wait_for_function(
        "() => { const e = document.getElementById('sim-accel-noise'); return e && e.dataset.bounds; }"
    )
    bounds = page.evaluate(
        """() => ['sim-length', 'sim-speed', 'sim-accel-noise', 'sim-gyro-bias'].map(id => {
            const e = document.getElementById(id); return [e.min, e.max]; })"""
    )
    # SimulateRequest: 80-5000 m, 5-80 m/s (18-288 km/h); SensorSpec: noise 0-1, bias ±0.1.
    assert bounds == [["80", "5000"], ["18", "288"], ["0", "1"], ["-0.1", "0.1"]], bounds
    loss_max = page.eval_on_selector(".zone-loss", "e => JSON.parse(e.dataset.bounds)")
    assert loss_max["max"] == 100 and loss_max["maxExclusive"], loss_max
    assert "80 to 5000 m" in page.inner_text("#sim-length-hint")
    page.fill("#sim-speed", "300")
    page.fill("#sim-accel-noise", "2")
    page.locator(".zone-loss").first.fill("100")
    page.click("#simulate-button")
    text = page.inner_text("#sim-status")
    assert "speed (km/h) must be at least 18 and at most 288" in text, text
    assert "accel noise must be at least 0 and at most 1" in text, text
    assert "(%) must be at least 0 and below 100" in text, text
    assert page.locator("#simulate-form [aria-invalid=true]").count() == 3
    assert not [u for u in posts if "/simulate" in u], posts
    page.watch.assert_clean()


def test_lists_are_read_page_by_page_to_the_end(page: Any, live_server: LiveServer) -> None:
    """The dashboard's lists (tracks on the upload and simulate forms, vehicles, a track's
    runs) are read to the end through the API's offset paging, not cut at one page: with a
    page of 2 items, every track the API counts comes back once, in the API's order."""
    with live_server.api() as api:
        for i in range(3):
            r = api.post("/api/v1/tracks", json={"name": f"zz paging line {i}"})
            assert r.status_code in (201, 409), r.text
        listed = api.get("/api/v1/tracks?limit=1000").json()
    page.goto(f"{live_server.url}/#/upload")
    page.wait_for_selector("#upload-button")
    names = page.evaluate(
        "async () => (await (await import('/static/js/api.js')).apiFetchAll('tracks', 2)).map(t => t.name)"
    )
    assert listed["count"] >= 3 and names == [t["name"] for t in listed["data"]], names
    page.wait_for_function(
        "n => document.querySelectorAll('#track-list option').length === n", arg=listed["count"]
    )
    page.watch.assert_clean()
