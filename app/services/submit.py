"""Accepting a run: resolve track and vehicle, de-duplicate, check, then process or queue.

Everything a client can get wrong is checked before anything is written, and the write is
one transaction: the track (if new), the run, its display signals, and either its full result
(short logs, processed inline) or its parsed input for the background worker.
"""

from __future__ import annotations

import dataclasses
import hashlib
import re
import threading
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.db.models import Run, RunInput, RunSignals, Track, Vehicle
from app.schemas.common import url_name_problem
from app.schemas.tracks import TrackParamsFields
from engine.budget import TimeBudget
from engine.errors import EngineError, LogFormatError
from engine.runlog import RunLog
from engine.setup import PreparedRun, RunSetup, prepare_run
from engine.track import TrackParams
from engine.vehicle_kinds import KIND_PRESETS, vehicle_from_dict
from engine.vehicle_kinds import Vehicle as EngineVehicle

from .calibration import maybe_auto_calibrate
from .centerlines import load_centerline, place_by_gnss
from .context import AppContext
from .errors import Conflict, Invalid
from .loads import declared_wheel_load, loaded_vehicle
from .logs import pack_log, summarize
from .processing import Processed, invert, start_inversion, store_result
from .signals import log_signals, pack_signals
from .vehicles import create_vehicle

DEFAULT_VEHICLE = "table1"
_UNSAFE_FILENAME = re.compile(r"[\x00-\x1f\x7f]")


@dataclass
class Submission:
    """A parsed run log and everything that came with it."""

    log: RunLog
    source: str
    content_hash: str
    track: str | None = None
    track_id: int | None = None
    vehicle: str | None = None
    vehicle_id: int | None = None
    name: str | None = None
    start_chainage_m: float | None = None
    direction: str = "increasing"
    recorded_at: datetime | None = None
    filename: str | None = None
    idempotency_key: str | None = None
    idempotency_owner: int | None = None
    """The API key whose Idempotency-Key this is (None: the clients without a key)."""
    options: dict[str, Any] = field(default_factory=dict)
    extra_signals: dict[str, Any] = field(default_factory=dict)
    payload_kg: float | None = None
    static_wheel_load_n: float | None = None
    new_track: dict[str, Any] = field(default_factory=dict)
    """Description, rail, k_nominal (N/m), spacing (m) of the track if this run creates it."""

    @property
    def stored_idempotency_key(self) -> str | None:
        """The Idempotency-Key as stored: each API key has its own (two pipelines may both
        send "run-1"), hashed so that it keeps the column's 200 characters."""
        if self.idempotency_key is None or self.idempotency_owner is None:
            return self.idempotency_key
        digest = hashlib.sha256(self.idempotency_key.encode()).hexdigest()
        return f"key{self.idempotency_owner}:{digest}"

    @property
    def identity(self) -> str:
        """What makes two submissions the same run: the log's content alone.

        A log is one pass over the track whatever the options it is sent with (start
        chainage, direction, vehicle, loads, column/unit options): a browser upload and a
        pipeline's upload of the same file are one run, never two passes that would confirm
        each other in the register. The same content sent again is answered with the stored
        run; :func:`ignored_options` names what the repeat asked differently.
        """
        return self.content_hash

    def how(self) -> dict[str, Any]:
        """How this submission asks the log to be read and placed (what a repeat may differ in)."""
        return {
            "start_chainage_m": self.start_chainage_m, "direction": self.direction,
            "payload_kg": self.payload_kg, "static_wheel_load_n": self.static_wheel_load_n,
            **_flat(self.options),
        }  # fmt: skip


def _flat(options: dict[str, Any]) -> dict[str, Any]:
    # the CSV options are kept as {"csv": {...}}: compare them one by one, by their own names
    out: dict[str, Any] = {}
    for k, v in options.items():
        if isinstance(v, dict):
            out.update(v)
        else:
            out[k] = v
    return out


