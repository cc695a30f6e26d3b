"""The screens say what the engine knows, in a real browser, on the public geometry set (two
coach and two heavy passes over rough rail): the register shows each separated soft spot with
its depth, loss and evidence; a single pass says what it cannot tell and links to the stiffness
map; the stiffness message names no stretch over a zone; the upload form never picks a vehicle
silently; chainage reads km+m; no serious or critical axe violation at 1280 and 390 px.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from browser.harness import LiveServer, axe_source, axe_violations, wait_for_plot
from playwright.sync_api import expect

pytestmark = pytest.mark.browser

DATA = Path("/work/shared/data/geometry")
TRACK = "Geometry set"
PRESET = {"A": "table1", "B": "heavy"}


@pytest.fixture(scope="module")
def geo_track(live_server: LiveServer) -> dict[str, Any]:
    """The four runs uploaded as the README says (file, track, vehicle, start chainage)."""
    if not DATA.is_dir():
        pytest.skip("the public geometry set is not on this machine")
    runs = []
    with live_server.api() as api:
        for i, name in enumerate(("geo_coach_1", "geo_heavy_1", "geo_coach_2", "geo_heavy_2")):
            truth = json.loads((DATA / f"{name}.truth.json").read_text())
            r = api.post(
                "/api/v1/runs?wait=true",
                files={"file": (f"{name}.csv", (DATA / f"{name}.csv").read_bytes(), "text/csv")},
                data={
                    "track": TRACK, "vehicle": PRESET[truth["vehicle_key"]],
                    "start_chainage_m": str(truth["start_chainage_m"]),
                    "recorded_at": f"2026-05-0{i + 1}T07:00:00Z",
                },
            )  # fmt: skip
            assert r.status_code in (200, 201), r.text
            runs.append(r.json())
        track_id = api.get(f"/api/v1/tracks/{TRACK}").json()["id"]
        defects = api.get(f"/api/v1/tracks/{track_id}/defects").json()
    return {"id": track_id, "runs": runs, "defects": defects}


def register_rows(page: Any) -> list[dict[str, str]]:
    return page.evaluate(
        """() => {
            const heads = [...document.querySelectorAll('#zone-table thead th')]
                .map(th => th.textContent.trim());
            const cells = (tr) => [...tr.children].map((c, i) => [heads[i], c.textContent.trim()]);
            return [...document.querySelectorAll('#zone-table tbody tr')]
                .map(tr => Object.fromEntries(cells(tr)));
        }"""
    )


def test_register_shows_separated_spots_with_depth_loss_and_evidence(
    page: Any, live_server: LiveServer, geo_track: dict[str, Any], screenshots: Path
) -> None:
    """Three separated defects: depth > 0, a loss with its band, 'separated: 4 passes, 2
    loads' and provisional (the presets as registered, no load declared), confirmed; zones in
    km+m; the stiffness message names no stretch over them."""
    page.goto(f"{live_server.url}/#/tracks/{geo_track['id']}")
    page.wait_for_selector("#zone-table tbody tr")
    sep = [r for r in register_rows(page) if r["Evidence"].startswith("separated")]
    assert len(sep) == 3, register_rows(page)
    for row in sep:
        # the presets as registered, no load declared: separated, but provisional
        assert row["Evidence"] == "separated: 4 passes, 2 loads provisional"
        assert row["Status"] == "confirmed"
        assert float(row["Depth (mm)"]) > 0
        assert "(" in row["Loss (%)"] and "–" in row["Loss (%)"]  # the band
        assert row["Zone"].startswith("0+")
    page.wait_for_selector("#stiffness-message", state="attached")
    said = page.locator("#stiffness-message").inner_text()
    for d in geo_track["defects"]:
        assert f"0+{d['peak_m']:05.1f}" not in said
    assert "3 soft spots separated" in page.locator("#map-separated").inner_text()
    page.locator("#zones-h").scroll_into_view_if_needed()
    page.screenshot(path=str(screenshots / "track-separated.png"), full_page=False)
    page.watch.assert_clean()


def test_register_fits_a_1280_screen(
    page: Any, live_server: LiveServer, geo_track: dict[str, Any]
) -> None:
    """At 1280 px the register's thirteen columns fit without sideways scrolling (its headers
    wrap at their spaces, the evidence may take two lines), so the trends and dates are in
    view."""
    page.set_viewport_size({"width": 1280, "height": 900})
    page.goto(f"{live_server.url}/#/tracks/{geo_track['id']}")
    page.wait_for_selector("#zone-table tbody tr")
    table_w, box_w = page.evaluate(
        """() => { const t = document.getElementById('zone-table');
                   return [t.scrollWidth, t.closest('.table-scroll').clientWidth]; }"""
    )
    assert table_w <= box_w + 1, f"register {table_w} px wide in a {box_w} px box"


def test_chainage_map_draws_the_separated_spots_in_a_top_row(
    page: Any, live_server: LiveServer, geo_track: dict[str, Any]
) -> None:
    """Over rough rail no single run finds the soft spots, the separation does: the chainage
    map shows them in a top row "Separated across loads", a marker at each separated defect's
    deepest point with its extent, on the runs' depth scale (drawn by them when no run has a
    spot); a click on one opens its profile across runs (it was a count in the note only)."""
    sep = sorted(
        (d for d in geo_track["defects"] if d["source"] == "separated"), key=lambda d: d["peak_m"]
    )
    assert len(sep) == 3, geo_track["defects"]
    page.goto(f"{live_server.url}/#/tracks/{geo_track['id']}")
    page.wait_for_function(
        "() => (document.getElementById('chainage-map')?.data || [])"
        ".some(t => t.meta === 'separated')"
    )
    drawn = page.evaluate(
        """() => { const d = document.getElementById('chainage-map');
                   const t = d.data.find(t => t.meta === 'separated');
                   const e = d.data.find(t => t.meta === 'separated-extents');
                   return { x: t.x, y: t.y, ext: e.x, color: t.marker.color,
                            top: d.layout.yaxis.categoryarray.at(-1),
                            scales: d.querySelectorAll('.colorbar').length }; }"""
    )
    # no single pass has a soft spot here: the separated markers draw the depth scale
    assert drawn["scales"] == 1
    assert drawn["top"] == "Separated across loads"
    assert set(drawn["y"]) == {"Separated across loads"}
    assert sorted(drawn["x"]) == pytest.approx([d["peak_m"] for d in sep])
    assert sorted(v for v in drawn["ext"] if v is not None) == pytest.approx(
        sorted([d["start_m"] for d in sep] + [d["end_m"] for d in sep])
    )
    assert sorted(drawn["color"]) == pytest.approx(sorted(d["depth_mm"] for d in sep))
    # a click on the marker of a defect other than the one shown first opens that one
    # (the register comes most urgent first; the page shows the first defect at the start)
    target = [d for d in geo_track["defects"] if d["source"] == "separated"][-1]
    page.locator("#chainage-map").scroll_into_view_if_needed()
    xy = page.evaluate(
        """(x) => { const d = document.getElementById('chainage-map');
                    const fl = d._fullLayout;
                    const box = d.querySelector('.nsewdrag').getBoundingClientRect();
                    return [box.left + fl.xaxis.l2p(x),
                            box.top + fl.yaxis.l2p(fl.yaxis.d2l('Separated across loads'))]; }""",
        target["peak_m"],
    )
    page.mouse.click(*xy)
    km = f"{int(target['start_m'] // 1000)}+{target['start_m'] % 1000:05.1f}"
    page.wait_for_function(
        "km => (document.getElementById('zone-info').textContent || '').startsWith('Zone ' + km)",
        arg=km,
    )
    page.watch.assert_clean()


def test_separated_defect_across_runs_shows_each_load_s_dip(
    page: Any, live_server: LiveServer, geo_track: dict[str, Any]
) -> None:
    """A separated defect hides in the rail geometry on the loaded profiles; "Defect across
    runs" draws each pass minus the separated geometry (on by default there), so the heavy
    passes' dips are deeper than the coaches' at the zone, and the toggle brings the loaded
    levels (with the aggregate) back."""
    sep = [d for d in geo_track["defects"] if d["source"] == "separated"]
    assert sep
    zone = sep[0]
    page.goto(f"{live_server.url}/#/tracks/{geo_track['id']}")
    page.wait_for_selector("#zone-table tbody tr")
    km = f"{int(zone['start_m'] // 1000)}+{zone['start_m'] % 1000:05.1f}"
    page.locator("#zone-table tbody tr", has_text=km).first.get_by_role("button").click()
    page.wait_for_function(
        "() => (document.getElementById('zone-info').textContent || '').includes('minus the')"
    )
    toggle = page.locator("#zone-minus-geometry")
    assert toggle.is_visible() and toggle.is_checked()
    lows = page.evaluate(
        """([a, b]) => document.getElementById('zone-plot').data
             .filter(t => String(t.meta).startsWith('run-'))
             .map(t => [t.name, Math.min(...t.y.filter((v, i) => v !== null
                                                     && t.x[i] >= a && t.x[i] <= b))])""",
        [zone["start_m"], zone["end_m"]],
    )
    heavy = [low for name, low in lows if name.endswith("196 kN")]
    coach = [low for name, low in lows if name.endswith("88 kN")]
    assert len(heavy) == 2 and len(coach) == 2, lows
    # about twice the load, about twice the dip (a geometric dip would be the same for all)
    assert max(heavy) < 1.5 * min(coach) < 0, lows
    title = "() => document.getElementById('zone-plot')._fullLayout.yaxis.title.text"
    assert page.evaluate(title) == "Level minus geometry (mm)"
    toggle.uncheck()
    page.wait_for_function(f"() => ({title})() === 'Loaded level (mm)'")
    metas = page.evaluate("() => document.getElementById('zone-plot').data.map(t => t.meta)")
    assert "aggregate" in metas
    page.watch.assert_clean()


def test_home_needs_attention_labels_the_provisional_defects(
    page: Any, live_server: LiveServer, geo_track: dict[str, Any]
) -> None:
    """The start page's "Needs attention" lists the geometry set's separated defects at a
    limit level with the register's "provisional" label (the presets as registered, no load
    declared), not as findings."""
    provisional = [d for d in geo_track["defects"] if d["provisional"] and d["level"]]
    assert provisional, geo_track["defects"]
    page.goto(f"{live_server.url}/#/")
    page.wait_for_selector("#attention-table tbody tr")
    # (the live server is shared: other tracks' defects may fill the table's 12 rows too)
    badges = page.evaluate(
        """t => [...document.querySelectorAll('#attention-table tbody tr')]
                .filter(tr => tr.children[1].textContent.trim() === t)
                .map(tr => tr.querySelector('.badge.provisional')?.textContent ?? null)""",
        TRACK,
    )
    assert badges and badges == ["provisional"] * len(badges), badges
    page.watch.assert_clean()


def test_a_single_rough_pass_says_what_it_cannot_tell(
    page: Any, live_server: LiveServer, geo_track: dict[str, Any]
) -> None:
    """A single pass over rough rail does not claim 'No soft spot detected': it says what one
    pass cannot tell, in sentences, and links to the track's stiffness map."""
    run = geo_track["runs"][0]
    page.goto(f"{live_server.url}/#/runs/{run['id']}")
    page.wait_for_selector("#run-summary")
    summary = page.locator("#run-summary").inner_text()
    assert "No soft spot detected" not in summary
    assert "cannot tell" in summary
    link = page.locator("#run-stiffness-link")
    assert link.get_attribute("href") == f"#/tracks/{run['track_id']}?view=stiffness"
    page.watch.assert_clean()


