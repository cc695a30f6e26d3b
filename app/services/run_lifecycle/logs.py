"""Run logs in and out of the service: parsing uploads, hashing, packing for the worker.

Units: the :class:`engine.runlog.RunLog` is canonical SI (s, m/s², rad/s, m/s, m).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from datetime import datetime
from typing import Any

import numpy as np

from app.services.errors import Invalid, TooLarge
from app.services.storage.packing import pack_named, unpack_named
from engine.errors import InputTooLarge, LogFormatError, ParameterError
from engine.logio import MAX_DECOMPRESSED_BYTES, CsvOptions, preview_csv, read_run_csv
from engine.runlog import COLUMNS as RUNLOG_COLUMNS
from engine.runlog import RunLog

LOG_COLUMNS = RUNLOG_COLUMNS
_FIRST_COLUMNS = LOG_COLUMNS[:5]
"""The columns of the first release: hashed even when absent (later ones only when present),
so that a log hashes as it did before columns were added."""


def sha256_hex(*chunks: bytes | bytearray) -> str:
    """Hex SHA-256 of the concatenated chunks."""
    h = hashlib.sha256()
    for c in chunks:
        h.update(c)
    return h.hexdigest()


def parse_csv(
    data: bytes | bytearray,
    options: dict[str, Any],
    field: str = "file",
    max_bytes: int | None = None,
) -> RunLog:
    """Read an uploaded CSV (plain or gzip) into a RunLog with the given column/unit options.

    ``max_bytes`` limits the CSV's size once decompressed (the upload limit applies to the
    CSV, not to what it was compressed to: a few kB of gzip can expand to gigabytes).

    Raises
    ------
    Invalid
        Naming the column, row or unit when the file cannot be read, or the option at fault.
    TooLarge
        A gzip file expands to more than ``max_bytes``.
    """
    try:
        opts = CsvOptions.from_dict({k: v for k, v in options.items() if v is not None})
    except ParameterError as exc:
        # The reader names the option at fault (ParameterError.field).
        raise Invalid.from_engine(exc) from None
    if not data:
        raise Invalid("the uploaded file is empty", field=field)
    try:
        return read_run_csv(
            data, opts, max_bytes=MAX_DECOMPRESSED_BYTES if max_bytes is None else max_bytes
        )
    except InputTooLarge as exc:
        raise TooLarge(
            f"{exc} (TRACKPROFILE_MAX_UPLOAD_MB)",
            field=field,
            limit_bytes=exc.limit_bytes,
            kind="InputTooLarge",
        ) from None
    except LogFormatError as exc:
        raise Invalid.from_engine(exc, field) from None


def recorded_at_of(data: bytes | bytearray, options: dict[str, Any]) -> datetime | None:
    """When a CSV's first sample was recorded (UTC), if its time column holds epoch seconds
    or milliseconds or another column ISO 8601 date-times (:func:`preview_csv`); None
    otherwise. Called after :func:`parse_csv` accepted the file."""
    try:
        return preview_csv(data, n_rows=0, options=CsvOptions(**options)).recorded_at
    except (LogFormatError, ParameterError):
        return None


def log_from_columns(columns: dict[str, Any]) -> RunLog:
    """A RunLog from canonical SI columns (JSON arrays or float arrays; None when absent).

    Raises
    ------
    Invalid
        Naming the column and row (line 2 = first sample, as in a CSV) on bad values.
    """
    arrays = {
        k: (None if v is None else np.asarray(v, dtype=np.float64)) for k, v in columns.items()
    }
    try:
        return RunLog(**arrays)  # type: ignore[arg-type]
    except LogFormatError as exc:
        raise Invalid.from_engine(exc, "columns") from None


def hash_columns(log: RunLog) -> str:
    """Content hash of a log given as columns: its SI arrays, column by column."""
    h = hashlib.sha256()
    for name in LOG_COLUMNS:
        arr = getattr(log, name)
        if arr is None and name not in _FIRST_COLUMNS:
            continue
        h.update(name.encode())
        h.update(b"-" if arr is None else np.ascontiguousarray(arr).tobytes())
    return h.hexdigest()


def pack_log(log: RunLog) -> bytes:
    """The log as stored for the worker, calibration and reprocessing: each canonical SI
    column losslessly compressed (float64, ``app.services.storage.packing``), ~45 % of its size
    (the sensor channels are noise down to their last digits and compress least)."""
    return pack_named({name: getattr(log, name) for name in LOG_COLUMNS}, LOG_COLUMNS, "f8")


def unpack_log(data: bytes) -> RunLog:
    """Inverse of :func:`pack_log`."""
    return RunLog(**unpack_named(data, LOG_COLUMNS))


@dataclass(frozen=True)
class LogSummary:
    """Metadata of a log known before processing (SI)."""

    n_samples: int
    sample_rate_hz: float
    duration_s: float
    speed_min_mps: float
    speed_max_mps: float


def summarize(log: RunLog) -> LogSummary:
    """Sample count, rate, duration and speed range of a log."""
    v = log.speed()
    return LogSummary(
        n_samples=log.n,
        sample_rate_hz=float(log.sample_rate_hz),
        duration_s=float(log.duration_s),
        speed_min_mps=float(np.min(v)),
        speed_max_mps=float(np.max(v)),
    )
