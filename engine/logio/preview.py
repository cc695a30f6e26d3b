"""Preview (the dashboard's column mapping): the head of a log and how it would be read."""

from __future__ import annotations

import codecs
from dataclasses import dataclass
from datetime import datetime
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import LogFormatError, ParameterError
from ..vehicle import GRAVITY
from .columns import (
    _map_columns,
)
from .header import (
    _Header,
    _is_skipped,
    _read_header,
    _split,
    _strip_comment,
)
from .options import CsvOptions
from .roles import (
    _ROLES,
    SPARSE_ROLES,
)
from .source import (
    _GZIP_MAGIC,
    _detect_encoding,
    _gunzip_head,
)
from .table import _to_float
from .units import _auto_gravity, epoch_start, iso_start, resolve_units

PREVIEW_BYTES = 1 << 20
"""How much (decompressed) text :func:`preview_csv` looks at, bytes."""

_GUESS_ROWS = 2000  # rows the preview parses to guess units and gravity


@dataclass(frozen=True)
class CsvPreview:
    """What a CSV looks like and how it would be read: for a column-mapping dialog.

    Attributes
    ----------
    delimiter : str
        ``','``, ``';'``, ``'\\t'`` or ``' '`` (any whitespace).
    columns : list of str
        Header names (an empty name becomes ``'column K'``).
    rows : list of list of str
        The first data rows, fields as written.
    mapping : dict
        Role (one of :data:`~engine.logio.ROLES`) -> column name, or None when no column is
        recognised (or two are: see ``warnings``).
    units : dict
        Role -> unit the column would be read in, or None.
    gravity : str or None
        ``'included'`` or ``'removed'`` (the option, else guessed from the first rows), None
        when it cannot be told.
    warnings : list of str
        Problems that would stop the upload (missing or ambiguous columns, unreadable values
        in the first rows) and assumptions worth checking (units without a suffix).
    recorded_at : datetime or None
        When the first sample was recorded (UTC), if the time column holds epoch seconds or
        milliseconds, else if another column holds ISO 8601 dates and times (the first row's);
        None when the file has no clock time.
    """

    delimiter: str
    columns: list[str]
    rows: list[list[str]]
    mapping: dict[str, str | None]
    units: dict[str, str | None]
    gravity: str | None
    warnings: list[str]
    recorded_at: datetime | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of every attribute."""
        return {
            "delimiter": self.delimiter,
            "columns": list(self.columns),
            "rows": [list(r) for r in self.rows],
            "mapping": dict(self.mapping),
            "units": dict(self.units),
            "gravity": self.gravity,
            "warnings": list(self.warnings),
            "recorded_at": self.recorded_at.isoformat() if self.recorded_at else None,
        }


def preview_csv(
    data: bytes | bytearray, n_rows: int = 10, options: CsvOptions | None = None
) -> CsvPreview:
    """Look at the start of a CSV: its columns, first rows and how they would be read.

    Only the first :data:`PREVIEW_BYTES` (decompressed) are read, so this is cheap on a large
    upload. It never raises for problems of the content (those become ``warnings``).

    Parameters
    ----------
    data : bytes
        The file (or its beginning), plain or gzip-compressed.
    n_rows : int
        Number of data rows to return (0 to 1000).
    options : CsvOptions, optional
        The user's current choices; the preview shows their effect.

    Returns
    -------
    CsvPreview

    Raises
    ------
    LogFormatError
        The data is empty, not text (binary, zip) or has no header line.
    ParameterError
        ``n_rows`` is out of range.
    """
    if not isinstance(n_rows, int) or not 0 <= n_rows <= 1000:
        raise ParameterError(f"n_rows must be an integer from 0 to 1000, got {n_rows!r}")
    opts = options if options is not None else CsvOptions()
    if data[:2] == _GZIP_MAGIC:
        head, more = _gunzip_head(data, PREVIEW_BYTES)
    else:
        head, more = bytes(data[:PREVIEW_BYTES]), len(data) > PREVIEW_BYTES
    if not head or head.isspace():
        raise LogFormatError("the file is empty: no header line naming the columns (and no data)")
    encoding, enc_note = _detect_encoding(head, final=not more)
    text = codecs.getincrementaldecoder(encoding)(errors="replace").decode(head, final=not more)
    lines = text.splitlines()
    if more and len(lines) > 1:
        lines = lines[:-1]  # the last line may be cut
    warns = [enc_note] if enc_note else []
    try:
        header = _read_header(lines)
    except LogFormatError as e:
        if "single column" not in str(e):
            raise
        # one column: show it anyway, the warning says which delimiter is expected
        first = next(s.strip() for s in lines if not _is_skipped(s.strip()))
        ln = next(i for i, s in enumerate(lines, 1) if not _is_skipped(s.strip()))
        header = _Header(line=ln, names=[first], delimiter=",", samples=[])
        warns.append(str(e))
    names, d = header.names, header.delimiter
    rows: list[list[str]] = []
    parsed: list[tuple[int, list[str]]] = []
    for ln, raw_line in enumerate(lines[header.line :], header.line + 1):
        s = raw_line.strip()
        if _is_skipped(s):
            continue
        fields_ = [f.strip() for f in _split(_strip_comment(s), d)]
        if len(rows) < n_rows:
            rows.append(fields_)
        if len(parsed) < _GUESS_ROWS:
            parsed.append((ln, fields_))
        elif len(rows) >= n_rows:
            break
    mapping = _map_columns(names, opts, header.line)
    warns.extend(str(p) for p in mapping.problems)
    chosen = {r: j for r, j in mapping.index.items() if j is not None}
    if len(names) > 1 and not parsed:
        warns.append(f"the file has a header (line {header.line}) but no data rows yet")

    values: dict[str, NDArray[np.float64]] = {}
    for role, j in chosen.items():
        vals = []
        for ln, f in parsed:
            if len(f) <= j:
                continue
            try:
                vals.append(_to_float(f[j], names[j], ln, role in SPARSE_ROLES))
            except LogFormatError as e:
                if len(warns) < 20:
                    warns.append(str(e))
        values[role] = np.asarray(vals, dtype=np.float64)
        values[role] = values[role][np.isfinite(values[role])]

    first_time = values["time"] if "time" in chosen else np.empty(0)
    accel = values["accel"] if "accel" in chosen else np.empty(0)
    t0 = float(first_time[0]) if first_time.size else None
    units, assumed, _ = resolve_units(
        {r: names[j] for r, j in chosen.items()},
        opts,
        mapping.name_unit,
        t0=t0,
        accel_mean=float(np.mean(accel)) if accel.size else None,
    )
    warns.extend(assumed)
    gravity: str | None = None if opts.gravity == "auto" else opts.gravity
    if gravity is None and accel.size:
        mean = float(np.mean(accel)) * _ROLES["accel"].factors[units["accel"] or "m/s2"]
        gravity = _auto_gravity(mean)
        if gravity is None:
            warns.append(
                f"the mean of {names[chosen['accel']]!r} in the first rows is "
                f"{mean:.4g} m/s²: neither gravity included (~{GRAVITY}) nor removed (~0); "
                "check accel_unit or set gravity"
            )
    return CsvPreview(
        delimiter=d,
        columns=list(names),
        rows=rows,
        mapping={r: (names[j] if j is not None else None) for r, j in mapping.index.items()},
        units=units,
        gravity=gravity,
        warnings=warns,
        recorded_at=(epoch_start(t0, units["time"]) if t0 is not None else None)
        or _iso_recorded_at(parsed, set(chosen.values())),
    )


def _iso_recorded_at(parsed: list[tuple[int, list[str]]], taken: set[int]) -> datetime | None:
    """The first row's ISO date and time in a column no role reads (a logger's wall-clock
    column beside its numeric time), or None."""
    for _, fields_ in parsed[:1]:
        for j, value in enumerate(fields_):
            when = None if j in taken else iso_start(value)
            if when is not None:
                return when
    return None
