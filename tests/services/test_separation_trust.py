"""A separated soft spot is provisional while a vehicle behind it has neither a calibration
applied nor its runs' loads declared (``app.services.track.separation_trust``), in the
register (``provisional_notes``), the stiffness window (``stiffness_with_vehicles``) and the
track's HTML report alike.

A coach and a wagon each pass once over a track whose stored separation (one chunk, one soft
spot, written by hand: no numerics) names both runs. Then the coach is calibrated (a version
made by a calibration that applied a parameter, its run reprocessed with it) and the wagon's
run declares its payload: the spot is no longer provisional. A calibration that kept every
parameter as registered, or a load declared on only some of a vehicle's runs, does not count.
"""

from __future__ import annotations

import hashlib
import html
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sqlalchemy import select, update

from app.db.migrate import upgrade
from app.db.models import Calibration, Run, Track, TrackStiffness, TrackStiffnessSpot, Vehicle
from app.db.session import Database
from app.services.track.register import provisional_notes, track_register
from app.services.track.separation_store import (
    CHUNK_POINTS,
    STIFFNESS_ARRAYS,
    stiffness_with_vehicles,
)
from app.services.track.separation_trust import Trust
from app.services.vehicles.versions import create_vehicle, new_version
from app.services.views.exports import track_report
from engine.vehicle_kinds import vehicle_from_dict
from support.app_fixtures import database_url_for

T0 = datetime(2026, 5, 1, tzinfo=UTC)


@pytest.fixture
def db(tmp_path: Path) -> Iterator[Database]:
    database = Database(database_url_for(tmp_path))
    upgrade(database)
    yield database
    database.dispose()


def _run(s: Any, track_id: int, vehicle_id: int, day: int) -> int:
    run = Run(
        track_id=track_id, vehicle_id=vehicle_id, source="upload",
        recorded_at=T0 + timedelta(days=day), start_chainage_m=0.0, direction="increasing",
        sample_rate_hz=1000.0, n_samples=1000, duration_s=1.0, speed_min_mps=20.0,
        speed_max_mps=20.0, status="done", options={}, attempts=1, vehicle_version=1,
        content_hash=hashlib.sha256(f"run {day}".encode()).hexdigest(),
    )  # fmt: skip
    s.add(run)
    s.flush()
    return run.id


def _separated_track(db: Database) -> dict[str, Any]:
    """A coach run, a wagon run (and a second wagon run off the spot), the separation's chunk
    0 with both first runs contributing and one soft spot they support."""
    with db.session() as s:
        params = s.scalars(select(Vehicle).order_by(Vehicle.id)).first().params_dict()  # type: ignore[union-attr]
    with db.session() as s:
        coach = create_vehicle(s, "coach", None, params).id
        wagon = create_vehicle(s, "wagon", None, params).id
    with db.session() as s:
        track = Track(name="T", k_nominal=8e7, spacing=0.6, EI=6.4e6, mass_per_m=60.0,
                      c_support=5e4)  # fmt: skip
        s.add(track)
        s.flush()
        runs = [_run(s, track.id, coach, 0), _run(s, track.id, wagon, 1),
                _run(s, track.id, wagon, 2)]  # fmt: skip
        block = np.zeros((len(STIFFNESS_ARRAYS), CHUNK_POINTS), dtype="<f4")
        block[STIFFNESS_ARRAYS.index("n_passes")] = 2
        block[STIFFNESS_ARRAYS.index("separable")] = 1
        block[STIFFNESS_ARRAYS.index("k_rel")] = 1
        contributors = [
            {"kind": "run", "id": rid, "label": f"run {rid}", "mean_force_n": f, "points": 100}
            for rid, f in ((runs[0], 60e3), (runs[1], 110e3))
        ]
        s.add(TrackStiffness(track_id=track.id, chunk=0, data=block.tobytes(),
                             meta={"contributors": contributors}))  # fmt: skip
        s.add(TrackStiffnessSpot(
            track_id=track.id, start_m=100.0, end_m=106.0, peak_m=103.0, loss_pct=45.0,
            depth_mm=0.8, support=[{"kind": "run", "id": runs[0], "force_n": 60e3},
                                   {"kind": "run", "id": runs[1], "force_n": 110e3}],
        ))  # fmt: skip
        s.commit()
        return {"track": track.id, "coach": coach, "wagon": wagon, "runs": runs}


