"""From a CSV to a :class:`~engine.runlog.RunLog`: columns converted to SI and checked."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import LogFormatError, ParameterError
from ..plausibility import (
    ACCEL_LIMIT_MPS2,
    PITCH_RATE_LIMIT_RADPS,
    SPEED_MAX_MPS,
    SPEED_MIN_MPS,
    WHEEL_LOAD_MAX_N,
    WHEEL_LOAD_MIN_N,
    check_chainage,
    check_time_steps,
)
from ..runlog import RunLog
from ..scan import first_at_most, first_nonfinite, first_outside, first_true
from ..vehicle import GRAVITY
from .columns import (
    _map_columns,
)
from .header import (
    _read_header,
)
from .limits import check_lines
from .options import CsvOptions
from .roles import (
    _ROLES,
    OPTION_UNITS,
    SPARSE_ROLES,
    _label,
)
from .source import (
    Source,
    _detect_encoding,
    _read_source,
    _Source,
)
from .table import _parse_table, _Table
from .units import EPOCH_MS_THRESHOLD, GRAVITY_TOLERANCE_MPS2, _auto_gravity, resolve_units

MIN_SAMPLES = 200
"""Fewest samples a log may have: shorter runs are too short to invert."""


@dataclass(frozen=True)
class ParsedRun:
    """A run log read from CSV, with what was recognised on the way.

    Attributes
    ----------
    log : RunLog
        The run in SI units, gravity removed.
    delimiter : str
        ``','``, ``';'``, ``'\\t'`` or ``' '`` (any whitespace).
    encoding : str
        Text encoding the file was read with.
    columns : dict
        Role (one of :data:`~engine.logio.ROLES`) -> header name, or None when the file has
        no such column.
    units : dict
        Role -> unit the column was read in (``'s'``, ``'ms'``, ``'epoch_s'``, ``'m/s2'``,
        ``'g'``, ``'rad/s'``, ``'deg/s'``, ``'m/s'``, ``'km/h'``, ``'m'``, ``'km'``, ``'N'``,
        ``'kN'``, ``'t'``) or None.
    gravity : str
        ``'included'`` (9.81 m/s² was subtracted) or ``'removed'``.
    notes : list of str
        Assumptions worth telling the user (units assumed, encoding).
    """

    log: RunLog
    delimiter: str
    encoding: str
    columns: dict[str, str | None]
    units: dict[str, str | None]
    gravity: str
    notes: list[str]

    def to_dict(self) -> dict[str, Any]:
        """Everything but the arrays, JSON-ready."""
        return {
            "n_samples": self.log.n,
            "sample_rate_hz": self.log.sample_rate_hz,
            "duration_s": self.log.duration_s,
            "delimiter": self.delimiter,
            "encoding": self.encoding,
            "columns": dict(self.columns),
            "units": dict(self.units),
            "gravity": self.gravity,
            "notes": list(self.notes),
        }


def _check_finite(table: _Table, j: int, name: str) -> None:
    v = table.columns[j]
    i = first_nonfinite(v)
    if i is not None:
        ln = table.line(i)
        raise LogFormatError(
            f"column {name!r} at line {ln} is {v[i]}: every value must be a finite number",
            column=name,
            row=ln,
        )


def _time(table: _Table, j: int, name: str, unit: str) -> NDArray[np.float64]:
    raw = table.columns[j]
    t = np.asarray(raw, dtype=np.float64)
    if unit == "epoch_s":
        t = t - t[0]
    elif unit == "ms":
        t = (t - t[0] if abs(t[0]) > EPOCH_MS_THRESHOLD else t) * 1e-3
    dt = np.diff(t)
    i = first_at_most(dt, 0.0)
    if i is not None:
        ln, prev = table.line(i + 1), table.line(i)
        what = "is the same as" if dt[i] == 0 else "comes before"
        kind = "duplicated time" if dt[i] == 0 else "time goes backwards"
        raise LogFormatError(
            f"{kind} in column {name!r} at line {ln}: {float(raw[i + 1])!r} {what} "
            f"{float(raw[i])!r} at line {prev}; time must be strictly increasing",
            column=name,
            row=ln,
        )
    check_time_steps(
        t, name, table.line,
        hint=f" (read in {_label(unit)}): is the unit right? (set time_unit to 's', 'ms' or "
        "'epoch_s')",
    )  # fmt: skip
    return t


def _limit_error(
    table: _Table, i: int, name: str, raw: float, unit: str, si: float, si_unit: str, what: str
) -> LogFormatError:
    ln = table.line(i)
    conv = "" if si == raw else f" ({si:.4g} {si_unit})"
    return LogFormatError(
        f"column {name!r} at line {ln} is {raw:g} {_label(unit)}{conv}: {what}",
        column=name,
        row=ln,
    )


def _refuse_outside(
    table: _Table, name: str, raw: NDArray[np.float64], unit: str, si: NDArray[np.float64],
    lo: float, hi: float, si_unit: str, what: str,
) -> None:  # fmt: skip
    """Refuse the first sample whose SI value lies outside ``lo..hi``: its line, its value as
    read (``raw`` in ``unit``) and in SI, and ``what`` the user is told."""
    i = first_outside(si, lo, hi)
    if i is not None:
        raise _limit_error(table, i, name, float(raw[i]), unit, float(si[i]), si_unit, what)


def _accel(
    table: _Table, j: int, name: str, unit: str, gravity: str
) -> tuple[NDArray[np.float64], str]:
    raw = table.columns[j]
    a = raw * _ROLES["accel"].factors[unit]
    alt = "set accel_unit='m/s2'" if unit == "g" else "set accel_unit='g' if it is in g"
    limit = ACCEL_LIMIT_MPS2 + GRAVITY
    _refuse_outside(
        table, name, raw, unit, a, -limit, limit, "m/s²",
        f"a vertical body acceleration stays within ±{ACCEL_LIMIT_MPS2:g} m/s², so the unit "
        f"looks wrong: the column is read in {_label(unit)}, expected m/s² or g ({alt})",
    )  # fmt: skip
    mean = float(np.mean(a))
    if gravity == "auto":
        found = _auto_gravity(mean)
        if found is None:
            down = (
                " The sensor's z axis may point down (positive must be up)."
                if abs(mean + GRAVITY) < GRAVITY_TOLERANCE_MPS2
                else ""
            )
            raise LogFormatError(
                f"the mean of column {name!r} is {mean:.4g} m/s² (read in {_label(unit)}): "
                f"neither about {GRAVITY} m/s² (gravity included) nor about 0 (gravity removed); "
                f"the unit may be wrong ({alt}), or set gravity to 'included' or 'removed'.{down}",
                column=name,
            )
        gravity = found
    elif gravity == "included" and abs(mean - GRAVITY) >= GRAVITY_TOLERANCE_MPS2:
        raise LogFormatError(
            f"gravity='included' but the mean of column {name!r} is {mean:.4g} m/s² (read in "
            f"{_label(unit)}), not about {GRAVITY} m/s²: check gravity and accel_unit",
            column=name,
        )
    elif gravity == "removed" and abs(mean) >= GRAVITY_TOLERANCE_MPS2:
        raise LogFormatError(
            f"gravity='removed' but the mean of column {name!r} is {mean:.4g} m/s² (read in "
            f"{_label(unit)}), not about 0: check gravity and accel_unit",
            column=name,
        )
    if gravity == "included":
        a = a - GRAVITY
    _refuse_outside(
        table, name, raw, unit, a, -ACCEL_LIMIT_MPS2, ACCEL_LIMIT_MPS2,
        "m/s² with gravity removed",
        f"a vertical body acceleration stays within ±{ACCEL_LIMIT_MPS2:g} m/s²; "
        f"is the unit right? (read in {_label(unit)}, expected m/s² or g)",
    )  # fmt: skip
    return a, gravity


def _pitch_rate(table: _Table, j: int, name: str, unit: str) -> NDArray[np.float64]:
    raw = table.columns[j]
    w = raw * _ROLES["pitch_rate"].factors[unit]
    alt = (
        "set pitch_rate_unit='deg/s' if it is in deg/s"
        if unit == "rad/s"
        else "expected rad/s or deg/s"
    )
    _refuse_outside(
        table, name, raw, unit, w, -PITCH_RATE_LIMIT_RADPS, PITCH_RATE_LIMIT_RADPS, "rad/s",
        f"a body pitch rate stays within ±{PITCH_RATE_LIMIT_RADPS:g} rad/s, so the unit "
        f"looks wrong: the column is read in {_label(unit)} ({alt})",
    )  # fmt: skip
    return w


def _speed(table: _Table, j: int, name: str, unit: str) -> NDArray[np.float64]:
    raw = table.columns[j]
    v = raw * _ROLES["speed"].factors[unit]
    i = first_outside(v, SPEED_MIN_MPS, SPEED_MAX_MPS)
    if i is None:
        return v
    if v[i] <= 0:
        what = (
            "the speed must be positive at every sample (the vehicle moving, in either "
            "direction; the direction of travel is given separately)"
        )
    elif v[i] < SPEED_MIN_MPS:
        what = (
            f"slower than the {SPEED_MIN_MPS:g} m/s ({SPEED_MIN_MPS * 3.6:g} km/h) the "
            "inversion needs: cut standstills out of the log"
        )
    else:
        alt = "set speed_unit='km/h' if it is km/h" if unit == "m/s" else "expected m/s or km/h"
        what = (
            f"faster than {SPEED_MAX_MPS:g} m/s ({SPEED_MAX_MPS * 3.6:g} km/h), so the unit looks "
            f"wrong: the column is read in {_label(unit)} ({alt})"
        )
    raise _limit_error(table, i, name, float(raw[i]), unit, float(v[i]), "m/s", what)


def _chainage(
    table: _Table,
    j: int,
    name: str,
    unit: str,
    t: NDArray[np.float64],
    speed: tuple[NDArray[np.float64], str, str] | None,
) -> NDArray[np.float64]:
    c = table.columns[j] * _ROLES["chainage"].factors[unit]
    check_chainage(c, t, name, table.line)
    total = float(c[-1] - c[0])
    mean_v = abs(total) / float(t[-1] - t[0])
    if speed is None:
        if not (SPEED_MIN_MPS <= mean_v <= SPEED_MAX_MPS):
            raise LogFormatError(
                f"column {name!r} (read in {unit}) moves at {mean_v:.4g} m/s on average, "
                f"outside {SPEED_MIN_MPS:g} to {SPEED_MAX_MPS:g} m/s: is the unit right? "
                "(set chainage_unit to 'm' or 'km')",
                column=name,
            )
    else:
        v, vname, vunit = speed
        ratio = mean_v / float(np.mean(v))
        if not (0.5 <= ratio <= 2.0):
            raise LogFormatError(
                f"column {name!r} (read in {unit}) advances at {mean_v:.4g} m/s on average but "
                f"the speed column {vname!r} (read in {_label(vunit)}) averages "
                f"{float(np.mean(v)):.4g} m/s: one of the units is wrong "
                "(set chainage_unit or speed_unit)",
                column=name,
            )
    return c


def _wheel_load(table: _Table, j: int, name: str, unit: str) -> NDArray[np.float64]:
    raw = table.columns[j]
    f = table.columns[j] * _ROLES["wheel_load"].factors[unit]
    others = " or ".join(repr(u) for u in OPTION_UNITS["wheel_load"] if u != unit)
    _refuse_outside(
        table, name, raw, unit, f, WHEEL_LOAD_MIN_N, WHEEL_LOAD_MAX_N, "N",
        f"a static wheel load lies between {WHEEL_LOAD_MIN_N / 1e3:g} and "
        f"{WHEEL_LOAD_MAX_N / 1e3:g} kN, so the unit looks wrong: the column is read in "
        f"{_label(unit)} (set wheel_load_unit to {others})",
    )  # fmt: skip
    return f


def _fixes(
    table: _Table, jlat: int, jlon: int, names: list[str]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Latitude and longitude, degrees: NaN where a row has no fix (both cells empty)."""
    lat = np.asarray(table.columns[jlat], dtype=np.float64)
    lon = np.asarray(table.columns[jlon], dtype=np.float64)
    half = np.isnan(lat) != np.isnan(lon)
    i = first_true(half)
    if i is not None:
        ln = table.line(i)
        empty, full = (names[jlat], names[jlon]) if np.isnan(lat[i]) else (names[jlon], names[jlat])
        raise LogFormatError(
            f"line {ln} has a value in column {full!r} but column {empty!r} is empty: a "
            "position fix needs both latitude and longitude (leave both empty between fixes)",
            column=empty,
            row=ln,
        )
    for j, a, limit in ((jlat, lat, 90.0), (jlon, lon, 180.0)):
        i = first_true(np.isinf(a) | (np.abs(a) > limit))
        if i is not None:
            ln = table.line(i)
            swap = (
                " (latitude and longitude look swapped: check lat_column and lon_column)"
                if j == jlat and abs(a[i]) <= 180.0 and abs(lon[i]) <= 90.0
                else ""
            )
            raise LogFormatError(
                f"column {names[j]!r} at line {ln} is {a[i]:g}: a "
                f"{_ROLES['lat' if j == jlat else 'lon'].label} is within ±{limit:g} degrees "
                f"(WGS84 decimal degrees expected){swap}",
                column=names[j],
                row=ln,
            )
    return lat, lon