def test_upload_form_never_picks_a_vehicle_silently(
    page: Any, live_server: LiveServer, geo_track: dict[str, Any]
) -> None:
    """Several vehicles: a new track, or the geometry track (as many coach as heavy runs),
    and the form asks — no vehicle chosen, the reason shown, an upload without one refused
    at the field; a track of coach runs only proposes its usual vehicle and says so."""
    with live_server.api() as api:
        r = api.post(
            "/api/v1/runs",
            files={"file": ("c.csv", (DATA / "geo_coach_1.csv").read_bytes(), "text/csv")},
            data={"track": "Coach line", "vehicle": "table1", "start_chainage_m": "25"},
        )
        assert r.status_code in (200, 201), r.text
    page.goto(f"{live_server.url}/#/upload")
    page.wait_for_selector("#vehicle-select option", state="attached")
    why = page.locator("#vehicle-why")
    for track, reason in (("A brand new line", "no runs yet"), (TRACK, "as many of")):
        page.fill("#track-input", track)
        page.wait_for_function(
            "r => document.getElementById('vehicle-why').textContent.includes(r)", arg=reason
        )
        assert page.locator("#vehicle-select").input_value() == ""
        assert "choose the vehicle" in why.inner_text()
    page.click("#upload-button")
    assert "choose the vehicle" in page.locator("#vehicle-select").evaluate(
        "el => el.closest('.field').textContent"
    )
    page.fill("#track-input", "Coach line")
    page.wait_for_function(
        "() => document.getElementById('vehicle-why').textContent.includes('most runs')"
    )
    assert page.locator("#vehicle-select").input_value() == "table1"
    page.watch.assert_clean()


