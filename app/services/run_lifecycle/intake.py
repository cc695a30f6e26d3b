"""A run as submitted: the upload parsed into a :class:`Submission`, and what it names.

The route validates the request's fields (its schema) and hands them here with the log's
bytes or arrays; the log is read (:func:`~app.services.run_lifecycle.logs.parse_csv`) and hashed at
once.
The track and vehicle a submission names are looked up by :mod:`app.services.lookup`, as for
every route.
"""

from __future__ import annotations

import hashlib
import re
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, Protocol

from sqlalchemy.orm import Session

from app.db.models import Run
from app.services.errors import Invalid
from app.services.lookup import resolve_vehicle
from app.services.run_lifecycle.logs import (
    hash_columns,
    log_from_columns,
    parse_csv,
    recorded_at_of,
    sha256_hex,
)
from engine.runlog import RunLog

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


def clean_filename(name: str | None) -> str | None:
    """The client's file name as data: last path component, printable, at most 255 chars."""
    if not name:
        return None
    base = re.split(r"[\\/]", name)[-1]
    base = _UNSAFE_FILENAME.sub("", base).strip()
    return base[:255] or None


class RunFields(Protocol):
    """The validated fields of a run upload (the request schema's, read only)."""

    @property
    def track(self) -> str | None: ...
    @property
    def track_id(self) -> int | None: ...
    @property
    def vehicle(self) -> str | None: ...
    @property
    def vehicle_id(self) -> int | None: ...
    @property
    def name(self) -> str | None: ...
    @property
    def start_chainage_m(self) -> float | None: ...
    @property
    def direction(self) -> str: ...
    @property
    def recorded_at(self) -> datetime | None: ...
    @property
    def payload_kg(self) -> float | None: ...
    @property
    def static_wheel_load_n(self) -> float | None: ...
    def new_track(self) -> dict[str, Any]: ...
    def csv_options(self) -> dict[str, Any]: ...


class JsonRunFields(RunFields, Protocol):
    """The validated fields of a JSON run upload: the log as CSV text, or arrays."""

    @property
    def csv(self) -> str | None: ...
    @property
    def filename(self) -> str | None: ...


def _submission(
    meta: RunFields, *, source: str, content_hash: str, filename: str | None, key: str | None,
    log: RunLog, options: dict[str, Any], file_recorded_at: datetime | None = None,
) -> Submission:  # fmt: skip
    return Submission(
        log=log,
        source=source,
        content_hash=content_hash,
        track=meta.track,
        track_id=meta.track_id,
        vehicle=meta.vehicle,
        vehicle_id=meta.vehicle_id,
        name=meta.name,
        start_chainage_m=meta.start_chainage_m,
        direction=meta.direction,
        # Given, else the file's own clock (epoch time column), else the upload time.
        recorded_at=meta.recorded_at or file_recorded_at,
        filename=filename,
        idempotency_key=key,
        options=options,
        payload_kg=meta.payload_kg,
        static_wheel_load_n=meta.static_wheel_load_n,
        new_track=meta.new_track(),
    )


def _file_clock(
    meta: RunFields, data: bytes | bytearray, options: dict[str, Any]
) -> datetime | None:
    """The file's own clock (:func:`recorded_at_of`) where the form gives no recording
    time, else None: the preview reads the file's head again (~15 ms a 1 km pass) for an
    answer the form's time overrides."""
    return None if meta.recorded_at is not None else recorded_at_of(data, options)


def _parse_and_hash(
    data: bytes | bytearray, options: dict[str, Any], field: str, max_bytes: int
) -> tuple[RunLog, str]:
    """The CSV's log and its SHA-256, hashed on a second thread while it is parsed
    (hashlib releases the GIL)."""
    with ThreadPoolExecutor(1, thread_name_prefix="hash-upload") as pool:
        digest = pool.submit(sha256_hex, data)
        log = parse_csv(data, options, field=field, max_bytes=max_bytes)
        return log, digest.result()


def from_upload(
    meta: RunFields, body: bytearray, filename: str | None, key: str | None, max_bytes: int
) -> Submission:
    """A multipart upload's submission: the CSV file ``body`` (plain or gzip, at most
    ``max_bytes``) read with the form's options; ``key``: the Idempotency-Key."""
    options = meta.csv_options()
    # read in place (no copy of the buffer: ~0.1-0.3 s and 135 MB for an hour at 1 kHz)
    log, content_hash = _parse_and_hash(body, options, "file", max_bytes)
    return _submission(
        meta, source="upload", content_hash=content_hash, filename=filename, key=key,
        log=log, options={"csv": options}, file_recorded_at=_file_clock(meta, body, options),
    )  # fmt: skip


def from_json(
    meta: JsonRunFields, columns: dict[str, Any] | None, key: str | None, max_bytes: int
) -> Submission:
    """A JSON upload's submission: its CSV text (``meta.csv``, read like a file), else its
    canonical SI arrays ``columns``; ``key``: the Idempotency-Key."""
    if meta.csv is not None:
        options = meta.csv_options()
        data = meta.csv.encode("utf-8")
        log, content_hash = _parse_and_hash(data, options, "csv", max_bytes)
        return _submission(
            meta, source="json", content_hash=content_hash, filename=meta.filename, key=key,
            log=log, options={"csv": options}, file_recorded_at=_file_clock(meta, data, options),
        )  # fmt: skip
    assert columns is not None
    log = log_from_columns(columns)
    return _submission(
        meta, source="json", content_hash=hash_columns(log), filename=meta.filename, key=key,
        log=log, options={"columns": True},
    )  # fmt: skip
