"""Issue 32 through the API: a passenger coach and a freight wagon over rough rail on one
track give every soft zone in the track's register, with its separated loss.

One 400 m track made with the engine's bogie-vehicle forward model (German low-disturbance
geometry, +-5 % support scatter, two zones of 5.4-6 m with 45-50 % loss); two coach runs (27
and 24 m/s) and two wagon runs (19 and 21 m/s) through the realistic sensor at 500 Hz, with
logged start chainages off by up to +-1.5 m, uploaded as CSV with the engine's presets
``passenger_coach`` and ``freight_wagon`` (stored on first use). The aligned chainage is the
frame of the first run uploaded, so the truth is compared after that run's start error.
"""

from __future__ import annotations

import csv
import dataclasses
import io
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from typing import Any

import pytest
from starlette.testclient import TestClient

from app.main import create_app
from engine.bogie import FREIGHT_WAGON, PASSENGER_COACH
from engine.logio import write_run_csv
from engine.synthetic import REALISTIC_SENSOR, make_run, make_track
from engine.track import SoftZone
from support.app_fixtures import make_settings

from .api_support import upload

pytestmark = pytest.mark.slow

SENSOR = dataclasses.replace(REALISTIC_SENSOR, sample_rate_hz=500.0)
ZONES = (SoftZone(140.0, 146.0, 0.50), SoftZone(260.0, 265.4, 0.45))
SEED = 6
FLEET = (
    ("passenger_coach", PASSENGER_COACH, 27.0, 1.2),
    ("freight_wagon", FREIGHT_WAGON, 19.0, -1.5),
    ("passenger_coach", PASSENGER_COACH, 24.0, -0.6),
    ("freight_wagon", FREIGHT_WAGON, 21.0, 0.9),
)
"""The order the runs arrive in: preset, vehicle, speed (m/s), logged start error (m)."""
TRACK = "rough coach and wagon"
DECLARED = "rough coach and wagon, loads declared"
"""The same four runs on a second track, each declaring its load (no payload on top of the
registered vehicle: the same wheel force, so the same separation)."""
T0 = datetime(2026, 4, 6, 6, 0, tzinfo=UTC)


