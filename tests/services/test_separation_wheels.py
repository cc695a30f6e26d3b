"""The separation's passes carry their vehicle's wheels (a bogie's two, a half car's one),
from the vehicle version that made each run's results."""

from __future__ import annotations

from app.db.models import Run, Vehicle, VehicleVersion
from app.db.session import Database
from app.services.track.separation_store import read_passes
from engine.bogie import FREIGHT_WAGON, PASSENGER_COACH
from services.test_newest_passes import _add_run, _track, db  # noqa: F401 (the fixture)


def test_each_pass_has_the_wheels_of_the_vehicle_version_behind_it(db: Database) -> None:  # noqa: F811
    """A half car's run: one wheel at 0; a coach's: two at +-1.3 m; a run made with an
    earlier version of that vehicle (a wagon's datasheet): that version's +-0.95 m."""
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
    now = _add_run(db, track_id, coach_id, 2, 2.0)
    old = _add_run(db, track_id, coach_id, 3, 3.0)
    with db.session() as s:
        s.get(Run, old).vehicle_version = 1
        s.commit()
        wheels = {p.id: p.wheel_offsets_m for p in read_passes(s, track_id, 1, 4)}
    assert wheels == {half: (0.0,), now: (1.3, -1.3), old: (0.95, -0.95)}
