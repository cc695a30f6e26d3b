"""What a pass can see, in a real browser: the run page never says "no soft spot" without the
pass's detection limit, and the simulate page simulates with an IMU grade."""

from __future__ import annotations

from typing import Any

import pytest
from browser.harness import LiveServer, wait_for_plot

pytestmark = pytest.mark.browser


def test_run_page_says_what_the_pass_could_not_see(page: Any, live_server: LiveServer) -> None:
    """A consumer-grade pass over a 30 % zone finds nothing; its page says so together with
    the losses it could not have seen (from GET /runs/{id}'s detection_limit)."""
    with live_server.api() as api:
        r = api.post(
            "/api/v1/simulate?wait=true",
            json={"track": "limit line", "length_m": 220, "speed_mps": 25, "seed": 4,
                  "zones": [{"start_m": 100, "end_m": 103, "loss": 0.3}],
                  "sensor_grade": "consumer-mems"},
        )  # fmt: skip
        assert r.status_code == 201, r.text
        run = r.json()["run"]
    assert run["n_soft_spots"] == 0
    loss3 = run["detection_limit"]["min_loss_pct"][0]
    page.goto(f"{live_server.url}/#/runs/{run['id']}")
    summary = page.locator("#run-summary")
    summary.wait_for()
    text = summary.inner_text()
    # smooth rail: "No soft spot detected."; a noisy pass the rail check calls rough says no
    # dip beyond its limit instead (it cannot tell supports from geometry): either way the
    # limit follows
    assert text.startswith(("No soft spot detected. ", "No dip beyond this pass's detection"))
    assert "This pass could not see losses below" in text
    digits = loss_digits(run["detection_limit"]["min_loss_pct"])
    assert f"{loss3:.{digits}f} % over 3 m" in text and "over 6 m" in text
    page.watch.assert_clean()


def loss_digits(losses: list[float | None]) -> int:
    """The page's rule for the limits' decimals: whole percent unless two different limits
    would read alike."""
    vals = [v for v in losses if v is not None]
    alike = any(
        abs(a - b) >= 0.05 and f"{a:.0f}" == f"{b:.0f}"
        for i, a in enumerate(vals)
        for b in vals[i + 1 :]
    )
    return 1 if alike else 0


@pytest.mark.parametrize(
    ("losses", "expected"),
    [
        ([16.35, 15.75], "losses below 16.4 % over 3 m or losses below 15.8 % over 6 m"),
        ([31.2, 18.4], "losses below 31 % over 3 m or losses below 18 % over 6 m"),
        ([16.02, 15.98], "losses below 16 % over 3 m or losses below 16 % over 6 m"),
        ([None, 40.0], "any loss over 3 m or losses below 40 % over 6 m"),
    ],
)
def test_limits_that_differ_do_not_read_alike(
    page: Any, live_server: LiveServer, losses: list[float | None], expected: str
) -> None:
    """Two limits that differ (16.35 and 15.75 %) are not both shown as "16 %": the wording
    takes one decimal then, and stays in whole percent otherwise (the same number twice, or
    limits that round apart)."""
    page.goto(f"{live_server.url}/#/")
    text = page.evaluate(
        """async (losses) => (await import('/static/js/visibility.js')).unseenText(
            {zone_length_m: [3, 6], min_loss_pct: losses, threshold_mm: 0.07})""",
        losses,
    )
    assert text == f"This pass could not see {expected} (its detection threshold: dips of 0.07 mm)."


def test_simulate_page_offers_the_imu_grades(page: Any, live_server: LiveServer) -> None:
    """The grade select lists the service's grades; choosing one disables the typed figures,
    the simulation runs with that grade and its result says what the pass could not see."""
    page.goto(f"{live_server.url}/#/simulate")
    sel = page.locator("#sim-sensor-grade")
    page.wait_for_function(
        "() => document.querySelectorAll('#sim-sensor-grade option').length === 5"
    )
    sel.select_option("tactical-mems")
    assert page.locator("#sim-accel-noise").is_disabled()
    page.fill("#sim-length", "250")
    page.locator("#sim-zones tbody tr").nth(1).get_by_role(
        "button", name="Remove this zone"
    ).click()
    with page.expect_response(
        lambda r: "/api/v1/simulate" in r.url and r.request.method == "POST"
    ) as resp:
        page.click("#simulate-button")
    body = resp.value.request.post_data_json
    assert body["sensor_grade"] == "tactical-mems" and "sensor" not in body
    wait_for_plot(page, "#sim-profile-plot", 2)
    assert "This pass could not see losses below" in page.locator("#sim-status").inner_text()
    page.watch.assert_clean()
