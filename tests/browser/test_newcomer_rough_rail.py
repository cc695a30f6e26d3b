"""A newcomer reaches the separated stiffness map of the public geometry set in the browser
alone, as the README's step 5 says: the four passes uploaded through the upload form (the
heavy vehicle chosen among the engine's presets, no API call first), then the track page's
register and stiffness map."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest
from browser.harness import LiveServer

pytestmark = [pytest.mark.browser, pytest.mark.slow]

DATA = Path("/work/shared/data/geometry")
TRACK = "Rough line, browser only"
PASSES = ("geo_coach_1", "geo_heavy_1", "geo_coach_2", "geo_heavy_2")
VEHICLE = {"A": "table1", "B": "heavy"}


def upload_through_the_form(page: Any, url: str, name: str) -> int:
    truth = json.loads((DATA / f"{name}.truth.json").read_text())
    page.goto(f"{url}/#/upload")
    page.set_input_files("#file-input", str(DATA / f"{name}.csv"))
    page.wait_for_selector("#preview-table")
    page.fill("#track-input", TRACK)
    page.dispatch_event("#track-input", "input")
    page.fill("#start-chainage", str(truth["start_chainage_m"]))
    vehicle = VEHICLE[truth["vehicle_key"]]
    # a preset is a choice before it is stored (the choices load after the page)
    page.wait_for_selector(f'#vehicle-select option[value="{vehicle}"]', state="attached")
    page.select_option("#vehicle-select", vehicle)
    page.click("#upload-button")
    page.wait_for_url(re.compile(r".*#/runs/\d+$"), timeout=120_000)
    return int(page.url.rsplit("/", 1)[1])


def test_the_geometry_set_uploaded_in_the_browser_shows_three_separated_spots(
    page: Any, live_server: LiveServer
) -> None:
    """Four uploads through the form, then the track page: three separated soft spots
    (separated: 4 passes, 2 loads) in the register and on the stiffness map."""
    if not DATA.is_dir():
        pytest.skip("the public geometry set is not on this machine")
    runs = [upload_through_the_form(page, live_server.url, n) for n in PASSES]
    assert len(set(runs)) == 4
    page.goto(f"{live_server.url}/#/")
    page.get_by_role("link", name=TRACK).first.click()
    page.wait_for_selector("#zone-table tbody tr", timeout=60_000)
    evidence = page.eval_on_selector_all(
        "#zone-table tbody tr", "rows => rows.map(r => r.textContent)"
    )
    separated = [e for e in evidence if "separated: 4 passes, 2 loads" in e]
    assert len(separated) == 3, evidence
    page.wait_for_selector("#map-separated", state="attached")
    assert "3 soft spots separated" in page.locator("#map-separated").inner_text()
    page.watch.assert_clean()