@pytest.fixture(scope="module")
def register(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    """The four runs simulated, uploaded one by one; the track's stiffness and register."""
    track = make_track(400.0, zones=ZONES, jitter=0.05, irregularity="german-low", seed=SEED)
    settings = make_settings(tmp_path_factory.mktemp("rough-bogie"))
    with TestClient(create_app(settings)) as client:
        for i, (preset, vehicle, speed, err) in enumerate(FLEET):
            syn = make_run(
                track=track, vehicle=vehicle, speed=speed, sensor=SENSOR, sim_rate_hz=500.0,
                seed=90 + i + SEED, start_chainage_m=12.0, start_error_m=err,
            )  # fmt: skip
            buf = io.StringIO()
            write_run_csv(syn.log, buf, digits=8)
            for track_name, payload_kg in ((TRACK, None), (DECLARED, 0.0)):
                r = upload(
                    client, buf.getvalue().encode(), track=track_name, vehicle=preset,
                    start_chainage_m=round(syn.logged_start_chainage_m, 2),
                    recorded_at=(T0 + timedelta(days=i)).isoformat(), payload_kg=payload_kg,
                )  # fmt: skip
                assert r.status_code == 201, r.text
        answers: dict[str, Any] = {"frame_error_m": FLEET[0][3]}
        for key, track_name in (("", TRACK), ("declared_", DECLARED)):
            for what in ("stiffness", "defects"):
                url = f"/api/v1/tracks/{track_name}/{what}"
                answers[key + what] = client.get(url).json()
                answers[key + what + "_csv"] = client.get(url, params={"format": "csv"}).text
            answers[key + "zones"] = client.get(
                f"/api/v1/views/tracks/{track_name}/chainage-map"
            ).json()["zones"]
        report = client.get(f"/api/v1/tracks/{TRACK}/report")
        answers["report"] = (report.status_code, report.text)
        quality = client.get(f"/api/v1/tracks/{TRACK}/quality")
        answers["quality"] = (quality.status_code, quality.json())
        yield answers


def test_coach_and_wagon_over_rough_rail_give_every_zone_in_the_register(
    register: dict[str, Any],
) -> None:
    """Every zone is in the register with a separated loss within +-10 points and both ends
    of its separated soft spot within +-1.5 m; the stiffness answer reports no other spot."""
    err = register["frame_error_m"]
    spots = sorted(register["stiffness"]["soft_spots"], key=lambda s: s["start_m"])
    found = [(s["start_m"] - err, s["end_m"] - err, s["stiffness_loss_pct"]) for s in spots]
    assert len(spots) == len(ZONES), f"found {found}, expected {ZONES}"
    for (start, end, loss), zone in zip(found, ZONES, strict=True):
        assert abs(start - zone.start_m) <= 1.5, (found, zone)
        assert abs(end - zone.end_m) <= 1.5, (found, zone)
        assert abs(loss - 100 * zone.loss) <= 10.0, (found, zone)
    for zone in ZONES:
        over = [
            d for d in register["defects"]
            if d["start_m"] - err <= zone.end_m and d["end_m"] - err >= zone.start_m
        ]  # fmt: skip
        assert any(
            d["stiffness_basis"] == "separated"
            and abs(d["stiffness_loss_pct"] - 100 * zone.loss) <= 10.0
            for d in over
        ), (zone, over)


def test_separated_zones_are_provisional_until_the_runs_declare_their_loads(
    register: dict[str, Any],
) -> None:
    """The presets as registered, never calibrated, no load declared: every separated soft
    spot, the stiffness window and every separated defect are provisional, the reason naming
    both vehicles and their runs, in JSON, the CSV twins and the chainage map's zones. The
    same runs declaring their loads give the same zones, none provisional."""
    st, defects = register["stiffness"], register["defects"]
    separated = [d for d in defects if d["source"] == "separated"]
    assert st["soft_spots"] and separated
    reasons = [st["provisional_reason"]] + [
        x["provisional_reason"] for x in [*st["soft_spots"], *separated]
    ]
    assert st["provisional"] and all(x["provisional"] for x in [*st["soft_spots"], *separated])
    for reason in reasons:
        assert reason.startswith(
            "vehicle freight_wagon: no calibration and no declared load on its runs "
        ), reason
        assert "; vehicle passenger_coach: no calibration and no declared load on its runs " in (
            reason
        )
    assert not any(d["provisional"] for d in defects if d["source"] != "separated")
    zones = register["zones"]
    assert any(z["source"] == "separated" for z in zones)
    assert all(z["provisional"] == (z["source"] == "separated") for z in zones)
    assert {z["provisional_reason"] for z in zones if z["provisional"]} <= set(reasons)
    assert f"# Provisional: {st['provisional_reason']}; calibrate" in register["stiffness_csv"]
    rows = list(csv.DictReader(io.StringIO(register["defects_csv"])))
    assert [r["provisional"] for r in rows] == ["1" if d["provisional"] else "0" for d in defects]
    assert [r["provisional_reason"] for r in rows] == [
        d["provisional_reason"] or "" for d in defects
    ]

    st2, defects2 = register["declared_stiffness"], register["declared_defects"]
    assert [(s["start_m"], s["stiffness_loss_pct"]) for s in st2["soft_spots"]] == [
        (s["start_m"], s["stiffness_loss_pct"]) for s in st["soft_spots"]
    ]
    assert not st2["provisional"] and st2["provisional_reason"] is None
    declared = [*st2["soft_spots"], *defects2, *register["declared_zones"]]
    assert not any(x["provisional"] or x["provisional_reason"] for x in declared)
    assert "Provisional" not in register["declared_stiffness_csv"]
    rows2 = list(csv.DictReader(io.StringIO(register["declared_defects_csv"])))
    assert rows2 and all(r["provisional"] == "0" for r in rows2)


def test_a_bogie_fleet_track_has_its_report_and_quality_with_the_wheelbases_nulls(
    register: dict[str, Any],
) -> None:
    """The track report and the quality answer of a track run by bogie vehicles are served
    (they were a 500: the observability took every vehicle for a half car), and the
    observability names each vehicle's wheelbase null (coach 2.6 m: 5.2 m; wagon 1.9 m:
    3.8 m)."""
    status, html = register["report"]
    assert status == 200 and "<html" in html.lower()
    status, q = register["quality"]
    assert status == 200, q
    nulls = {o["vehicle"]: o["wheelbase_nulls_m"] for o in q["observability"]}
    assert nulls == {"passenger_coach": [5.2], "freight_wagon": [3.8]}
