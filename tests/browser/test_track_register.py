"""The track view's defect register in a real browser: status, priority and level per defect in
the service's order, the aggregated profile with its spread band, alerts since a date, the
limits form (a refused value names its field; saved limits re-rank the register) and exports.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from browser.harness import LiveServer, wait_for_plot

pytestmark = pytest.mark.browser

TRACK = "Register line"


@pytest.fixture(scope="module")
def register_track(live_server: LiveServer) -> Iterator[tuple[int, list[dict[str, Any]]]]:
    """Four simulated monthly runs over one line: a steady 50 % zone and one deepening from
    25 % to 55 % stiffness loss. Yields the track id and its register (from the API)."""
    with live_server.api() as api:
        for k in range(4):
            r = api.post(
                "/api/v1/simulate?wait=true",
                json={
                    "track": TRACK,
                    "length_m": 400,
                    "speed_mps": 20.0 + 3.0 * k,
                    "zones": [
                        {"start_m": 120, "end_m": 125, "loss": 0.5},
                        {"start_m": 250, "end_m": 256, "loss": 0.25 + 0.1 * k},
                    ],
                    "start_chainage_m": 20.0 + (1.5, -2.0, 3.0, -1.0)[k],
                    "sensor": "realistic",
                    "seed": 40 + k,
                    "recorded_at": f"2025-{3 + k:02d}-10T06:00:00Z",
                },
            )
            assert r.status_code in (200, 201), r.text
            assert r.json()["run"]["alignment"]["status"] in ("reference", "aligned")
        track_id = api.get(f"/api/v1/tracks/{TRACK}").json()["id"]
        defects = api.get(f"/api/v1/tracks/{track_id}/defects").json()
    assert len(defects) >= 2
    yield track_id, defects


def table_rows(page: Any) -> list[dict[str, str]]:
    """The register table as {column title: cell text} per row, in display order."""
    return page.evaluate(
        """() => {
            const heads = [...document.querySelectorAll('#zone-table thead th')]
                .map(th => th.textContent.trim());
            const cells = (tr) => [...tr.children].map((c, i) => [heads[i], c.textContent.trim()]);
            return [...document.querySelectorAll('#zone-table tbody tr')]
                .map(tr => Object.fromEntries(cells(tr)));
        }"""
    )


@pytest.mark.slow
def test_track_view_shows_the_register_with_status_and_priority(
    page: Any, live_server: LiveServer, register_track: tuple[int, list[dict[str, Any]]]
) -> None:
    """The register table lists every defect in the service's priority order with its priority,
    level, status, its evidence (kind, passes, loads) and trend; the deepening zone shows as
    worsening; the aggregated profile is drawn with its spread band; alerts and exports are
    offered."""
    track_id, defects = register_track
    page.goto(f"{live_server.url}/#/tracks/{track_id}")
    wait_for_plot(page, "#chainage-map")
    page.wait_for_selector("#zone-table tbody tr")
    assert page.locator("#zones-h").inner_text() == "Defect register"
    rows = table_rows(page)
    assert len(rows) == len(defects)
    levels = {"immediate": "Immediate", "intervention": "Intervention", "alert": "Alert"}
    for row, d in zip(rows, defects, strict=True):
        assert row["Priority"] == str(d["priority"])
        assert row["Status"] == d["status"]
        assert row["Level"] == levels.get(d["level"], "none")
        more = d["runs_covering"] > d["runs_seen"]
        covering = f" (of {d['runs_covering']} covering)" if more else ""
        assert row["Evidence"] == d["evidence_text"] + covering
        km, m = divmod(round(d["peak_m"], 1), 1000)
        assert row["Peak"] == f"{int(km)}+{m:05.1f}"  # km+m
    priorities = [int(r["Priority"]) for r in rows]
    assert priorities == sorted(priorities)
    deep = [d for d in defects if 240 < d["peak_m"] < 270]
    assert len(deep) == 1 and deep[0]["status"] == "worsening"
    assert any(r["Status"] == "worsening" and r["Trend (mm/mo)"].startswith("+") for r in rows)

    wait_for_plot(page, "#aggregate-plot")
    metas = page.evaluate("() => document.getElementById('aggregate-plot').data.map(t => t.meta)")
    assert {"aggregate", "aggregate-band"} <= set(metas)
    shapes = page.evaluate("() => document.getElementById('aggregate-plot').layout.shapes.length")
    assert shapes == len(defects)

    page.fill("#alerts-since", "2025-01-01")
    page.click("#alerts-show")
    page.wait_for_selector("#alerts-table tbody tr")
    assert page.locator("#alerts-table tbody tr").count() == sum(1 for d in defects if d["level"])
    page.fill("#alerts-since", "2031-01-01")
    page.click("#alerts-show")
    page.wait_for_selector("#alerts-none")

    hrefs = page.evaluate(
        "() => [...document.querySelectorAll('#track-exports a')].map(a => a.getAttribute('href'))"
    )
    assert f"/api/v1/tracks/{track_id}/defects?format=csv" in hrefs
    assert f"/api/v1/tracks/{track_id}/profile?format=csv" in hrefs
    assert f"/api/v1/tracks/{track_id}/report" in hrefs
    page.watch.assert_clean()


def test_limits_form_names_a_refused_field_and_re_ranks_the_register(
    page: Any, live_server: LiveServer, register_track: tuple[int, list[dict[str, Any]]]
) -> None:
    """Limits that shrink with urgency are refused with the field named and marked invalid;
    tight limits are saved (PUT) and every defect then shows priority 1, immediate action."""
    track_id, defects = register_track
    page.goto(f"{live_server.url}/#/tracks/{track_id}")
    page.wait_for_selector("#zone-table tbody tr")
    page.wait_for_function("() => document.getElementById('limit-alert_depth_mm').value !== ''")
    assert "default limits" in page.locator("#limits-state").inner_text()

    page.fill("#limit-alert_depth_mm", "0.5")
    page.fill("#limit-intervention_depth_mm", "0.2")
    page.click("#limits-save")
    page.wait_for_selector("#limits-message.error")
    # the refusal sits next to the field, in the form's words (labels, not API names)
    error = page.locator("#limit-intervention_depth_mm-error").inner_text()
    assert error.startswith("Intervention depth (mm)") and "alert depth (mm)" in error, error
    assert "_mm" not in error and "_mm" not in page.locator("#limits-message").inner_text()
    invalid = page.get_attribute("#limit-intervention_depth_mm", "aria-invalid")
    assert invalid == "true"
    page.fill("#limit-intervention_depth_mm", "")

    # the service's bounds are the form's: checked before anything is sent
    puts: list[str] = []
    page.on("request", lambda r: puts.append(r.url) if r.method == "PUT" else None)
    page.fill("#limit-alert_depth_mm", "-1")
    page.fill("#limit-alert_loss_pct", "150")
    page.click("#limits-save")
    page.wait_for_selector("#limit-alert_loss_pct-error")
    assert "must be greater than 0" in page.locator("#limit-alert_depth_mm-error").inner_text()
    assert "at most 100" in page.locator("#limit-alert_loss_pct-error").inner_text()
    assert puts == []
    page.fill("#limit-alert_loss_pct", "")

    for name, value in (("alert_depth_mm", "0.01"), ("intervention_depth_mm", "0.02"),
                        ("immediate_depth_mm", "0.03")):  # fmt: skip
        page.fill(f"#limit-{name}", value)
    page.click("#limits-save")
    page.wait_for_selector("#limits-message.success")
    page.wait_for_function(
        """() => [...document.querySelectorAll('#zone-table tbody tr')]
                 .every(tr => tr.textContent.includes('Immediate'))"""
    )
    rows = table_rows(page)
    assert len(rows) == len(defects) and {r["Priority"] for r in rows} == {"1"}
    with live_server.api() as api:
        stored = api.get(f"/api/v1/tracks/{track_id}/limits").json()
        assert stored["immediate_depth_mm"] == 0.03 and not stored["is_default"]
        # leave the shared service's track as it was for other tests
        assert api.put(f"/api/v1/tracks/{track_id}/limits", json={}).status_code == 200
    page.watch.assert_clean()