def _known(units: dict[str, str | None], role: str) -> str:
    unit = units[role]
    if unit is None:  # resolve_units decides every unit when given the data
        raise RuntimeError(f"the {role} unit was left unresolved")
    return unit


def parse_run_csv(
    source: Source, options: CsvOptions | None = None, *, max_bytes: int | None = None
) -> ParsedRun:
    """Read a logger's CSV into a :class:`RunLog`, reporting what was recognised.

    Same as :func:`read_run_csv` but also returns the delimiter, the column chosen for each
    role, the units and the gravity handling, for display to the user.

    Raises
    ------
    LogFormatError
        See :func:`read_run_csv`.
    """
    opts = options if options is not None else CsvOptions()
    if not isinstance(opts, CsvOptions):
        raise ParameterError(f"options must be CsvOptions, got {type(opts).__name__}")
    data = _read_source(source, max_bytes)
    if not data or data.isspace():
        raise LogFormatError("the file is empty: no header line naming the columns (and no data)")
    encoding, enc_note = _detect_encoding(data)
    check_lines(data, char_bytes=2 if encoding == "utf-16" else 1)
    notes = [enc_note] if enc_note else []
    src = _Source(data, encoding)
    with src.lines() as f:
        header = _read_header(f)
    mapping = _map_columns(header.names, opts, header.line)
    if mapping.problems:
        raise mapping.problems[0]
    names = header.names
    idx = {r: j for r, j in mapping.index.items() if j is not None}
    sparse = frozenset(idx[r] for r in SPARSE_ROLES if r in idx)
    table = _parse_table(src, header, sorted(set(idx.values())), sparse)
    if table.n == 0:
        raise LogFormatError(
            f"the file has a header (line {header.line}) but no data rows", row=header.line
        )
    if table.n < MIN_SAMPLES:
        raise LogFormatError(
            f"the log has only {table.n} samples: at least MIN_SAMPLES = {MIN_SAMPLES} are "
            "needed, the run is too short to invert"
        )
    for j in idx.values():
        if j not in sparse:
            _check_finite(table, j, names[j])

    jt, ja, jw = idx["time"], idx["accel"], idx["pitch_rate"]
    units, assumed, unit_notes = resolve_units(
        {r: names[j] for r, j in idx.items()},
        opts,
        mapping.name_unit,
        t0=float(table.columns[jt][0]),
        accel_mean=float(np.mean(table.columns[ja])),
    )
    notes.extend(unit_notes + assumed)
    t = _time(table, jt, names[jt], _known(units, "time"))
    accel, gravity = _accel(table, ja, names[ja], _known(units, "accel"), opts.gravity)
    pitch = _pitch_rate(table, jw, names[jw], _known(units, "pitch_rate"))
    speed = None
    if "speed" in idx:
        speed = _speed(table, idx["speed"], names[idx["speed"]], _known(units, "speed"))
    chainage = None
    if "chainage" in idx:
        jc = idx["chainage"]
        sp = (speed, names[idx["speed"]], _known(units, "speed")) if speed is not None else None
        chainage = _chainage(table, jc, names[jc], _known(units, "chainage"), t, sp)
    wheel_load = None
    if "wheel_load" in idx:
        jl = idx["wheel_load"]
        wheel_load = _wheel_load(table, jl, names[jl], _known(units, "wheel_load"))

    lat = lon = None
    if "lat" in idx and "lon" in idx:
        lat, lon = _fixes(table, idx["lat"], idx["lon"], names)

    log = RunLog(
        time_s=t,
        accel_z_mps2=accel,
        pitch_rate_radps=pitch,
        speed_mps=speed,
        chainage_m=chainage,
        wheel_load_n=wheel_load,
        lat_deg=lat,
        lon_deg=lon,
    )
    # The columns' checks above are every check of check_plausible (the one check each input
    # path shares: same limits, same file lines) with unit hints in their messages: a service
    # prepares this log with prepare_run(..., log_checked=True) and they are not repeated.
    return ParsedRun(
        log=log,
        delimiter=header.delimiter,
        encoding=encoding,
        columns={r: (names[j] if j is not None else None) for r, j in mapping.index.items()},
        units=units,
        gravity=gravity,
        notes=notes,
    )