@pytest.mark.parametrize("width", [1280, 390])
def test_no_serious_axe_violation_on_the_changed_pages(
    page: Any, live_server: LiveServer, geo_track: dict[str, Any], width: int
) -> None:
    """axe-core: no serious or critical violation on the track page (register, stiffness map,
    plan view), a run page and the upload form, at desktop and phone width."""
    page.set_viewport_size({"width": width, "height": 900})
    src = axe_source()
    found = {}
    for url, ready in (
        (f"#/tracks/{geo_track['id']}", "#zone-table tbody tr"),
        (f"#/runs/{geo_track['runs'][0]['id']}", "#run-summary"),
        ("#/upload", "#vehicle-select option"),
    ):
        page.goto(f"{live_server.url}/{url}")
        page.wait_for_selector(ready, state="attached")
        if url.startswith("#/tracks"):
            wait_for_plot(page, "#chainage-map")
        found[url] = axe_violations(page, src)
    assert not any(found.values()), found


@pytest.mark.slow
def test_a_track_being_reprocessed_reads_as_updating_then_loads(
    page: Any, live_server: LiveServer, geo_track: dict[str, Any]
) -> None:
    """The register answered 409 ``status: "updating"`` (a vehicle edit reprocessing the
    track's runs) twice: the page says "Updating — N runs left" with the server's count, no
    error, and shows the register once the read succeeds; the notice then goes away."""
    answers = [3, 2]
    seen: list[int] = []

    def defects(route: Any) -> None:
        if answers:
            left = answers.pop(0)
            seen.append(left)
            route.fulfill(
                status=409,
                content_type="application/json",
                body=json.dumps(
                    {
                        "detail": {
                            "message": "the track is updating",
                            "status": "updating",
                            "runs_left": left,
                        }
                    }
                ),  # fmt: skip
            )
        else:
            route.continue_()

    page.route("**/api/v1/tracks/*/defects", defects)
    page.goto(f"{live_server.url}/#/tracks/{geo_track['id']}")
    updating = page.locator("#updating")
    expect(updating).to_contain_text("Updating — 3 runs left")
    expect(updating).to_contain_text("Updating — 2 runs left")
    page.wait_for_selector("#zone-table tbody tr")
    expect(updating).to_be_hidden()
    assert seen == [3, 2]
    assert "Cannot load" not in page.locator("main").inner_text()
    assert len([r for r in register_rows(page) if r["Evidence"].startswith("separated")]) == 3
    page.watch.assert_clean()


