"""The track view's stiffness map in a real browser (issue 10): on an irregular track passed by
two wheel loads it draws the support stiffness in % of nominal, coloured by the track's loss
limits, with the unloaded geometry, the separated soft spot and the contributing passes; on a
track with one wheel load it draws no stiffness and says why, and so does the run view.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from browser.harness import LiveServer, wait_for_plot

pytestmark = pytest.mark.browser

MIXED = "Stiffness line"
COACHES = "Coach line"
RAIL = {"spectrum": "german-low", "seed": 11}
ZONE = {"start_m": 150.0, "end_m": 157.0, "loss": 0.5}


def simulate(api: Any, track: str, vehicle: str, speed: float, seed: int) -> dict[str, Any]:
    r = api.post(
        "/api/v1/simulate?wait=true",
        json={
            "track": track, "vehicle": vehicle, "length_m": 320, "speed_mps": speed,
            "zones": [ZONE], "start_chainage_m": 12.0, "sensor": "realistic", "seed": seed,
            "irregularity": RAIL,
        },
    )  # fmt: skip
    assert r.status_code in (200, 201), r.text
    return dict(r.json()["run"])


@pytest.fixture(scope="module")
def tracks(live_server: LiveServer) -> Iterator[dict[str, Any]]:
    """Two coaches and a heavy vehicle over one irregular track; one coach over another."""
    with live_server.api() as api:
        for vehicle, speed, seed in (("table1", 22.0, 1), ("heavy", 21.0, 2), ("table1", 26.0, 3)):
            simulate(api, MIXED, vehicle, speed, seed)
        coach = simulate(api, COACHES, "table1", 24.0, 4)
        mixed_id = api.get(f"/api/v1/tracks/{MIXED}").json()["id"]
        st = api.get(f"/api/v1/tracks/{mixed_id}/stiffness").json()
        coach_id = coach["track_id"]
    yield {"mixed": mixed_id, "stiffness": st, "coach_track": coach_id, "coach_run": coach}


@pytest.mark.slow
def test_stiffness_map_draws_stiffness_geometry_and_loads(
    page: Any, live_server: LiveServer, tracks: dict[str, Any]
) -> None:
    """The stiffness map shows % of nominal with its band, the soft zone's points in the colour
    of the limit its loss reaches, the unloaded geometry, the separated soft spot and the three
    passes with their wheel loads (the heavy one about twice the coaches')."""
    st = tracks["stiffness"]
    assert st["separable"] and st["soft_spots"], st["message"]
    page.goto(f"{live_server.url}/#/tracks/{tracks['mixed']}")
    wait_for_plot(page, "#stiffness-map", 4)
    metas = page.evaluate("() => document.getElementById('stiffness-map').data.map(t => t.meta)")
    assert "stiffness" in metas and "geometry" in metas
    levels = [m for m in metas if m and m.startswith("level-")]
    assert levels, metas
    lowest = page.evaluate(
        """() => Math.min(...document.getElementById('stiffness-map').data
                 .find(t => t.meta === 'stiffness').y.filter(v => v !== null))"""
    )
    assert lowest < 80, lowest
    spots = page.locator("#stiffness-spots tbody tr")
    assert spots.count() == len(st["soft_spots"])
    assert page.locator("#stiffness-spots tbody tr td").nth(2).inner_text() == (
        f"{st['soft_spots'][0]['stiffness_loss_pct']:.0f}"
    )
    items = page.locator("#stiffness-contributors li").all_inner_texts()
    assert len(items) == 3
    assert sum("(heavy)" in t for t in items) == 1 and sum("(table1)" in t for t in items) == 2
    kn = [float(t.split(": ")[1].split(" kN")[0]) for t in items]
    assert max(kn) / min(kn) > 1.8
    shapes = page.evaluate(
        "() => document.getElementById('stiffness-map').layout.shapes.map(s => s.name)"
    )
    assert shapes.count("separated-spot") == len(st["soft_spots"])


def test_one_wheel_load_says_not_separable(
    page: Any, live_server: LiveServer, tracks: dict[str, Any]
) -> None:
    """A track passed by one vehicle type: no stiffness drawn, the plain message instead; the
    run view of that run says the same and lists no stiffness loss."""
    page.goto(f"{live_server.url}/#/tracks/{tracks['coach_track']}")
    page.wait_for_selector("#stiffness-message:not([hidden])")
    text = page.locator("#stiffness-message").inner_text()
    # where (km+m) and what would separate it, as a sentence
    assert text.startswith("Geometry and stiffness are not separable at 0+"), text
    assert "or a survey, would separate them." in text
    assert page.locator("#stiffness-map").is_hidden()
    run = tracks["coach_run"]
    page.goto(f"{live_server.url}/#/runs/{run['id']}")
    page.wait_for_selector("#run-stiffness-message")
    assert "cannot tell" in page.locator("#run-summary").inner_text()
    assert "stiffness map" in page.locator("#run-stiffness-message").inner_text()
    losses = page.locator("#spots-table tbody tr td:nth-child(6)").all_inner_texts()
    assert all(v.strip() in ("—", "") for v in losses), losses


def test_a_track_whose_separation_is_being_redone_says_so_and_reloads(
    page: Any, live_server: LiveServer, tracks: dict[str, Any]
) -> None:
    """While a just-stored run's separation waits (the API's ``updating``; the worker redoes
    it within a second or so, so the answer is made to say it here), the card says it is
    updating besides its usual message and reloads by itself; then the plain message is back.
    """
    track = tracks["coach_track"]
    answers: list[bool] = []

    def updating_once(route: Any) -> None:
        body = route.fetch().json()
        body["updating"] = not answers
        answers.append(body["updating"])
        route.fulfill(json=body)

    page.route(f"**/api/v1/tracks/{track}/stiffness", updating_once)
    page.goto(f"{live_server.url}/#/tracks/{track}")
    page.wait_for_selector("#stiffness-message:not([hidden])")
    text = page.locator("#stiffness-message").inner_text()
    assert text.startswith("Updating: a run stored a moment ago") and "not separable" in text
    page.wait_for_function(
        "() => !document.getElementById('stiffness-message').textContent.startsWith('Updating')",
        timeout=10_000,
    )
    assert answers == [True, False]  # reloaded once, by itself
    assert "not separable" in page.locator("#stiffness-message").inner_text()


@pytest.mark.slow
def test_provisional_spots_are_labelled_and_the_banners_say_why_and_what_to_do(
    page: Any, live_server: LiveServer, tracks: dict[str, Any]
) -> None:
    """The mixed track's passes are the registered presets, none calibrated and no run with a
    declared load: its separated soft spots are provisional. The stiffness map's spot table
    and the register label each one "provisional", and a banner above each names the
    vehicles and their runs and says to calibrate them or declare the runs' loads."""
    st = tracks["stiffness"]
    assert st["soft_spots"] and all(s["provisional"] for s in st["soft_spots"]), st["soft_spots"]
    with live_server.api() as api:
        defects = api.get(f"/api/v1/tracks/{tracks['mixed']}/defects").json()
    provisional = [d for d in defects if d["provisional"]]
    assert provisional and all(d["source"] == "separated" for d in provisional)
    page.goto(f"{live_server.url}/#/tracks/{tracks['mixed']}")
    page.wait_for_selector("#stiffness-spots tbody tr")
    labels = page.locator("#stiffness-spots tbody .badge.provisional")
    assert labels.count() == len(st["soft_spots"])
    assert labels.first.inner_text() == "provisional"
    assert labels.first.get_attribute("title") == st["soft_spots"][0]["provisional_reason"]
    banner = page.locator("#stiffness-provisional")
    register_banner = page.locator("#register-provisional")
    for box in (banner, register_banner):
        box.wait_for()
        text = box.inner_text()
        assert text.startswith("Provisional: "), text
        assert "vehicle heavy: no calibration and no declared load on its run" in text
        assert "vehicle table1: no calibration and no declared load on its runs" in text
        assert "Calibrate each vehicle named" in text and "declare each run's load" in text
    page.wait_for_selector("#zone-table tbody tr")
    marked = page.locator("#zone-table tbody .badge.provisional")
    assert marked.count() == len(provisional)
    page.watch.assert_clean()