def read_run_csv(
    source: Source, options: CsvOptions | None = None, *, max_bytes: int | None = None
) -> RunLog:
    """Read a logger's CSV into a :class:`~engine.runlog.RunLog` (SI units, gravity removed).

    Parameters
    ----------
    source : bytes, str, os.PathLike or binary file object
        The file's content, its path, or an open binary file. Gzip (magic bytes ``1f 8b``) is
        decompressed; a UTF-8 BOM is dropped; ``\\r\\n`` line ends are fine.
    options : CsvOptions, optional
        Column names and units when they are not recognised from the header, and whether the
        acceleration includes gravity. Explicit options always win.
    max_bytes : int, optional
        Largest size of a gzip source once decompressed, B (default
        :data:`MAX_DECOMPRESSED_BYTES`).

    Returns
    -------
    RunLog
        ``time_s`` in s (epoch times shifted to start at 0), ``accel_z_mps2`` in m/s² with
        gravity removed, ``pitch_rate_radps`` in rad/s, ``speed_mps`` in m/s and/or
        ``chainage_m`` in m, and ``wheel_load_n`` in N when the log has a load-weigh column.

    Raises
    ------
    LogFormatError
        The file is empty, has only a header, misses a column or has two candidates for one,
        repeats a column name, holds text, an empty field, NaN or infinity where a number
        belongs, has a line with the wrong number of fields or a decimal comma, a time column
        that is not strictly increasing with a constant step (gaps, irregular sampling), fewer
        than :data:`MIN_SAMPLES` samples, or values implausible in the unit read (acceleration
        beyond 50 m/s², pitch rate beyond 5 rad/s, speed outside 0.5 to 150 m/s, static wheel
        load outside 5 to 300 kN). The message names the column, the 1-based file line
        (``.row``; the header is line 1 when nothing precedes it) and the unit expected. A
        line too long for the header's columns (see :mod:`engine.logio.limits`) is refused
        before it is split.
    InputTooLarge
        A gzip source expands to more than ``max_bytes``.
    ParameterError
        ``options`` is not a :class:`CsvOptions`.
    OSError
        A path cannot be opened.

    Examples
    --------
    >>> log = read_run_csv(b"timestamp,az_g,gyro_y_dps,speed_kmh\\n...")  # doctest: +SKIP
    """
    return parse_run_csv(source, options, max_bytes=max_bytes).log