def ignored_options(session: Session, run_id: int, sub: Submission) -> list[str]:
    """The fields a repeated upload of run ``run_id``'s log asked differently from how the run
    was stored (they were not applied: the stored run answers). Fields the repeat left out are
    not differences; the vehicle is compared by id."""
    run = session.get(Run, run_id)
    if run is None:
        return []
    stored: dict[str, Any] = {
        "start_chainage_m": run.start_chainage_m, "direction": run.direction,
        "payload_kg": run.payload_kg, "static_wheel_load_n": run.static_wheel_load_n,
        **_flat(run.options or {}),
    }  # fmt: skip
    out = []
    placed_by_gnss = run.positioning is not None
    for k, v in sub.how().items():
        if v is None or (k == "direction" and placed_by_gnss and sub.start_chainage_m is None):
            continue  # left out, or both placed by the fixes (direction from the fixes)
        if k == "start_chainage_m" and placed_by_gnss:
            out.append(k)  # placed by GNSS when stored: a given start is a different placement
        elif stored.get(k) != v:
            out.append(k)
    if sub.vehicle_id is not None or sub.vehicle is not None:
        try:
            wanted = resolve_vehicle(session, sub.vehicle, sub.vehicle_id).id
        except Invalid:
            wanted = None
        if wanted != run.vehicle_id:
            out.append("vehicle_id" if sub.vehicle_id is not None else "vehicle")
    return sorted(out)


_inflight_guard = threading.Lock()
_inflight: dict[str, threading.Lock] = {}


@contextmanager
def _one_at_a_time(key: str) -> Iterator[None]:
    """Serialise identical submissions in this process: the second waits for the first and
    then finds its run (a duplicate), instead of inverting the same log again."""
    with _inflight_guard:
        lock = _inflight.setdefault(key, threading.Lock())
    with lock:
        yield
    with _inflight_guard:
        if not lock.locked():
            _inflight.pop(key, None)


def clean_filename(name: str | None) -> str | None:
    """The client's file name as data: last path component, printable, at most 255 chars."""
    if not name:
        return None
    base = re.split(r"[\\/]", name)[-1]
    base = _UNSAFE_FILENAME.sub("", base).strip()
    return base[:255] or None


def resolve_vehicle(session: Session, name: str | None, vehicle_id: int | None) -> Vehicle:
    """The vehicle named or numbered (default: the Table 1 vehicle); Invalid when unknown."""
    if vehicle_id is not None:
        v = session.get(Vehicle, vehicle_id)
        if v is None:
            raise Invalid(f"vehicle_id {vehicle_id} does not exist", field="vehicle_id")
        return v
    wanted = name or DEFAULT_VEHICLE
    v = session.scalar(select(Vehicle).where(Vehicle.name == wanted))
    if v is None and wanted in KIND_PRESETS:
        # A preset's name is a vehicle everywhere: stored on first use, like table1.
        v = vehicle_from_preset(session, wanted)
    if v is None:
        # Only the engine's presets are named: the stored vehicles are listed by
        # GET /api/v1/vehicles to those who may read them, not in every error.
        raise Invalid(
            f"vehicle {wanted!r} does not exist; the presets are {', '.join(sorted(KIND_PRESETS))} "
            "(the stored vehicles: GET /api/v1/vehicles; a new one: POST /api/v1/vehicles)",
            field="vehicle",
        )
    return v


def vehicle_from_preset(session: Session, preset: str, name: str | None = None) -> Vehicle:
    """Register the engine's vehicle preset ``preset`` as a vehicle (named after it by
    default, version 1). Commits; a concurrent first use of the same preset loses the race on
    the unique name and finds the other's row."""
    wanted = name or preset
    try:
        return create_vehicle(
            session, wanted, f"Engine vehicle preset {preset!r}", KIND_PRESETS[preset].to_dict()
        )
    except Conflict:
        found = session.scalar(select(Vehicle).where(Vehicle.name == wanted))
        assert found is not None
        return found


def resolve_track(session: Session, name: str | None, track_id: int | None) -> Track | None:
    """The track numbered (Invalid when unknown) or named (None: a new track of that name)."""
    if track_id is not None:
        t = session.get(Track, track_id)
        if t is None:
            raise Invalid(f"track_id {track_id} does not exist", field="track_id")
        return t
    return session.scalar(select(Track).where(Track.name == name))


def _existing(session: Session, sub: Submission, track: Track | None) -> Run | None:
    """A stored run this submission repeats (same Idempotency-Key, or same content on the track)."""
    if sub.idempotency_key:
        stored = sub.stored_idempotency_key
        prev = session.scalar(select(Run).where(Run.idempotency_key == stored))
        if prev is not None:
            same_track = track is not None and prev.track_id == track.id
            if prev.content_hash != sub.identity or not same_track:
                raise Conflict(
                    f"Idempotency-Key {sub.idempotency_key!r} was already used for run {prev.id} "
                    "with different content or track; use a new key for a new run",
                    field="Idempotency-Key",
                    run_id=prev.id,
                )
            return prev
    if track is not None:
        return session.scalar(
            select(Run).where(Run.track_id == track.id, Run.content_hash == sub.identity)
        )
    return None


