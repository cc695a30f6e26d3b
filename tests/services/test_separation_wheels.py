"""The separation's passes carry their vehicle's wheels (a bogie's two, a half car's one) and
its end ring shapes at the run's speed, from the vehicle version that made each run's
results."""

from __future__ import annotations

import pytest

from app.db.models import Run, Vehicle, VehicleVersion
from app.db.session import Database
from app.services.track.separation_store import read_passes
from engine.bogie import FREIGHT_WAGON, PASSENGER_COACH
from engine.end_rings import end_ring_shapes
from engine.vehicle_kinds import vehicle_from_dict
from services.test_newest_passes import _add_run, _track, db  # noqa: F401 (the fixture)


@pytest.mark.slow
def test_each_pass_has_the_wheels_of_the_vehicle_version_behind_it(db: Database) -> None:  # noqa: F811
    """A half car's run: one wheel at 0; a coach's: two at +-1.3 m; a run made with an
    earlier version of that vehicle (a wagon's datasheet): that version's +-0.95 m. Each run
    carries the end ring shapes of that vehicle at its speed (30 m/s); a pass alone, none."""
    track_id, half_car_id = _track(db)
    with db.session() as s:
        coach = Vehicle(name="coach", version=2)
        coach.set_params(PASSENGER_COACH)
        s.add(coach)
        s.flush()
        s.add_all([
            VehicleVersion(vehicle_id=coach.id, version=1, params=FREIGHT_WAGON.to_dict(),
                           source="created"),
            VehicleVersion(vehicle_id=coach.id, version=2, params=PASSENGER_COACH.to_dict(),
                           source="manual"),
        ])  # fmt: skip
        s.commit()
        coach_id = coach.id
    half = _add_run(db, track_id, half_car_id, 1, 1.0)
    with db.session() as s:
        (alone,) = read_passes(s, track_id, 1, 4)
    assert alone.end_rings is None
    now = _add_run(db, track_id, coach_id, 2, 2.0)
    old = _add_run(db, track_id, coach_id, 3, 3.0)
    with db.session() as s:
        s.get(Run, old).vehicle_version = 1
        s.commit()
        passes = read_passes(s, track_id, 1, 4)
        half_car = vehicle_from_dict(s.get(Vehicle, half_car_id).params_dict())
    wheels = {p.id: p.wheel_offsets_m for p in passes}
    assert wheels == {half: (0.0,), now: (1.3, -1.3), old: (0.95, -0.95)}
    rings = {p.id: p.end_rings for p in passes}
    assert rings[now] is end_ring_shapes(PASSENGER_COACH, 30.0)
    assert rings[old] is end_ring_shapes(FREIGHT_WAGON, 30.0)
    assert rings[half] is end_ring_shapes(half_car, 30.0)