def _trust(db: Database, track_id: int) -> tuple[Trust, Trust, Trust]:
    """The separated defect's, the stiffness window's and its soft spot's verdicts; the
    track's report says "provisional" exactly when they are."""
    with db.session() as s:
        defects = track_register(s, track_id)
        notes = provisional_notes(s, track_id, defects)
        window = stiffness_with_vehicles(s, track_id)
        track = s.get(Track, track_id)
        assert track is not None
        report = track_report(s, track, top=25)
    (separated,) = [n for d, n in zip(defects, notes, strict=True) if d.source == "separated"]
    assert all(not n.provisional for d, n in zip(defects, notes, strict=True)
               if d.source != "separated")  # fmt: skip
    (spot,) = window.spot_trust
    said = [separated, window.trust, spot]
    assert ("<strong>provisional</strong>" in report) == separated.provisional
    assert ("<strong>Provisional:</strong>" in report) == window.trust.provisional
    for reason in {t.reason for t in said if t.provisional}:
        assert html.escape(reason or "") in report
    return separated, window.trust, spot


def _calibrate(db: Database, vehicle_id: int, fitted: list[dict[str, Any]]) -> None:
    """A finished calibration of the vehicle that made its next version; its runs processed
    again with that version (as the worker does)."""
    with db.session() as s:
        vehicle = s.get(Vehicle, vehicle_id)
        assert vehicle is not None
        cal = Calibration(vehicle_id=vehicle_id, status="done", request={}, applied=True,
                          result={"fitted": fitted, "significant": True})  # fmt: skip
        s.add(cal)
        s.flush()
        version, _ = new_version(
            s, vehicle, vehicle_from_dict(vehicle.params_dict()), source="calibration",
            calibration_id=cal.id,
        )  # fmt: skip
        cal.applied_version = version
        s.execute(update(Run).where(Run.vehicle_id == vehicle_id).values(vehicle_version=version))
        s.commit()


def test_provisional_until_each_vehicle_is_calibrated_or_its_loads_declared(
    db: Database,
) -> None:
    t = _separated_track(db)
    coach_run, wagon_run, _ = t["runs"]
    for trust in _trust(db, t["track"]):
        assert trust.provisional
        assert trust.reason == (
            f"vehicle coach: no calibration and no declared load on its run {coach_run}; "
            f"vehicle wagon: no calibration and no declared load on its run {wagon_run}"
        )

    # a calibration that kept every parameter as registered made a version, but calibrated
    # nothing: the coach still counts against the spot
    _calibrate(db, t["coach"], [{"name": "Is", "applied": False}])
    assert all("vehicle coach" in (tr.reason or "") for tr in _trust(db, t["track"]))
    _calibrate(db, t["coach"], [{"name": "Is", "applied": False}, {"name": "ks", "applied": True}])
    for trust in _trust(db, t["track"]):
        assert trust.provisional
        assert trust.reason == (
            f"vehicle wagon: no calibration and no declared load on its run {wagon_run}"
        )

    # the wagon declares its load on the run behind the spot: its other run (off the spot)
    # does not matter, and nothing is provisional any more
    with db.session() as s:
        s.execute(update(Run).where(Run.id == wagon_run).values(payload_kg=30_000.0))
        s.commit()
    for trust in _trust(db, t["track"]):
        assert trust == Trust(False, None)


def test_declared_loads_alone_and_calibrations_stored_before_per_parameter_flags(
    db: Database,
) -> None:
    """Both vehicles' runs declaring a static wheel load make the spot count with no
    calibration; a calibration stored before each parameter's ``applied`` was recorded
    applied every fitted parameter."""
    t = _separated_track(db)
    coach_run, wagon_run, _ = t["runs"]
    with db.session() as s:
        s.execute(update(Run).where(Run.id == coach_run).values(static_wheel_load_n=60e3))
        s.commit()
    assert all(tr.reason == f"vehicle wagon: no calibration and no declared load on its run "
               f"{wagon_run}" for tr in _trust(db, t["track"]))  # fmt: skip
    _calibrate(db, t["wagon"], [{"name": "Is"}])
    assert all(not tr.provisional for tr in _trust(db, t["track"]))
