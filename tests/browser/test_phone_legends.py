"""Chart legends at phone width (390 px) and on a desktop (1280 px): on the run, track and
quality pages no legend covers its chart's x-axis title or falls outside its figure. A legend
placed as a fraction of the plot's height lands on the title once a phone makes the plot
short; the shared layout anchors it to the figure's bottom edge instead.
"""

from __future__ import annotations

from typing import Any

import pytest
from browser.harness import LiveServer, wait_for_plot

pytestmark = pytest.mark.browser

TRACK = "Legend line"

# Per visible chart: its legend's background box, the x-axis titles' boxes and the figure's.
BOXES = """() => [...document.querySelectorAll('.js-plotly-plot')].filter(d => d.offsetParent)
  .map(d => {
    const box = (e) => { const b = e.getBoundingClientRect();
                         return {l: b.left, r: b.right, t: b.top, b: b.bottom}; };
    const bg = d.querySelector('g.legend rect.bg');
    const titles = [...d.querySelectorAll('g[class^="g-x"][class$="title"] text')]
      .filter(t => t.textContent.trim()).map(box);
    const figure = box(d.querySelector('svg.main-svg'));
    return {id: d.id, legend: bg ? box(bg) : null, titles, figure};
  })"""


def overlaps(a: dict[str, float], b: dict[str, float]) -> bool:
    return a["l"] < b["r"] and b["l"] < a["r"] and a["t"] < b["b"] and b["t"] < a["b"]


@pytest.fixture(scope="module")
def legend_run(live_server: LiveServer) -> dict[str, Any]:
    """One simulated pass with a soft spot found (its peaks give the profile a legend)."""
    with live_server.api() as api:
        r = api.post(
            "/api/v1/simulate?wait=true",
            json={"track": TRACK, "length_m": 300, "speed_mps": 22.0, "seed": 12,
                  "zones": [{"start_m": 140, "end_m": 146, "loss": 0.5}],
                  "start_chainage_m": 10.0, "sensor": "realistic"},
        )  # fmt: skip
        assert r.status_code in (200, 201), r.text
        run = dict(r.json()["run"])
    assert run["n_soft_spots"] >= 1
    return run


@pytest.mark.parametrize("width", [390, 1280])
def test_no_legend_covers_an_axis_title(
    browser: Any, live_server: LiveServer, legend_run: dict[str, Any], width: int
) -> None:
    context = browser.new_context(viewport={"width": width, "height": 844})
    page = context.new_page()
    try:
        tid, rid = legend_run["track_id"], legend_run["id"]
        checked = []
        for route, charts in (
            (f"/runs/{rid}", ("#profile-plot", "#signals-plot")),
            (f"/tracks/{tid}", ("#aggregate-plot",)),
            (f"/tracks/{tid}/quality", ("#quality-levels",)),
        ):
            page.goto(f"{live_server.url}/#{route}")
            for sel in charts:
                wait_for_plot(page, sel)
            page.wait_for_timeout(300)  # the responsive relayout after the first paint
            for chart in page.evaluate(BOXES):
                if chart["legend"] is None:
                    continue
                leg, fig = chart["legend"], chart["figure"]
                checked.append(chart["id"])
                for title in chart["titles"]:
                    where = f"{route} #{chart['id']}"
                    assert not overlaps(leg, title), f"{where}: legend {leg} on x title {title}"
                assert fig["t"] - 1 <= leg["t"] and leg["b"] <= fig["b"] + 1, (
                    f"{route} #{chart['id']}: legend {leg} outside its figure {fig}"
                )
        # the charts with a legend were all there to check
        assert {"profile-plot", "signals-plot", "aggregate-plot", "quality-levels"} <= set(checked)
    finally:
        context.close()