def test_alignment_notice_names_every_status(
    page: Any, live_server: LiveServer, geo_track: dict[str, Any]
) -> None:
    """The track page's notice of runs: a placed run is said to be in the register at its
    logged (or GNSS) chainage, an unaligned one to be left out with its reason; reference and
    aligned runs get no notice (the runs list's statuses are set here to one of each)."""
    statuses = ["reference", "aligned", "placed", "unaligned"]

    def runs(route: Any) -> None:
        body = route.fetch().json()
        for r, st in zip(body["data"], statuses, strict=False):
            r["alignment"] = {"status": st, "offset_m": 0.0, "correlation": None,
                              "overlap_m": None, "reason": f"why {st}"}  # fmt: skip
        route.fulfill(json=body)

    page.route("**/api/v1/runs?track=*", runs)
    page.goto(f"{live_server.url}/#/tracks/{geo_track['id']}")
    page.wait_for_selector("#alignment-notices")
    placed = page.locator("#placed-runs").inner_text()
    assert placed.startswith("1 run is in the aggregated profile and the register")
    assert "aligned again as the track gains passes" in placed
    unaligned = page.locator("#unaligned-runs").inner_text()
    assert unaligned.startswith("1 run was not aligned to this track and is left out")
    assert "why unaligned" in unaligned
    notices = page.locator("#alignment-notices").inner_text()
    assert "why reference" not in notices and "why aligned" not in notices
    assert page.locator("#alignment-notices .message").count() == 2
    page.watch.assert_clean()


@pytest.mark.slow
@pytest.mark.parametrize("width", [1280, 390])
def test_no_serious_axe_violation_on_the_other_pages(
    page: Any, live_server: LiveServer, geo_track: dict[str, Any], width: int
) -> None:
    """axe-core: no serious or critical violation on the home page, the track's quality
    view, the simulate form, the vehicle list, a vehicle's page and the track's HTML report,
    at desktop and phone width (the track, run, upload and plan views: the tests above and
    test_gnss)."""
    page.set_viewport_size({"width": width, "height": 900})
    src = axe_source()
    found = {}
    for url, ready in (
        ("/#/", "#runs-table"),
        (f"/#/tracks/{geo_track['id']}/quality", "main h1"),
        ("/#/simulate", "main form"),
        ("/#/vehicles", "main h1"),
        ("/#/vehicles/table1", "main h1"),
        (f"/api/v1/tracks/{geo_track['id']}/report", "h1"),
    ):
        page.goto(f"{live_server.url}{url}")
        page.wait_for_selector(ready)
        page.wait_for_load_state("networkidle")
        found[url] = axe_violations(page, src)
    assert not any(found.values()), found