def _check_new_track_name(name: str | None) -> None:
    # A new track must be addressable by name in URLs (/api/v1/tracks/{track}); tracks that
    # already exist are found by their stored name whatever it is.
    problem = url_name_problem(name or "")
    if problem is not None:
        raise Invalid(f"track name {name!r} {problem}", field="track")


def _track_params(columns: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in columns.items() if k in TrackParams.__dataclass_fields__}


def _new_track_columns(given: dict[str, Any]) -> dict[str, Any]:
    """The columns of a track a submission creates: the given properties over the defaults
    (UIC60 on 80 kN/mm supports), checked by the engine (a ParameterError names the field)."""
    columns = {"rail": "UIC60", **TrackParamsFields().model_dump(), **given}
    TrackParams.from_dict(_track_params(columns))
    return columns


def _preflight(
    sub: Submission, vehicle: EngineVehicle, track: TrackParams, placed: bool
) -> PreparedRun:
    # Everything that can be known about a log without inverting it (the engine's O(n)
    # pre-flight: speed, distance covered, sampling against the wavelength band), so that a
    # queued run does not fail later for a reason the client could have been told now. The
    # CSV reader made the log's plausibility checks ("csv" options) unless GNSS placed it.
    if sub.log.chainage_m is None and sub.start_chainage_m is None:
        gnss = (
            "the log has no GNSS fixes (latitude/longitude columns) to place it by"
            if sub.log.lat_deg is None or not sub.log.has_fixes
            else "the track has no centerline to place its GNSS fixes on (PUT "
            "/api/v1/tracks/{track}/centerline)"
        )
        raise Invalid(
            "start_chainage_m is required when the log has no chainage column and cannot be "
            f"placed by GNSS ({gnss}): give the chainage of the body centre at the first "
            "sample, m",
            field="start_chainage_m",
        )
    try:
        setup = RunSetup(sub.start_chainage_m, sub.direction, vehicle, track)
        return prepare_run(sub.log, setup, log_checked="csv" in sub.options and not placed)
    except EngineError as exc:
        # JSON arrays are named like a CSV's lines; the request field is "columns".
        json_columns = isinstance(exc, LogFormatError) and "columns" in sub.options
        raise Invalid.from_engine(exc, field="columns" if json_columns else None) from None


def submit(ctx: AppContext, sub: Submission) -> tuple[int, bool]:
    """Store a run (processed now if short, else queued); returns ``(run_id, created)``.

    ``created`` is False when the same run was stored before (same Idempotency-Key, or same
    content on the same track): nothing new is written then.

    Raises
    ------
    Invalid
        Unknown vehicles/tracks, missing start chainage and logs the engine rejects.
    Conflict
        A reused Idempotency-Key. Nothing is stored in either case.
    """
    try:
        for attempt in range(3):
            try:
                with _one_at_a_time(f"{ctx.db.url}|{sub.track}|{sub.track_id}|{sub.identity}"):
                    return _submit_once(ctx, sub)
            except IntegrityError:
                # A concurrent request stored the same track name or content first: look again.
                if attempt == 2:
                    raise Conflict(
                        "the run conflicts with one being stored at the same time; retry"
                    ) from None
        raise AssertionError("unreachable")
    finally:
        ctx.memory.busy()  # the upload's copies were just freed: kept while busy


