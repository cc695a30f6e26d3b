"""The track quality view (EN 13848) in a real browser: sections coloured by class along
chainage as the API classes them, the D1/D2 levels with the isolated defects, the exceedance
list and the section table as the API answers them, the exports, the way in from the track
page; axe-core finds no serious or critical violation."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from browser.harness import LiveServer, axe_source, axe_violations, wait_for_plot

pytestmark = pytest.mark.browser

TRACK = "Quality line"
RAIL = {"spectrum": "german-low", "seed": 33}


@pytest.fixture(scope="module")
def quality(live_server: LiveServer) -> Iterator[dict[str, Any]]:
    """Three coach runs over an irregular 450 m line, low D1 limits so that its largest
    peaks are defects, line speeds in two ranges. Yields the API's quality answer."""
    with live_server.api() as api:
        for k in range(3):
            r = api.post(
                "/api/v1/simulate?wait=true",
                json={
                    "track": TRACK, "length_m": 450, "speed_mps": 22.0 + 2.0 * k, "zones": [],
                    "start_chainage_m": 10.0 + (0.8, -1.0, 0.4)[k], "sensor": "realistic",
                    "seed": 330 + k, "irregularity": RAIL,
                    "recorded_at": f"2026-{3 + k:02d}-01T06:00:00Z",
                },
            )  # fmt: skip
            assert r.status_code in (200, 201), r.text
        tid = api.get(f"/api/v1/tracks/{TRACK}").json()["id"]
        r = api.put(f"/api/v1/tracks/{tid}/quality-limits",
                    json={"isolated_mm": {"D1": [[1.5, 2.0, 2.5]] * 5}})  # fmt: skip
        assert r.status_code == 200, r.text
        r = api.put(f"/api/v1/tracks/{tid}/line-speeds", json={"ranges": [
            {"from_m": 0, "to_m": 200, "speed_kmh": 100},
            {"from_m": 200, "to_m": 600, "speed_kmh": 160},
        ]})  # fmt: skip
        assert r.status_code == 200, r.text
        q = api.get(f"/api/v1/tracks/{tid}/quality").json()
    yield {"id": tid, "q": q}


@pytest.mark.slow
def test_quality_view_shows_classes_levels_and_exceedances(
    page: Any, live_server: LiveServer, quality: dict[str, Any]
) -> None:
    """From the track page's link: one bar per classed section in its class's trace, the D1
    and D2 traces and a marker per defect, the defect table row for row as the API lists them,
    the section table with passes, exports for CSV and GeoJSON, the repeatability, what the
    coach's body cannot see and which limit tables are unverified defaults; axe clean."""
    q = quality["q"]
    assert q["defects"], "the low limits should make some D1 peak a defect"
    page.goto(f"{live_server.url}/#/tracks/{quality['id']}")
    page.locator("#track-quality-link").click()
    wait_for_plot(page, "#quality-levels", 2)
    wait_for_plot(page, "#quality-classes", 1)
    bars = page.evaluate(
        "() => document.getElementById('quality-classes').data"
        ".map(t => [t.meta, t.x.filter(v => v !== null).length / 2])"
    )
    want: dict[str, int] = {}
    for s in q["sections"]:
        if s["quality_class"]:
            want[f"class-{s['quality_class']}"] = want.get(f"class-{s['quality_class']}", 0) + 1
    assert dict(bars) == want
    metas = page.evaluate("() => document.getElementById('quality-levels').data.map(t => t.meta)")
    assert "d1" in metas and "d2" in metas
    markers = page.evaluate(
        """() => document.getElementById('quality-levels').data
                 .filter(t => (t.meta || '').startsWith('defect-'))
                 .reduce((n, t) => n + t.x.length, 0)"""
    )
    assert markers == len(q["defects"])
    rows = page.locator("#quality-defects tbody tr")
    assert rows.count() == len(q["defects"])
    first = rows.nth(0).locator("td").all_inner_texts()
    assert first[0] == f"{q['defects'][0]['peak_m']:.1f}" and first[1] == q["defects"][0]["band"]
    sec_rows = page.locator("#quality-sections tbody tr")
    assert sec_rows.count() == len(q["sections"])
    assert sec_rows.nth(0).locator("td").nth(4).inner_text() == str(q["sections"][0]["n_passes"])
    assert page.locator("a[href$='.geojson?section_m=200']").count() == 1
    assert page.locator("a[href*='quality.csv']").count() == 1
    facts = page.locator("#quality-facts li").all_inner_texts()
    assert any("Repeatability" in t for t in facts)
    # one precision for the blind wavelengths (the API's 16.52, 5.51, 3.3 m read 16.5, 5.5, 3.3)
    blind = next(t for t in facts if t.startswith("table1 at"))
    assert "bounce blind at 16.5, 5.5, 3.3 m" in blind, blind
    # the basis in words, its header explained
    basis = sec_rows.nth(0).locator("td").nth(8).inner_text()
    assert basis in ("separated geometry", "loaded profile", "both"), basis
    assert "separated from the support" in (
        page.locator("#quality-sections th", has_text="Level from").get_attribute("title") or ""
    )
    # the track's own D1 limits; the other tables are still the unverified defaults, and said so
    assert q["unverified_limits"] == ["isolated_mm.D2", "class_sd_mm"]
    said = page.locator("#quality-unverified").inner_text()
    assert "not verified" in said and all(t in said for t in q["unverified_limits"])
    # said once: the notes do not repeat the unverified tables in other words
    assert page.locator("body").inner_text().count("not verified") == 1
    assert axe_violations(page, axe_source()) == []


def test_quality_view_says_none_when_no_isolated_defect(page: Any, live_server: LiveServer) -> None:
    """A smooth line (no irregularity) has no isolated defect at a limit level: the defect
    table says "None" in a row of its own, not an empty body that reads as not loaded."""
    track = "Quality smooth line"
    with live_server.api() as api:
        r = api.post(
            "/api/v1/simulate?wait=true",
            json={"track": track, "length_m": 300, "speed_mps": 22.0, "zones": [],
                  "start_chainage_m": 10.0, "sensor": "realistic", "seed": 341},
        )  # fmt: skip
        assert r.status_code in (200, 201), r.text
        tid = api.get(f"/api/v1/tracks/{track}").json()["id"]
        q = api.get(f"/api/v1/tracks/{tid}/quality").json()
    assert q["sections"] and q["defects"] == [], q["defects"]
    page.goto(f"{live_server.url}/#/tracks/{tid}/quality")
    rows = page.locator("#quality-defects tbody tr")
    rows.first.wait_for()
    assert rows.count() == 1
    assert rows.first.inner_text().startswith("None: no isolated defect")
    page.watch.assert_clean()
