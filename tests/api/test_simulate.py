"""POST /api/v1/simulate: synthetic runs processed like uploads, with their truth."""

from __future__ import annotations

import numpy as np
import pytest
from starlette.testclient import TestClient

from api.api_support import assert_zones_match, row_counts
from engine.detect import DetectionConfig, robust_baseline

BODY = {"track": "sim", "length_m": 220, "speed_mps": 25, "zones": [{"start_m": 100,
        "end_m": 105, "loss": 0.5}], "seed": 7}  # fmt: skip


def test_simulated_run_finds_its_zone(client: TestClient) -> None:
    """A simulated run is stored and processed; its soft spot matches the simulated zone and
    the answer carries the truth (zones, true loaded level, the detection's baseline of it)."""
    r = client.post("/api/v1/simulate", json=BODY)
    assert r.status_code == 201, r.text
    body = r.json()
    run = body["run"]
    assert run["status"] == "done"
    assert run["source"] == "simulate"
    assert run["track"] == "sim"
    assert run["options"]["simulation"]["zones"] == BODY["zones"]
    spots = client.get(f"/api/v1/runs/{run['id']}/soft-spots").json()
    assert_zones_match(spots, BODY["zones"])
    truth = body["truth"]
    assert truth["zones"] == BODY["zones"]
    assert len(truth["chainage_m"]) == len(truth["level_mm"]) > 100
    i_min = min(range(len(truth["level_mm"])), key=lambda i: truth["level_mm"][i] or 0)
    assert 95 <= truth["chainage_m"][i_min] <= 110  # the true level dips at the zone
    # the baseline the dashboard draws the truth about is the detection's, served
    level = np.array([np.nan if v is None else v for v in truth["level_mm"]])
    step = truth["chainage_m"][1] - truth["chainage_m"][0]
    expected = robust_baseline(level, step, DetectionConfig().baseline_window_m)
    assert truth["baseline_window_m"] == DetectionConfig().baseline_window_m
    assert np.array(truth["baseline_mm"], dtype=float) == pytest.approx(expected, nan_ok=True)
    residual = level - expected
    assert np.nanargmin(residual) == pytest.approx(i_min, abs=8)  # still the zone, about it
    sig = client.get(f"/api/v1/runs/{run['id']}/signals").json()
    assert sig["n_samples"] == run["n_samples"]


@pytest.mark.slow
def test_same_simulation_is_not_stored_twice(client: TestClient, settings) -> None:
    """The simulation is deterministic in its seed: the same request returns the stored run,
    also dated otherwise (the same log is one pass, as an upload's); another seed is another
    run."""
    first = client.post("/api/v1/simulate", json=BODY).json()["run"]
    before = row_counts(settings)
    again = client.post("/api/v1/simulate", json=BODY)
    assert again.status_code == 200
    assert again.json()["run"]["id"] == first["id"]
    dated = client.post("/api/v1/simulate", json={**BODY, "recorded_at": "2026-01-02T03:04:00Z"})
    assert dated.status_code == 200 and dated.json()["run"]["id"] == first["id"]
    assert row_counts(settings) == before
    other = client.post("/api/v1/simulate", json={**BODY, "seed": 8})
    assert other.status_code == 201
    assert other.json()["run"]["id"] != first["id"]


def test_zone_text_and_ideal_sensor(client: TestClient) -> None:
    """Zones may be given as 'start:end:loss' text; an ideal sensor is allowed."""
    body = {**BODY, "zones": ["100:105:0.5"], "sensor": "ideal", "jitter": 0}
    r = client.post("/api/v1/simulate", json=body)
    assert r.status_code == 201, r.text
    assert r.json()["truth"]["zones"] == BODY["zones"]


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"zones": [{"start_m": 200, "end_m": 260, "loss": 0.5}]}, "zones.0.end_m"),
        ({"zones": [{"start_m": 50, "end_m": 40, "loss": 0.5}]}, "zones.0"),
        ({"zones": [{"start_m": 50, "end_m": 60, "loss": 1.5}]}, "zones.0.loss"),
        ({"zones": ["50-60"]}, "zones.0"),
        ({"length_m": 5000, "speed_mps": 5}, "length_m"),
        ({"start_chainage_m": 2}, "start_chainage_m"),
        ({"start_chainage_m": 215}, "start_chainage_m"),
        ({"speed_mps": -3}, "speed_mps"),
        ({"vehicle": "nope"}, "vehicle"),
        ({"sensor": "noisy"}, "sensor"),
        ({"wheels": 4}, "wheels"),
    ],
)
def test_impossible_simulations_are_refused(client: TestClient, settings, change, field):
    """Zones off the track, no room to run, too long a run, bad values, unknown vehicles and
    unknown keys are 422 naming the field; nothing is stored."""
    before = row_counts(settings)
    r = client.post("/api/v1/simulate", json={**BODY, **change})
    assert r.status_code == 422, r.text
    assert r.json()["detail"]["field"].startswith(field), r.json()
    assert row_counts(settings) == before


def test_run_in_decreasing_chainage(client: TestClient) -> None:
    """A run travelling towards decreasing chainage maps its soft spot to the right place."""
    body = {**BODY, "direction": "decreasing", "start_chainage_m": 200}
    r = client.post("/api/v1/simulate", json=body)
    assert r.status_code == 201, r.text
    run = r.json()["run"]
    assert run["direction"] == "decreasing"
    assert_zones_match(client.get(f"/api/v1/runs/{run['id']}/soft-spots").json(), BODY["zones"])


def test_a_simulated_track_is_a_track_of_its_own() -> None:
    """Without a track name, a simulation's runs go to a track named after the physical track
    simulated (never a shared "simulated" track mixing with others): the same setting meets
    again, another zone, seed or rail is another track; speed and vehicle are not the track."""
    from app.api.convert import simulation_spec
    from app.schemas.simulate import SimulateRequest

    base = SimulateRequest()
    same = SimulateRequest(speed_mps=30.0, vehicle="heavy")
    other_zone = SimulateRequest(zones=[{"start_m": 100, "end_m": 106, "loss": 0.4}])
    other_seed = SimulateRequest(seed=4)
    rough = SimulateRequest(irregularity={"spectrum": "german-low", "seed": 3})
    names = [simulation_spec(r).track for r in (base, other_zone, other_seed, rough)]
    assert simulation_spec(same).track == names[0]
    assert len(set(names)) == 4 and all(n.startswith("simulated ") for n in names)
    assert simulation_spec(SimulateRequest(track="Line 9")).track == "Line 9"