def _submit_once(ctx: AppContext, sub: Submission) -> tuple[int, bool]:
    settings = ctx.settings
    identity = sub.identity  # what the client sent; placement by GNSS changes the log below
    positioning: dict[str, Any] | None = None
    with ctx.db.session() as s:
        vehicle = resolve_vehicle(s, sub.vehicle, sub.vehicle_id)
        track = resolve_track(s, sub.track, sub.track_id)
        prev = _existing(s, sub, track)
        if prev is not None and prev.status != "failed":
            return prev.id, False
        failed_id = prev.id if prev is not None else None
        vehicle_id = vehicle.id
        wheel_load_n, load_field = declared_wheel_load(
            sub.log, sub.payload_kg, sub.static_wheel_load_n
        )
        vp = loaded_vehicle(
            vehicle_from_dict(vehicle.params_dict()), sub.payload_kg, wheel_load_n,
            field=load_field,
        )  # fmt: skip
        vehicle_version = vehicle.version
        track_fields = track.params_dict() if track is not None else None
        track_name = track.name if track is not None else sub.track
        line = load_centerline(s, track.id) if track is not None else None
    if sub.start_chainage_m is None and line is not None and sub.log.lat_deg is not None:
        # Positions from GNSS: the fixes and the odometer give start, direction and scale; a
        # processing stage, so under a processing slot and the processing budget.
        with ctx.slots:
            budget = TimeBudget(
                settings.processing_budget_s, "GNSS placement", "TRACKPROFILE_PROCESSING_BUDGET_S"
            )
            placed = place_by_gnss(sub.log, line, budget)
        assert placed.log.chainage_m is not None
        sub = dataclasses.replace(
            sub, log=placed.log, start_chainage_m=float(placed.log.chainage_m[0]),
            direction=placed.placement.direction,
        )  # fmt: skip
        positioning = placed.placement.to_dict()
    if track is None:
        _check_new_track_name(sub.track)
    new_track = _new_track_columns(sub.new_track) if track is None else {}
    tp = TrackParams.from_dict(track_fields or _track_params(new_track))

    prepared = _preflight(sub, vp, tp, placed=positioning is not None)
    started = None
    if sub.log.n > settings.inline_max_samples and ctx.handover is not None:
        # Queued for this process's worker: its inversion starts now, beside the storing of
        # its input, and the worker takes the result (its claim and crash safety as for any
        # queued run).
        started = start_inversion(ctx.slots, prepared, settings.processing_budget_s)
    # The log is kept either way (reprocessing with a new vehicle version, calibration):
    # packed on a second thread meanwhile (Zstandard and numpy's copies release the GIL).
    with ThreadPoolExecutor(1, thread_name_prefix="pack-log") as pool:
        packing = pool.submit(pack_log, sub.log)
        summary = summarize(sub.log)
        signals, decimated = log_signals(sub.log)
        signals |= sub.extra_signals

        processed: Processed | None = None
        if sub.log.n <= settings.inline_max_samples:
            with ctx.slots:
                try:
                    processed = invert(prepared, settings.processing_budget_s)
                except EngineError as exc:
                    raise Invalid.from_engine(exc) from None
        packed = packing.result()

    with ctx.db.session() as s:
        if failed_id is not None:
            # A failed run of the same content is replaced by the new attempt.
            old = s.get(Run, failed_id)
            if old is not None:
                s.delete(old)
                s.flush()
        track_row = s.scalar(select(Track).where(Track.name == track_name))
        if track_row is None:
            track_row = Track(name=track_name, **new_track)
            s.add(track_row)
            s.flush()
        run = Run(
            name=sub.name,
            track_id=track_row.id,
            vehicle_id=vehicle_id,
            source=sub.source,
            original_filename=clean_filename(sub.filename),
            recorded_at=sub.recorded_at,
            start_chainage_m=sub.start_chainage_m,
            direction=sub.direction,
            sample_rate_hz=summary.sample_rate_hz,
            n_samples=summary.n_samples,
            duration_s=summary.duration_s,
            speed_min_mps=summary.speed_min_mps,
            speed_max_mps=summary.speed_max_mps,
            chainage_offset_m=0.0,
            status="processing",
            stage="queued",
            options=sub.options,
            content_hash=identity,
            positioning=positioning,
            idempotency_key=sub.stored_idempotency_key,
            attempts=0,
            payload_kg=sub.payload_kg,
            static_wheel_load_n=wheel_load_n,
        )
        s.add(run)
        s.flush()
        s.add(
            RunSignals(
                run_id=run.id,
                n_points=len(signals["time_s"]),
                decimated=decimated,
                packed=pack_signals(signals),
            )
        )
        s.add(RunInput(run_id=run.id, data=packed))
        if processed is not None:
            store_result(s, run, processed, vehicle_version)
        run_id = run.id
        handover = ctx.handover if processed is None else None
        if handover is not None:
            # Before the commit: this process's worker may claim the run at once.
            handover.put(run_id, prepared, started)
        try:
            s.commit()
        except BaseException:
            if handover is not None:
                handover.take(run_id)
            raise
        if processed is not None:
            maybe_auto_calibrate(s, vehicle_id, settings.auto_calibrate_runs)
    if processed is None or settings.auto_calibrate_runs:
        ctx.wake_worker()
    return run_id, True
