"""Whether a separated soft spot can be trusted yet: the vehicles behind it must be known.

The separation tells a soft support from rail geometry by the difference between passes of
different wheel loads, so an error in a vehicle's parameters or its load is read as a
stiffness change. Measured on rough rail with bogie vehicles 10 % off their registration
(docs/accuracy.md, "Calibrating each vehicle before the separation" and "Applying only what
is significant"): the separation finds 11 of 39 zones with the registered vehicles, 20 with
each calibrated from its own passes, 27 with each run's load declared as well, 32 with the
true vehicles. A separated result is therefore **provisional** while a run behind it has
neither:

- its vehicle's parameters from a calibration: the vehicle version the run was processed
  with (``Run.vehicle_version``) was made by a calibration (``VehicleVersion.source``
  ``"calibration"``) that applied at least one fitted parameter; nor
- a declared load: ``Run.payload_kg`` or ``Run.static_wheel_load_n`` (given on upload, or read
  from the log's load-weigh column, ``app.services.vehicles.loads``).

A vehicle whose runs all have one or the other contributes trust; surveys are recorded at a
known wheel load and always do. Decided on read (a few rows of the track's runs and its
vehicles' calibrated versions): nothing stored goes stale when a calibration is applied or a
run is reprocessed.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import Calibration, Run, Vehicle, VehicleVersion
from engine.register import Defect

PROVISIONAL_REMEDY = (
    "calibrate the vehicle from its runs, or declare each run's load (payload_kg or "
    "static_wheel_load_n on upload)"
)
"""What makes a provisional separated result count (said with the reason where it is shown)."""


@dataclass(frozen=True)
class Trust:
    """Whether a separated result is provisional, and why (None when it is not)."""

    provisional: bool
    reason: str | None = None
    """Each vehicle that makes it so and its runs:
    ``vehicle X: no calibration and no declared load on its runs 3, 5``."""

    def to_dict(self) -> dict[str, Any]:
        """The answer's fields: ``provisional``, ``provisional_reason``."""
        return {"provisional": self.provisional, "provisional_reason": self.reason}


TRUSTED = Trust(False)
"""A result every contributing vehicle is known for (or one that is not separated)."""


def calibrated_version(cal_applied: bool, fitted: Sequence[Mapping[str, Any]] | None) -> bool:
    """Whether a calibration applied at least one fitted parameter.

    ``cal_applied`` is the calibration's own flag (it made a version); a fitted parameter
    without an ``applied`` entry (stored before it was recorded) was applied with the others.
    """
    return cal_applied and any(f.get("applied") is not False for f in fitted or ())


@dataclass(frozen=True)
class RunBasis:
    """What a run's results rest on, as far as trusting a separation goes."""

    vehicle: str
    calibrated: bool
    """Processed with a vehicle version from a calibration that applied a parameter."""
    declared_load: bool
    """The run declares its load (payload or static wheel load)."""

    @property
    def known(self) -> bool:
        """The run's wheel force rests on a calibrated vehicle or a declared load."""
        return self.calibrated or self.declared_load


def run_bases(session: Session, track_id: int) -> dict[int, RunBasis]:
    """Every run of the track by id with what its results rest on (two queries: the runs,
    then their vehicles' versions made by an applied calibration)."""
    runs = session.execute(
        select(Run.id, Run.vehicle_id, Run.vehicle_version, Run.payload_kg,
               Run.static_wheel_load_n, Vehicle.name)
        .join(Vehicle, Vehicle.id == Run.vehicle_id)
        .where(Run.track_id == track_id)
    ).all()  # fmt: skip
    vehicle_ids = {r[1] for r in runs}
    calibrated: set[tuple[int, int]] = set()
    if vehicle_ids:
        for vid, ver, applied, result in session.execute(
            select(VehicleVersion.vehicle_id, VehicleVersion.version, Calibration.applied,
                   Calibration.result)
            .join(Calibration, Calibration.id == VehicleVersion.calibration_id)
            .where(VehicleVersion.vehicle_id.in_(vehicle_ids),
                   VehicleVersion.source == "calibration")
        ):  # fmt: skip
            if calibrated_version(bool(applied), (result or {}).get("fitted")):
                calibrated.add((int(vid), int(ver)))
    return {
        int(rid): RunBasis(
            vehicle=str(name),
            # a run processed before versions were recorded: which parameters is unknown
            calibrated=ver is not None and (int(vid), int(ver)) in calibrated,
            declared_load=payload is not None or wheel_load is not None,
        )
        for rid, vid, ver, payload, wheel_load, name in runs
    }


def trust_of(passes: Iterable[tuple[str, int]], bases: Mapping[int, RunBasis]) -> Trust:
    """Whether a separated result of these passes (``(kind, id)``: ``"run"`` or
    ``"survey"``) is provisional, with the vehicles that make it so and their runs, by name.

    A run no longer stored (deleted since) is not judged: it no longer counts anywhere.
    """
    unknown: dict[str, list[int]] = {}
    for kind, pid in passes:
        basis = bases.get(pid) if kind == "run" else None
        if basis is not None and not basis.known:
            unknown.setdefault(basis.vehicle, []).append(pid)
    if not unknown:
        return TRUSTED
    reason = "; ".join(
        f"vehicle {name}: no calibration and no declared load on its "
        + ("run " if len(ids) == 1 else "runs ")
        + ", ".join(str(i) for i in sorted(set(ids)))
        for name, ids in sorted(unknown.items())
    )
    return Trust(True, reason)


def judge(bases: Mapping[int, RunBasis]) -> Callable[[Iterable[tuple[str, int]]], Trust]:
    """:func:`trust_of` over ``bases``, each set of passes judged once: a long line's spots
    and defects mostly share the few sets of passes that separated them."""
    seen: dict[tuple[tuple[str, int], ...], Trust] = {}

    def of(passes: Iterable[tuple[str, int]]) -> Trust:
        key = tuple(passes)
        out = seen.get(key)
        if out is None:
            out = seen[key] = trust_of(key, bases)
        return out

    return of


def defects_trust(
    defects: Sequence[Defect], of: Callable[[Iterable[tuple[str, int]]], Trust]
) -> list[Trust]:
    """Whether each defect is provisional: one the separation found (``source``
    ``"separated"``) by the passes of its current separation (its latest separated
    sighting), with ``of`` (:func:`judge`); any other is not (its figures rest on no vehicle's
    comparison with another)."""
    out = []
    for d in defects:
        current = (
            next((o for o in reversed(d.history) if o.source == "separated"), None)
            if d.source == "separated"
            else None
        )
        out.append(TRUSTED if current is None else of((p.kind, p.id) for p in current.passes))
    return out
