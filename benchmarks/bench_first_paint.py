"""Where a cold first visit's chart time goes: run and track page in Debian chromium.

For each repetition a fresh browser context (empty cache) opens the run page of the example
run (``examples/example_run.csv.gz``) and waits for its profile chart, then another fresh
context at 390x844 (a phone) opens its track page and waits for the chainage map. Reported
for the run page, ms from the navigation: DOMContentLoaded (the shell's ES modules loaded),
plotly.js requested and fetched (resource timing: bytes on the wire and decoded), plotly.js
defined (its script parsed and evaluated: ``window.Plotly`` set), the chart painted (the
animation frame in which its SVG is first there: ``CHART_MARKS``, the browser's own measure)
and noticed (when the driver's wait for it returned: the "in ... s" wall-clock figures, which
also hold the driver's delay in noticing, e.g. behind a long task that follows the paint). With
``--trace`` chromium's own trace adds the time V8 spent on the plotly script
(``v8.parseOnBackground``: streaming compile off the main thread; ``EvaluateScript``: running
its top level, lazy compiles included).

    python benchmarks/bench_first_paint.py [--reps 3] [--bundle B] [--trace] [--static DIR]

``--bundle cartesian`` makes the service serve plotly's partial bundle (as when the dashboard's
own bundle cannot be built by scripts/_plotly.sh), ``--bundle full`` the plotly package's full
bundle (as without npm), ``--static DIR`` another dashboard (e.g. an older
commit's ``static/``: ``git archive COMMIT static | tar -x -C DIR/..``), for a before/after
on the same machine.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO), str(REPO / "tests")]

from browser.harness import (  # noqa: E402
    CHART_MARKS,
    CHROMIUM,
    CHROMIUM_ARGS,
    VIEWPORT,
    ensure_plotly_bundle,
    start_server,
    stop_server,
)

EXAMPLE = REPO / "examples" / "example_run.csv.gz"
TRUTH = json.loads((REPO / "examples" / "example_run.truth.json").read_text())
PHONE = {"width": 390, "height": 844}
TRACK_READY = (
    "() => { const gd = document.getElementById('chainage-map');"
    " return gd && gd.data && gd.data.length >= 2 && gd._fullLayout"
    " && gd.querySelector('.main-svg'); }"
)
READY = (
    "() => { const gd = document.getElementById('profile-plot');"
    " return gd && gd._fullLayout && gd.querySelector('.main-svg'); }"
)
TIMES = """() => {
  const n = performance.getEntriesByType('navigation')[0];
  const r = performance.getEntriesByType('resource').find(e => e.name.includes('plotly'));
  const m = performance.getEntriesByName('plotly-defined')[0];
  return { dom_content_loaded: n.domContentLoadedEventEnd, plotly_fetch_start: r.startTime,
           plotly_fetched: r.responseEnd, plotly_wire_bytes: r.transferSize,
           plotly_decoded_bytes: r.decodedBodySize, plotly_defined: m ? m.startTime : null,
           first_draw_called: (performance.getEntriesByName('first-draw')[0] || {}).startTime,
           html_fetched: n.responseEnd, html_first_byte: n.responseStart,
           page_module_fetched: Math.max(0, ...performance.getEntriesByType('resource')
             .filter(e => e.name.includes('/pages/')).map(e => e.responseEnd)),
           data_fetched: Math.max(0, ...performance.getEntriesByType('resource')
             .filter(e => e.name.includes('/api/')).map(e => e.responseEnd)),
           chart_painted: ['profile-plot', 'chainage-map'].map(id =>
             (performance.getEntriesByName('chart-painted:' + id)[0] || {}).startTime)
             .find(t => t !== undefined),
           chart_noticed: performance.now() }; }"""
TRACE_CATEGORIES = ["devtools.timeline", "v8", "disabled-by-default-v8.compile"]


def v8_times(trace: Path) -> dict[str, float]:
    """ms of each complete trace event on plotly's script (parse, evaluate)."""
    events = json.loads(trace.read_text())
    events = events["traceEvents"] if isinstance(events, dict) else events
    out: dict[str, float] = {}
    for e in events:
        data = (e.get("args") or {}).get("data") or {}
        if e.get("ph") == "X" and "plotly" in str(data.get("url", "")):
            out[e["name"]] = out.get(e["name"], 0.0) + e.get("dur", 0) / 1000
    return {k: round(v, 1) for k, v in out.items() if v >= 1}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument(
        "--bundle", choices=["dashboard", "cartesian", "full"], default="dashboard",
        help="plotly.js served: core+heatmap (built), plotly's partial bundle, the full one",
    )  # fmt: skip
    ap.add_argument("--trace", action="store_true", help="add V8's parse/evaluate times")
    ap.add_argument("--static", type=Path, help="serve this dashboard directory instead")
    args = ap.parse_args()
    from playwright.sync_api import sync_playwright

    ensure_plotly_bundle()
    tmp = Path(tempfile.mkdtemp())
    settings = {}
    if args.bundle != "dashboard":
        settings["TRACKPROFILE_PLOTLY_DASHBOARD_JS"] = str(tmp / "none.js")
    if args.bundle == "full":
        settings["TRACKPROFILE_PLOTLY_PARTIAL_JS"] = str(tmp / "none.js")
    if args.static:
        settings["TRACKPROFILE_STATIC_DIR"] = str(args.static.resolve())
    server = start_server(tmp, settings=settings)
    try:
        with server.api() as api:
            r = api.post(
                "/api/v1/runs?wait=true",
                files={"file": (EXAMPLE.name, EXAMPLE.read_bytes(), "application/gzip")},
                data={"track": "bench", "start_chainage_m": str(TRUTH["start_chainage_m"])},
            )
            r.raise_for_status()
            url = f"{server.url}/#/runs/{r.json()['id']}"
            track_url = f"{server.url}/#/tracks/{r.json()['track_id']}"
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
            for rep in range(args.reps):
                context = browser.new_context(viewport=VIEWPORT)
                page = context.new_page()
                page.add_init_script(CHART_MARKS)
                trace = tmp / f"trace{rep}.json"
                if args.trace:
                    browser.start_tracing(page=page, path=str(trace), categories=TRACE_CATEGORIES)
                t = time.perf_counter()
                page.goto(url)
                page.wait_for_function(READY)
                total = time.perf_counter() - t
                times = page.evaluate(TIMES)
                if args.trace:
                    browser.stop_tracing()
                    times["v8_ms"] = v8_times(trace)
                ms = {k: round(v) if isinstance(v, float) else v for k, v in times.items()}
                context.close()
                context = browser.new_context(viewport=PHONE)
                page = context.new_page()
                page.add_init_script(CHART_MARKS)
                t = time.perf_counter()
                page.goto(track_url)
                page.wait_for_function(TRACK_READY)
                phone = time.perf_counter() - t
                track_ms = {
                    k: round(v) if isinstance(v, float) else v
                    for k, v in page.evaluate(TIMES).items()
                }
                context.close()
                print(
                    f"rep {rep}: run chart in {total:.2f} s"
                    f" (painted {ms['chart_painted'] / 1000:.2f} s),"
                    f" track chart at 390 px in {phone:.2f} s"
                    f" (painted {track_ms['chart_painted'] / 1000:.2f} s)",
                    json.dumps(ms),
                    "track:",
                    json.dumps(track_ms),
                )
            browser.close()
    finally:
        stop_server(server)


if __name__ == "__main__":
    main()
