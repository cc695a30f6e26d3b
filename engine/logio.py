"""Reading run logs as loggers write them, and writing canonical ones.

A logger's CSV is turned into a :class:`~engine.runlog.RunLog` (SI units, gravity removed) by
:func:`read_run_csv`. Column names and units are recognised from the header (``time_s``,
``timestamp``, ``az_g``, ``gyro_y_dps``, ``speed_kmh``, ``chainage_m``, ...) unless
:class:`CsvOptions` names them; everything else about the file is checked up front, and every
problem is a :class:`~engine.errors.LogFormatError` naming the column, the 1-based line of the
file (the header is line 1 when nothing precedes it) and the unit expected.

Accepted input: bytes, a path or a binary file object; gzip-compressed or plain; UTF-8 (with or
without BOM), UTF-16 with BOM, or Windows-1252 text; ``\\n``, ``\\r\\n`` or ``\\r`` line ends;
``,``, ``;``, tab or whitespace delimiters; ``#`` comment lines. Decimal commas are refused.

Large files take the fast path (numpy's C tokenizer streaming over the decoded text, about a
second per 150 MB); only a file the fast path rejects is re-read line by line, which either
reads it (text in columns that are not used, trailing delimiters) or finds the exact line that
is wrong.
"""

from __future__ import annotations

import codecs
import csv
import gzip
import io
import math
import os
import re
import warnings
import zlib
from array import array
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, field, fields
from typing import IO, Any, BinaryIO, TextIO

import numpy as np
from numpy.typing import NDArray

from .errors import LogFormatError, ParameterError
from .runlog import RunLog
from .vehicle import GRAVITY

__all__ = [
    "ACCEL_LIMIT_MPS2",
    "MAX_DECOMPRESSED_BYTES",
    "MIN_SAMPLES",
    "PITCH_RATE_LIMIT_RADPS",
    "SPEED_MAX_MPS",
    "SPEED_MIN_MPS",
    "CsvOptions",
    "CsvPreview",
    "ParsedRun",
    "parse_run_csv",
    "preview_csv",
    "read_run_csv",
    "write_run_csv",
]

MIN_SAMPLES = 200
"""Fewest samples a log may have: shorter runs are too short to invert."""

ACCEL_LIMIT_MPS2 = 50.0
"""Largest plausible vertical body acceleration, m/s² (gravity removed); beyond it the unit is
wrong (e.g. counts or mm/s²)."""

PITCH_RATE_LIMIT_RADPS = 5.0
"""Largest plausible body pitch rate, rad/s; beyond it the unit is wrong (e.g. deg/s)."""

SPEED_MIN_MPS = 0.5
"""Slowest speed accepted at any sample, m/s (standstills cannot be inverted)."""

SPEED_MAX_MPS = 150.0
"""Fastest plausible speed, m/s (540 km/h); beyond it the unit is wrong (e.g. km/h)."""

MIN_RATE_HZ = 10.0
"""Lowest plausible sample rate, Hz; a slower time column is in the wrong unit (ms read as s)."""

MAX_RATE_HZ = 100_000.0
"""Highest plausible sample rate, Hz."""

EPOCH_THRESHOLD_S = 1e8
"""Time values above this (about 1973 in Unix seconds) are taken as epoch seconds."""

EPOCH_MS_THRESHOLD = 1e11
"""Time values above this are taken as epoch milliseconds."""

STEP_TOLERANCE = 0.01
"""Allowed deviation of a time step from the median step, as a fraction of it."""

GAP_FACTOR = 1.5
"""A step longer than this many median steps is reported as a gap."""

GRAVITY_TOLERANCE_MPS2 = 1.5
"""How far the mean acceleration may be from 9.81 (included) or 0 (removed), m/s²."""

G_UNIT_MPS2 = GRAVITY
"""Value of 1 g when converting from the unit g, m/s². The model's own gravity is used (not the
standard 9.80665) so that a logger at rest reading exactly 1 g gives exactly zero once gravity
is removed."""

MAX_DECOMPRESSED_BYTES = 1 << 30
"""Largest gzip-decompressed size accepted, bytes (a guard against decompression bombs)."""

PREVIEW_BYTES = 1 << 20
"""How much (decompressed) text :func:`preview_csv` looks at, bytes."""

_SAMPLE_LINES = 20  # data lines used to sniff the delimiter
_GUESS_ROWS = 2000  # rows the preview parses to guess units and gravity

# ---------------------------------------------------------------------------------------------
# Roles: what each column means, the names it goes by, and its units
# ---------------------------------------------------------------------------------------------

ROLES = ("time", "accel", "pitch_rate", "speed", "chainage")


@dataclass(frozen=True)
class _Role:
    key: str
    label: str
    canonical: str
    aliases: frozenset[str]
    units: Mapping[str, str]  # compact unit spelling -> canonical unit
    unsupported: frozenset[str]  # compact unit spellings we recognise but do not convert
    factors: Mapping[str, float]  # canonical unit -> factor to SI
    examples: str  # for error messages: names that are recognised
    alias_units: Mapping[str, str] = field(default_factory=dict)  # names that imply a unit


def _words(text: str) -> list[str]:
    return text.split()


def _units(table: Mapping[str, Iterable[str]]) -> dict[str, str]:
    return {spelling: unit for unit, spellings in table.items() for spelling in spellings}


_ROLES: dict[str, _Role] = {
    "time": _Role(
        key="time",
        label="time",
        canonical="time_s",
        aliases=frozenset(
            _words(
                "time t timestamp time_stamp ts epoch unix_time unixtime epoch_time elapsed "
                "elapsed_time sample_time"
            )
        ),
        units=_units(
            {
                "s": _words("s sec secs second seconds"),
                "ms": _words("ms msec msecs millis millisecond milliseconds"),
                "epoch_s": _words("epoch epochs unix unixs epochsec epochseconds unixtime"),
            }
        ),
        unsupported=frozenset(_words("us usec micros ns nsec min mins h hr")),
        factors={"s": 1.0, "ms": 1e-3, "epoch_s": 1.0},
        examples="time_s, time_ms, timestamp, time, t",
        alias_units={"epoch": "epoch_s", "unix_time": "epoch_s", "unixtime": "epoch_s"},
    ),
    "accel": _Role(
        key="accel",
        label="vertical acceleration",
        canonical="accel_z_mps2",
        aliases=frozenset(
            _words(
                "accel_z acc_z az a_z accz accelz acceleration_z accel acc acceleration "
                "vertical_accel vertical_acceleration accel_vertical acc_vertical acc_vert "
                "accel_vert lin_acc_z linear_acceleration_z z_accel z_acc"
            )
        ),
        units=_units({"m/s2": _words("ms2 mps2 mss mpss msec2 mpersec2"), "g": ["g", "gs"]}),
        unsupported=frozenset(_words("mg millig mms2 cms2 gal ftps2 fts2 counts lsb")),
        factors={"m/s2": 1.0, "g": G_UNIT_MPS2},
        examples="accel_z_mps2, az_g, acc_z_ms2, accel_z, acc_z, az",
    ),
    "pitch_rate": _Role(
        key="pitch_rate",
        label="pitch rate",
        canonical="pitch_rate_radps",
        aliases=frozenset(
            _words(
                "pitch_rate pitchrate pitch_velocity gyro_y gyr_y gyroy gy wy w_y omega_y rate_y "
                "angular_rate_y ang_rate_y angular_velocity_y ang_vel_y gyro"
            )
        ),
        units=_units(
            {
                "rad/s": _words("rads radps radsec radpersec radpers"),
                "deg/s": _words("degs dps degps degsec degpersec degpers"),
            }
        ),
        unsupported=frozenset(_words("rpm mrads mdps counts lsb")),
        factors={"rad/s": 1.0, "deg/s": math.pi / 180.0},
        examples="pitch_rate_radps, gyro_y_dps, gyro_y_rads, gyro_y, pitch_rate, gy",
    ),
    "speed": _Role(
        key="speed",
        label="speed",
        canonical="speed_mps",
        aliases=frozenset(
            _words("speed v vel velocity spd ground_speed gps_speed train_speed vehicle_speed")
        ),
        units=_units(
            {
                "m/s": _words("ms mps mpersec msec"),
                "km/h": _words("kmh kph kmph kmhr kmperh kmperhour"),
            }
        ),
        unsupported=frozenset(_words("mph kn kt knots kts fts fps")),
        factors={"m/s": 1.0, "km/h": 1.0 / 3.6},
        examples="speed_mps, speed_kmh, speed_kph, speed, v",
    ),
    "chainage": _Role(
        key="chainage",
        label="chainage",
        canonical="chainage_m",
        aliases=frozenset(
            _words(
                "chainage km position pos odometer odo distance dist mileage kilometrage "
                "track_position location"
            )
        ),
        units=_units({"m": _words("m metre meter metres meters"), "km": ["km"]}),
        unsupported=frozenset(_words("mi mile miles ft feet yd")),
        factors={"m": 1.0, "km": 1000.0},
        examples="chainage_m, odometer_m, position, chainage, km",
        alias_units={"km": "km", "kilometrage": "km"},
    ),
}

_OPTION_UNITS: dict[str, tuple[str, ...]] = {
    "time": ("s", "ms", "epoch_s"),
    "accel": ("m/s2", "g"),
    "pitch_rate": ("rad/s", "deg/s"),
    "speed": ("m/s", "km/h"),
    "chainage": ("m", "km"),
}
_GRAVITY_MODES = ("auto", "included", "removed")
_UNIT_LABEL = {"m/s2": "m/s²", "epoch_s": "epoch s"}


def _unit_key(text: str) -> str:
    """Compact spelling of a unit: lower case, no separators (``'m/s^2'`` -> ``'ms2'``)."""
    t = text.lower().replace("²", "2").replace("°", "deg").replace("µ", "u")
    return re.sub(r"[^a-z0-9]", "", t)


def _label(unit: str) -> str:
    return _UNIT_LABEL.get(unit, unit)


# ---------------------------------------------------------------------------------------------
# Options
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class CsvOptions:
    """How to read a logger's CSV; every field left at ``None`` is recognised automatically.

    Parameters
    ----------
    time_column, accel_column, pitch_rate_column, speed_column, chainage_column : str, optional
        Header name of the column holding the sample time, the vertical body acceleration, the
        body pitch rate, the vehicle speed and the chainage (odometer). Matched exactly, else
        ignoring case and surrounding spaces. Explicit names always win over recognition.
    time_unit : {'s', 'ms', 'epoch_s'}, optional
        Unit of the time column. ``'epoch_s'`` (Unix seconds) is shifted to start at 0.
        Default: from the column name's suffix (``_s``, ``_ms``), else epoch seconds when the
        values exceed 1e8 (epoch milliseconds above 1e11), else seconds.
    accel_unit : {'m/s2', 'g'}, optional
        Unit of the acceleration (also ``m/s^2``, ``m/s²``, ``mps2``). Default: from the name
        (``_g``, ``_mps2``, ``_ms2``), else g when the mean is about 1, else m/s².
    pitch_rate_unit : {'rad/s', 'deg/s'}, optional
        Unit of the pitch rate (also ``radps``, ``dps``). Default: from the name (``_radps``,
        ``_rads``, ``_dps``, ``_degps``), else rad/s.
    speed_unit : {'m/s', 'km/h'}, optional
        Unit of the speed (also ``mps``, ``kmh``, ``kph``). Default: from the name (``_mps``,
        ``_kmh``, ``_kph``), else m/s.
    chainage_unit : {'m', 'km'}, optional
        Unit of the chainage. Default: from the name (``_m``, ``_km``, a column called ``km``),
        else m.
    gravity : {'auto', 'included', 'removed'}
        Whether the acceleration includes gravity (reads about +1 g at rest). ``'included'``
        subtracts 9.81 m/s²; ``'auto'`` decides from the mean acceleration.

    Raises
    ------
    ParameterError
        An option has a value outside the allowed ones (the message lists them), or two
        options name the same column.
    """

    time_column: str | None = None
    accel_column: str | None = None
    pitch_rate_column: str | None = None
    speed_column: str | None = None
    chainage_column: str | None = None
    time_unit: str | None = None
    accel_unit: str | None = None
    pitch_rate_unit: str | None = None
    speed_unit: str | None = None
    chainage_unit: str | None = None
    gravity: str = "auto"

    def __post_init__(self) -> None:
        seen: dict[str, str] = {}
        for role in ROLES:
            opt = f"{role}_column"
            value = getattr(self, opt)
            if value is not None and not isinstance(value, str):
                raise ParameterError(
                    f"{opt} must be a column name (text), got {value!r}", field=opt
                )
            value = value.strip() if value is not None else None
            value = value or None
            object.__setattr__(self, opt, value)
            if value is not None:
                if value in seen:
                    raise ParameterError(
                        f"{seen[value]} and {opt} both name the column {value!r}: "
                        "each column can have one meaning only",
                        field=opt,
                    )
                seen[value] = opt
        for role in ROLES:
            opt = f"{role}_unit"
            object.__setattr__(self, opt, _canonical_option_unit(role, getattr(self, opt)))
        g = self.gravity
        g = "auto" if g is None else g
        if not isinstance(g, str) or g.strip().lower() not in _GRAVITY_MODES:
            raise ParameterError(
                f"gravity must be one of 'auto', 'included', 'removed', got {self.gravity!r}",
                field="gravity",
            )
        object.__setattr__(self, "gravity", g.strip().lower())

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> CsvOptions:
        """Build from a mapping of option names (e.g. form fields); ``None``/empty = default.

        Raises
        ------
        ParameterError
            On an unknown key (the message lists the known ones) or a bad value.
        """
        known = [f.name for f in fields(cls)]
        unknown = sorted(set(d) - set(known))
        if unknown:
            raise ParameterError(
                f"unknown CSV option(s) {', '.join(unknown)}; known options: {', '.join(known)}",
                field=unknown[0],
            )
        kw = {k: v for k, v in d.items() if v is not None and v != ""}
        return cls(**kw)

    def to_dict(self) -> dict[str, str | None]:
        """The options as a plain dict (canonical unit spellings)."""
        return asdict(self)


def _canonical_option_unit(role: str, value: object) -> str | None:
    if value is None:
        return None
    opt = f"{role}_unit"
    allowed = _OPTION_UNITS[role]
    listed = ", ".join(repr(u) for u in allowed)
    if not isinstance(value, str):
        raise ParameterError(f"{opt} must be one of {listed}, got {value!r}", field=opt)
    if not value.strip():
        return None
    key = _unit_key(value)
    if role == "time" and key in ("epochs", "epoch"):
        return "epoch_s"
    unit = _ROLES[role].units.get(key)
    if unit is None or unit not in allowed:
        raise ParameterError(
            f"{opt} {value!r} is not supported: use one of {listed} "
            "(or leave it empty to recognise the unit from the column name)",
            field=opt,
        )
    return unit


# ---------------------------------------------------------------------------------------------
# Bytes in: file, gzip, text encoding
# ---------------------------------------------------------------------------------------------

Source = str | os.PathLike[str] | bytes | bytearray | memoryview | BinaryIO | IO[bytes]

_GZIP_MAGIC = b"\x1f\x8b"
# bytes that never occur in text: C0 controls other than tab, LF, VT, FF, CR and DEL
_CONTROL_BYTES = bytes([*range(0, 9), *range(14, 32), 127])
_TEXT_BYTES_DELETE = bytes(b for b in range(256) if b not in _CONTROL_BYTES)


def _read_source(source: Source) -> bytes:
    """The bytes of a source, gzip-decompressed when it is gzip."""
    if isinstance(source, bytes | bytearray | memoryview):
        data = bytes(source)
    elif isinstance(source, str | os.PathLike):
        with open(source, "rb") as fh:
            data = fh.read()
    elif hasattr(source, "read"):
        got = source.read()
        data = got.encode("utf-8") if isinstance(got, str) else bytes(got)
    else:
        raise LogFormatError(
            f"cannot read a run log from {type(source).__name__}: "
            "give bytes, a file path or a binary file object"
        )
    if data[:2] == _GZIP_MAGIC:
        data = _gunzip(data)
    return data


def _gunzip(data: bytes, limit: int | None = None) -> bytes:
    """Decompress gzip data, refusing more than ``limit`` (default MAX_DECOMPRESSED_BYTES)."""
    cap = MAX_DECOMPRESSED_BYTES if limit is None else limit
    try:
        with gzip.GzipFile(fileobj=io.BytesIO(data)) as gz:
            out = gz.read(cap + 1)
    except (OSError, EOFError, zlib.error) as e:
        raise LogFormatError(f"the gzip-compressed file is corrupt or truncated ({e})") from None
    if len(out) > cap:
        raise LogFormatError(
            f"the gzip-compressed file expands to more than {cap} bytes "
            f"(MAX_DECOMPRESSED_BYTES): split the run into shorter logs"
        )
    if out[:2] == _GZIP_MAGIC:
        raise LogFormatError("the file is gzip-compressed twice: compress the CSV only once")
    return out


def _gunzip_head(data: bytes, size: int) -> tuple[bytes, bool]:
    """The first ``size`` decompressed bytes of gzip data, and whether there is more."""
    d = zlib.decompressobj(wbits=16 + zlib.MAX_WBITS)
    try:
        out = d.decompress(data, size)
    except zlib.error as e:
        raise LogFormatError(f"the gzip-compressed file is corrupt ({e})") from None
    return out, bool(d.unconsumed_tail) or not d.eof


def _line_of_offset(data: bytes, offset: int) -> int:
    return data.count(b"\n", 0, offset) + 1


def _detect_encoding(data: bytes, final: bool = True) -> tuple[str, str | None]:
    """Text encoding of ``data`` and a note when it is not UTF-8.

    Raises
    ------
    LogFormatError
        When the data is not text (binary, zip, spreadsheet).
    """
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        return "utf-16", None
    if data.startswith(b"PK\x03\x04"):
        raise LogFormatError(
            "the file is a zip archive (an .xlsx workbook?), not CSV text: "
            "export the sheet as CSV, or gzip the CSV"
        )
    bad = data[:65536].translate(None, _TEXT_BYTES_DELETE)
    if bad:
        i = data.index(bad[:1])
        raise LogFormatError(
            f"the file is not CSV text: it holds the binary byte 0x{bad[0]:02x} "
            f"at line {_line_of_offset(data, i)}",
            row=_line_of_offset(data, i),
        )
    if data.isascii():
        return "utf-8-sig", None
    dec = codecs.getincrementaldecoder("utf-8-sig")()
    view = memoryview(data)
    step = 1 << 20
    try:
        for i in range(0, len(data), step):
            dec.decode(view[i : i + step], final=final and i + step >= len(data))
        return "utf-8-sig", None
    except UnicodeDecodeError:
        pass
    bad = data.translate(None, _TEXT_BYTES_DELETE)
    if bad:
        i = data.index(bad[:1])
        line = _line_of_offset(data, i)
        raise LogFormatError(
            f"the file is not CSV text: it holds the binary byte 0x{bad[0]:02x} at line {line}",
            row=line,
        )
    # Excel on Windows writes CSV in Windows-1252; its five undefined bytes make it Latin-1
    enc = "latin-1" if any(bytes([b]) in data for b in b"\x81\x8d\x8f\x90\x9d") else "cp1252"
    return enc, f"the file is not UTF-8: read as {enc}"


@dataclass(frozen=True)
class _Source:
    data: bytes
    encoding: str

    def lines(self) -> io.TextIOWrapper:
        # universal newlines: \r\n and \r become \n
        return io.TextIOWrapper(io.BytesIO(self.data), encoding=self.encoding, newline=None)


# ---------------------------------------------------------------------------------------------
# Header, delimiter, fields
# ---------------------------------------------------------------------------------------------

_DELIMITER_LABEL = {",": "',' (comma)", ";": "';' (semicolon)", "\t": "tab", " ": "whitespace"}
_DECIMAL_COMMA = re.compile(r"^[+-]?\d+,\d+([eE][+-]?\d+)?$")
_DATE_LIKE = re.compile(r"\d{4}-\d{2}-\d{2}|\d{1,2}:\d{2}")


def _is_skipped(stripped: str) -> bool:
    return not stripped or stripped[0] == "#"


def _split(line: str, delimiter: str) -> list[str]:
    """Fields of one line (already stripped of its line end)."""
    if delimiter == " ":
        return line.split()
    if '"' in line:
        return next(csv.reader([line], delimiter=delimiter, quotechar='"'))
    return line.split(delimiter)


def _field_count_ok(k: int, n: int, fields_: list[str]) -> bool:
    # a trailing delimiter on data lines (an empty last field) is tolerated
    return k == n or (k == n + 1 and not fields_[-1].strip())


def _sniff(header: str, samples: list[str]) -> str:
    best: tuple[bool, int] | None = None
    chosen = ""
    for d in (",", ";", "\t"):
        nh = len(_split(header, d))
        if nh < 2:
            continue
        ok = all(_field_count_ok(len(f), nh, f) for f in (_split(s, d) for s in samples))
        if best is None or (ok, nh) > best:
            best, chosen = (ok, nh), d
    if chosen:
        return chosen
    nh = len(header.split())
    if nh >= 2 and all(len(s.split()) == nh for s in samples):
        return " "
    others = [c for c in header if not (c.isalnum() or c in "_-. ()[]/^²°\"'")]
    hint = ""
    if others:
        common = max(set(others), key=others.count)
        hint = f" This file seems to use {common!r} as the delimiter."
    raise LogFormatError(
        f"the header {_short(header, 80)!r} is a single column: columns must be separated by "
        f"',' (comma; or ';', tab or spaces).{hint}",
    )


@dataclass(frozen=True)
class _Header:
    line: int  # 1-based line number of the header
    names: list[str]
    delimiter: str
    samples: list[str]  # the first data lines (stripped), for sniffing and the preview


def _read_header(lines: Iterable[str]) -> _Header:
    it = iter(lines)
    header = None
    ln = 0
    for ln, raw in enumerate(it, 1):  # noqa: B007
        s = raw.strip()
        if not _is_skipped(s):
            header = s.lstrip("\ufeff")
            break
    if header is None:
        raise LogFormatError(
            "the file is empty: no header line naming the columns (and no data)"
            if ln == 0
            else "the file has no header line: it holds only blank or comment lines"
        )
    samples: list[str] = []
    for raw in it:
        s = raw.strip()
        if _is_skipped(s):
            continue
        samples.append(_strip_comment(s))
        if len(samples) >= _SAMPLE_LINES:
            break
    delimiter = _sniff(header, samples)
    raw_names = [n.strip().strip('"').strip() for n in _split(header, delimiter)]
    if (
        len(raw_names) > 2
        and not raw_names[-1]
        and samples
        and all(len(_split(s, delimiter)) == len(raw_names) - 1 for s in samples)
    ):
        raw_names.pop()  # a trailing delimiter on the header line only
    names = [n if n else f"column {k}" for k, n in enumerate(raw_names, 1)]
    return _Header(line=ln, names=names, delimiter=delimiter, samples=samples)


def _strip_comment(s: str) -> str:
    return s[: s.index("#")].rstrip() if "#" in s else s


def _short(text: str, n: int = 40) -> str:
    return text if len(text) <= n else text[: n - 1] + "…"


# ---------------------------------------------------------------------------------------------
# Column recognition
# ---------------------------------------------------------------------------------------------

_BRACKET_UNIT = re.compile(r"[\(\[\{]([^\)\]\}]*)[\)\]\}]\s*$")


def _split_name(name: str) -> tuple[str, str | None]:
    """Snake-case base of a column name and the unit written in brackets, if any."""
    unit = None
    m = _BRACKET_UNIT.search(name)
    if m:
        unit, name = m.group(1), name[: m.start()]
    s = re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", name.strip())  # camelCase -> camel_Case
    s = s.lower().replace("²", "2").replace("°", "deg")
    return re.sub(r"[^a-z0-9]+", "_", s).strip("_"), unit


@dataclass(frozen=True)
class _Match:
    unit: str | None  # canonical unit the name implies, None when it says nothing
    unsupported: str | None = None  # a unit we recognise but cannot convert


def _match(name: str, role: _Role) -> _Match | None:
    """Whether a column name fits a role, and the unit its name implies."""
    base, bracket = _split_name(name)
    if bracket is not None:
        if base not in role.aliases and base != role.canonical:
            return None
        key = _unit_key(bracket)
        if not key:
            return _Match(role.alias_units.get(base))
        if key in role.units:
            return _Match(role.units[key])
        return _Match(None, unsupported=bracket.strip())
    if base in role.aliases:
        return _Match(role.alias_units.get(base))
    tokens = base.split("_")
    for k in (1, 2, 3):
        if len(tokens) <= k:
            break
        stem, key = "_".join(tokens[:-k]), "".join(tokens[-k:])
        if stem in role.aliases:
            if key in role.units:
                return _Match(role.units[key])
            if key in role.unsupported:
                return _Match(None, unsupported="_".join(tokens[-k:]))
    return None


def _unit_from_name(name: str, role: _Role) -> str | None:
    """Unit implied by any column name's suffix or bracket (for explicitly chosen columns)."""
    base, bracket = _split_name(name)
    if bracket is not None:
        return role.units.get(_unit_key(bracket))
    if base in role.alias_units:
        return role.alias_units[base]
    tokens = base.split("_")
    for k in (1, 2, 3):
        if len(tokens) <= k:
            break
        key = "".join(tokens[-k:])
        if key in role.units:
            return role.units[key]
    return None


def _find_column(names: list[str], wanted: str) -> int | None:
    if wanted in names:
        return names.index(wanted)
    folded = [i for i, n in enumerate(names) if n.strip().casefold() == wanted.strip().casefold()]
    return folded[0] if len(folded) == 1 else None


@dataclass
class _Mapping:
    index: dict[str, int | None]
    name_unit: dict[str, str | None]
    problems: list[LogFormatError]


def _columns_found(names: list[str]) -> str:
    return ", ".join(repr(n) for n in names)


def _map_columns(names: list[str], options: CsvOptions, header_line: int) -> _Mapping:
    """Assign columns to roles; problems are collected, not raised (the preview shows them)."""
    problems: list[LogFormatError] = []
    index: dict[str, int | None] = dict.fromkeys(ROLES)
    name_unit: dict[str, str | None] = dict.fromkeys(ROLES)

    seen: dict[str, int] = {}
    for j, n in enumerate(names):
        if n in seen:
            problems.append(
                LogFormatError(
                    f"column {n!r} appears twice in the header (line {header_line}, columns "
                    f"{seen[n] + 1} and {j + 1}): every column needs its own name",
                    column=n,
                    row=header_line,
                )
            )
        else:
            seen[n] = j

    taken: set[int] = set()
    for role in ROLES:
        wanted = getattr(options, f"{role}_column")
        if wanted is None:
            continue
        found = _find_column(names, wanted)
        if found is None:
            problems.append(
                LogFormatError(
                    f"{role}_column {wanted!r} is not a column of the file; "
                    f"columns found: {_columns_found(names)}",
                    column=wanted,
                    row=header_line,
                )
            )
            continue
        index[role] = found
        name_unit[role] = _unit_from_name(names[found], _ROLES[role])
        taken.add(found)

    near_misses: dict[str, list[str]] = {r: [] for r in ROLES}
    for role in ROLES:
        if getattr(options, f"{role}_column") is not None:
            continue
        spec = _ROLES[role]
        cands: list[tuple[int, _Match]] = []
        for j, n in enumerate(names):
            if j in taken:
                continue
            m = _match(n, spec)
            if m is None:
                continue
            if m.unsupported is not None:
                near_misses[role].append(
                    f"column {n!r} looks like the {spec.label} but its unit {m.unsupported!r} "
                    f"is not supported (use {' or '.join(_label(u) for u in _OPTION_UNITS[role])})"
                )
                continue
            cands.append((j, m))
        if len(cands) > 1:
            listed = " and ".join(repr(names[j]) for j, _ in cands)
            problems.append(
                LogFormatError(
                    f"{len(cands)} columns could be the {spec.label}: {listed}; "
                    f"set {role}_column to the one to use",
                    column=names[cands[0][0]],
                    row=header_line,
                )
            )
        elif cands:
            j, m = cands[0]
            index[role], name_unit[role] = j, m.unit

    def missing(roles: tuple[str, ...]) -> None:
        labels = " or ".join(_ROLES[r].label for r in roles)
        expected = "; ".join(f"{_ROLES[r].label}: {_ROLES[r].examples}" for r in roles)
        opts = " or ".join(f"{r}_column" for r in roles)
        extra = [m + "." for r in roles for m in near_misses[r]]
        if all(re.fullmatch(r"[+-]?[\d.eE+-]+", n) for n in names):
            extra.append(
                "The first line holds numbers: the file needs a header line naming columns."
            )
        problems.append(
            LogFormatError(
                " ".join(
                    [
                        f"no {labels} column: columns found (line {header_line}): "
                        f"{_columns_found(names)}; expected names such as {expected}, "
                        f"or set {opts}.",
                        *extra,
                    ]
                ),
                column=_ROLES[roles[0]].canonical,
                row=header_line,
            )
        )

    for role in ("time", "accel", "pitch_rate"):
        if index[role] is None and getattr(options, f"{role}_column") is None:
            missing((role,))
    if (
        index["speed"] is None
        and index["chainage"] is None
        and options.speed_column is None
        and options.chainage_column is None
    ):
        missing(("speed", "chainage"))
    return _Mapping(index=index, name_unit=name_unit, problems=problems)


# ---------------------------------------------------------------------------------------------
# Numbers: fast path and line-by-line path
# ---------------------------------------------------------------------------------------------


class _Table:
    """The needed columns as float arrays (file units) and the file line of each row."""

    def __init__(
        self,
        columns: dict[int, NDArray[np.float64]],
        n: int,
        source: _Source,
        header: _Header,
        lines: NDArray[np.int64] | None,
    ) -> None:
        self.columns = columns
        self.n = n
        self._source = source
        self._header = header
        self._lines = lines

    def line(self, row: int) -> int:
        """1-based file line number of data row ``row`` (0-based)."""
        if self._lines is not None:
            return int(self._lines[row])
        # only reached when reporting an error: count data lines up to ``row``
        k = -1
        with self._source.lines() as f:
            for ln, raw in enumerate(f, 1):
                if ln <= self._header.line or _is_skipped(raw.strip()):
                    continue
                k += 1
                if k == row:
                    return ln
        return self._header.line + 1 + row


def _parse_fast(src: _Source, header: _Header) -> NDArray[np.float64] | None:
    """All columns via numpy's C tokenizer, or None when the file needs the careful path."""
    with src.lines() as f:
        for _ in range(header.line):
            f.readline()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # "input contained no data"
                arr = np.loadtxt(
                    f,
                    dtype=np.float64,
                    delimiter=None if header.delimiter == " " else header.delimiter,
                    comments="#",
                    quotechar='"',
                    ndmin=2,
                )
        except (ValueError, UnicodeDecodeError):
            return None
    if arr.shape[0] == 0 or arr.shape[1] != len(header.names):
        return None
    return arr


def _to_float(text: str, column: str, line: int) -> float:
    t = text.strip()
    if len(t) >= 2 and t[0] == t[-1] == '"':
        t = t[1:-1].strip()
    if not t:
        raise LogFormatError(
            f"column {column!r} is empty at line {line}: every sample needs a number",
            column=column,
            row=line,
        )
    try:
        if "_" in t:  # float() accepts 1_000, loggers never write it
            raise ValueError(t)
        return float(t)
    except ValueError:
        pass
    if _DECIMAL_COMMA.match(t):
        raise LogFormatError(
            f"column {column!r} at line {line} holds {t!r}, a number with a decimal comma: "
            "decimal commas are not supported, write numbers with a decimal point ('0.5')",
            column=column,
            row=line,
        ) from None
    hint = ""
    if _DATE_LIKE.search(t):
        hint = "; dates and clock times are not supported, write the time in s, ms or epoch s"
    raise LogFormatError(
        f"column {column!r} at line {line} holds {_short(t)!r}, which is not a number{hint}",
        column=column,
        row=line,
    ) from None


def _parse_careful(src: _Source, header: _Header, needed: list[int]) -> _Table:
    """Read line by line, converting only the needed columns; raises at the first bad line."""
    n_cols = len(header.names)
    cols = {j: array("d") for j in needed}
    lines = array("q")
    d = header.delimiter
    with src.lines() as f:
        for _ in range(header.line):
            f.readline()
        for ln, raw in enumerate(f, header.line + 1):
            s = raw.strip()
            if _is_skipped(s):
                continue
            s = _strip_comment(s)
            parts = _split(s, d)
            if not _field_count_ok(len(parts), n_cols, parts):
                raise _field_count_error(s, len(parts), n_cols, ln, header)
            for j, out in cols.items():
                out.append(_to_float(parts[j], header.names[j], ln))
            lines.append(ln)
    n = len(lines)
    arrays = {j: np.frombuffer(a, dtype=np.float64) if n else np.empty(0) for j, a in cols.items()}
    return _Table(arrays, n, src, header, np.frombuffer(lines, dtype=np.int64))


def _field_count_error(s: str, k: int, n: int, ln: int, header: _Header) -> LogFormatError:
    msg = (
        f"line {ln} has {k} fields but the header (line {header.line}) has {n} columns "
        f"separated by {_DELIMITER_LABEL[header.delimiter]}"
    )
    if k > n and re.search(r"\d,\d", s):
        msg += (
            "; numbers with a decimal comma ('0,5') would do this: decimal commas are not "
            "supported, write numbers with a decimal point"
        )
    elif k == 1:
        msg += f"; the line is {_short(s)!r}: is a different delimiter used on it?"
    return LogFormatError(msg, row=ln)


def _parse_table(src: _Source, header: _Header, needed: list[int]) -> _Table:
    arr = _parse_fast(src, header)
    if arr is None:
        return _parse_careful(src, header, needed)
    return _Table({j: arr[:, j] for j in needed}, arr.shape[0], src, header, None)


# ---------------------------------------------------------------------------------------------
# From columns to a RunLog: units, gravity, plausibility
# ---------------------------------------------------------------------------------------------


def _auto_time_unit(t0: float) -> str:
    if abs(t0) > EPOCH_MS_THRESHOLD:
        return "ms"
    if abs(t0) > EPOCH_THRESHOLD_S:
        return "epoch_s"
    return "s"


def _auto_accel_unit(mean: float, gravity: str) -> str:
    # a mean of about 1 only makes sense as g with gravity included
    if gravity != "removed" and abs(mean - 1.0) < 0.15:
        return "g"
    return "m/s2"


def _auto_gravity(mean_mps2: float) -> str | None:
    if abs(mean_mps2 - GRAVITY) < GRAVITY_TOLERANCE_MPS2:
        return "included"
    if abs(mean_mps2) < GRAVITY_TOLERANCE_MPS2:
        return "removed"
    return None


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
        Role (``time``, ``accel``, ``pitch_rate``, ``speed``, ``chainage``) -> header name, or
        None when the file has no such column.
    units : dict
        Role -> unit the column was read in (``'s'``, ``'ms'``, ``'epoch_s'``, ``'m/s2'``,
        ``'g'``, ``'rad/s'``, ``'deg/s'``, ``'m/s'``, ``'km/h'``, ``'m'``, ``'km'``) or None.
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


def _first(mask: NDArray[np.bool_]) -> int | None:
    idx = np.flatnonzero(mask)
    return int(idx[0]) if idx.size else None


def _check_finite(table: _Table, j: int, name: str) -> None:
    v = table.columns[j]
    i = _first(~np.isfinite(v))
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
    i = _first(dt <= 0)
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
    h = float(np.median(dt))
    i = _first(np.abs(dt - h) > STEP_TOLERANCE * h)
    if i is not None:
        ln, prev = table.line(i + 1), table.line(i)
        step = float(dt[i])
        if step > GAP_FACTOR * h:
            msg = (
                f"gap in the time column {name!r} at line {ln}: {step:.6g} s after line {prev}, "
                f"{step / h:.3g} times the expected constant step of {h:.6g} s "
                f"({1 / h:.6g} Hz); the log must be sampled without gaps"
            )
        else:
            msg = (
                f"irregular sampling in the time column {name!r} at line {ln}: the step from "
                f"line {prev} is {step:.6g} s, expected a constant step of {h:.6g} s "
                f"({1 / h:.6g} Hz, within {STEP_TOLERANCE:.0%}); resample the log to a constant "
                "rate"
            )
        raise LogFormatError(msg, column=name, row=ln)
    rate = 1.0 / h
    if not (MIN_RATE_HZ <= rate <= MAX_RATE_HZ):
        raise LogFormatError(
            f"the time column {name!r} (read in {_label(unit)}) steps by {h:.6g} s, a sample "
            f"rate of {rate:.6g} Hz, outside the plausible {MIN_RATE_HZ:g} Hz to "
            f"{MAX_RATE_HZ:g} Hz: is the unit right? (set time_unit to 's', 'ms' or 'epoch_s')",
            column=name,
        )
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


def _accel(
    table: _Table, j: int, name: str, unit: str, gravity: str
) -> tuple[NDArray[np.float64], str]:
    raw = table.columns[j]
    a = raw * _ROLES["accel"].factors[unit]
    alt = "set accel_unit='m/s2'" if unit == "g" else "set accel_unit='g' if it is in g"
    i = _first(np.abs(a) > ACCEL_LIMIT_MPS2 + GRAVITY)
    if i is not None:
        raise _limit_error(
            table, i, name, float(raw[i]), unit, float(a[i]), "m/s²",
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
    i = _first(np.abs(a) > ACCEL_LIMIT_MPS2)
    if i is not None:
        raise _limit_error(
            table, i, name, float(raw[i]), unit, float(a[i]), "m/s² with gravity removed",
            f"a vertical body acceleration stays within ±{ACCEL_LIMIT_MPS2:g} m/s²; "
            f"is the unit right? (read in {_label(unit)}, expected m/s² or g)",
        )  # fmt: skip
    return a, gravity


def _pitch_rate(table: _Table, j: int, name: str, unit: str) -> NDArray[np.float64]:
    raw = table.columns[j]
    w = raw * _ROLES["pitch_rate"].factors[unit]
    i = _first(np.abs(w) > PITCH_RATE_LIMIT_RADPS)
    if i is not None:
        alt = (
            "set pitch_rate_unit='deg/s' if it is in deg/s"
            if unit == "rad/s"
            else "expected rad/s or deg/s"
        )
        raise _limit_error(
            table, i, name, float(raw[i]), unit, float(w[i]), "rad/s",
            f"a body pitch rate stays within ±{PITCH_RATE_LIMIT_RADPS:g} rad/s, so the unit "
            f"looks wrong: the column is read in {_label(unit)} ({alt})",
        )  # fmt: skip
    return w


def _speed(table: _Table, j: int, name: str, unit: str) -> NDArray[np.float64]:
    raw = table.columns[j]
    v = raw * _ROLES["speed"].factors[unit]
    i = _first((v < SPEED_MIN_MPS) | (v > SPEED_MAX_MPS))
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
    total = float(c[-1] - c[0])
    if total == 0:
        raise LogFormatError(
            f"column {name!r} does not change: the chainage must move with the vehicle",
            column=name,
        )
    sign = 1.0 if total > 0 else -1.0
    i = _first(np.diff(c) * sign <= 0)
    if i is not None:
        ln = table.line(i + 1)
        raise LogFormatError(
            f"column {name!r} at line {ln} is {float(table.columns[j][i + 1])!r}, not beyond "
            f"{float(table.columns[j][i])!r} at line {table.line(i)}: the chainage must move "
            "steadily "
            f"{'up' if sign > 0 else 'down'} through the run",
            column=name,
            row=ln,
        )
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


def _resolve_unit(role: str, options: CsvOptions, mapping: _Mapping) -> str | None:
    """Unit from the options, else from the column name, else None (decided from the data)."""
    opt: str | None = getattr(options, f"{role}_unit")
    return opt if opt is not None else mapping.name_unit[role]


def parse_run_csv(source: Source, options: CsvOptions | None = None) -> ParsedRun:
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
    data = _read_source(source)
    if not data or data.isspace():
        raise LogFormatError("the file is empty: no header line naming the columns (and no data)")
    encoding, enc_note = _detect_encoding(data)
    notes = [enc_note] if enc_note else []
    src = _Source(data, encoding)
    with src.lines() as f:
        header = _read_header(f)
    mapping = _map_columns(header.names, opts, header.line)
    if mapping.problems:
        raise mapping.problems[0]
    names = header.names
    idx = {r: j for r, j in mapping.index.items() if j is not None}
    table = _parse_table(src, header, sorted(set(idx.values())))
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
        _check_finite(table, j, names[j])

    units: dict[str, str | None] = dict.fromkeys(ROLES)
    for role in idx:
        units[role] = _resolve_unit(role, opts, mapping)

    jt = idx["time"]
    t0 = float(table.columns[jt][0])
    t_unit = units["time"] or _auto_time_unit(t0)
    if t_unit == "s" and opts.time_unit is None and abs(t0) > EPOCH_THRESHOLD_S:
        t_unit = "epoch_s"  # seconds by its name, epoch seconds by its values
    if opts.time_unit is None and (t_unit == "epoch_s" or abs(t0) > EPOCH_MS_THRESHOLD):
        what = "epoch milliseconds" if t_unit == "ms" else "epoch seconds"
        notes.append(f"time column {names[jt]!r} read as {what}, shifted to start at 0")
    units["time"] = t_unit
    t = _time(table, jt, names[jt], t_unit)

    ja = idx["accel"]
    a_unit = units["accel"]
    if a_unit is None:
        a_unit = _auto_accel_unit(float(np.mean(table.columns[ja])), opts.gravity)
        notes.append(
            f"acceleration column {names[ja]!r} read in {_label(a_unit)} "
            "(its name has no unit; set accel_unit to be sure)"
        )
    units["accel"] = a_unit
    accel, gravity = _accel(table, ja, names[ja], a_unit, opts.gravity)

    jw = idx["pitch_rate"]
    w_unit = units["pitch_rate"]
    if w_unit is None:
        w_unit = "rad/s"
        notes.append(
            f"pitch-rate column {names[jw]!r} read in rad/s "
            "(its name has no unit; set pitch_rate_unit to be sure)"
        )
    units["pitch_rate"] = w_unit
    pitch = _pitch_rate(table, jw, names[jw], w_unit)

    speed = None
    if "speed" in idx:
        js = idx["speed"]
        s_unit = units["speed"]
        if s_unit is None:
            s_unit = "m/s"
            notes.append(
                f"speed column {names[js]!r} read in m/s "
                "(its name has no unit; set speed_unit to be sure)"
            )
        units["speed"] = s_unit
        speed = _speed(table, js, names[js], s_unit)

    chainage = None
    if "chainage" in idx:
        jc = idx["chainage"]
        c_unit = units["chainage"] or "m"
        units["chainage"] = c_unit
        sp = (speed, names[idx["speed"]], units["speed"] or "m/s") if speed is not None else None
        chainage = _chainage(table, jc, names[jc], c_unit, t, sp)

    log = RunLog(
        time_s=t,
        accel_z_mps2=accel,
        pitch_rate_radps=pitch,
        speed_mps=speed,
        chainage_m=chainage,
    )
    return ParsedRun(
        log=log,
        delimiter=header.delimiter,
        encoding=encoding,
        columns={r: (names[j] if j is not None else None) for r, j in mapping.index.items()},
        units=units,
        gravity=gravity,
        notes=notes,
    )


def read_run_csv(source: Source, options: CsvOptions | None = None) -> RunLog:
    """Read a logger's CSV into a :class:`~engine.runlog.RunLog` (SI units, gravity removed).

    Parameters
    ----------
    source : bytes, str, os.PathLike or binary file object
        The file's content, its path, or an open binary file. Gzip (magic bytes ``1f 8b``) is
        decompressed; a UTF-8 BOM is dropped; ``\\r\\n`` line ends are fine.
    options : CsvOptions, optional
        Column names and units when they are not recognised from the header, and whether the
        acceleration includes gravity. Explicit options always win.

    Returns
    -------
    RunLog
        ``time_s`` in s (epoch times shifted to start at 0), ``accel_z_mps2`` in m/s² with
        gravity removed, ``pitch_rate_radps`` in rad/s, ``speed_mps`` in m/s and/or
        ``chainage_m`` in m.

    Raises
    ------
    LogFormatError
        The file is empty, has only a header, misses a column or has two candidates for one,
        repeats a column name, holds text, an empty field, NaN or infinity where a number
        belongs, has a line with the wrong number of fields or a decimal comma, a time column
        that is not strictly increasing with a constant step (gaps, irregular sampling), fewer
        than :data:`MIN_SAMPLES` samples, or values implausible in the unit read (acceleration
        beyond 50 m/s², pitch rate beyond 5 rad/s, speed outside 0.5 to 150 m/s). The message
        names the column, the 1-based file line (``.row``; the header is line 1 when nothing
        precedes it) and the unit expected.
    ParameterError
        ``options`` is not a :class:`CsvOptions`.
    OSError
        A path cannot be opened.

    Examples
    --------
    >>> log = read_run_csv(b"timestamp,az_g,gyro_y_dps,speed_kmh\\n...")  # doctest: +SKIP
    """
    return parse_run_csv(source, options).log


# ---------------------------------------------------------------------------------------------
# Preview (the dashboard's column mapping)
# ---------------------------------------------------------------------------------------------


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
        Role (``time``, ``accel``, ``pitch_rate``, ``speed``, ``chainage``) -> column name, or
        None when no column is recognised (or two are: see ``warnings``).
    units : dict
        Role -> unit the column would be read in, or None.
    gravity : str or None
        ``'included'`` or ``'removed'`` (the option, else guessed from the first rows), None
        when it cannot be told.
    warnings : list of str
        Problems that would stop the upload (missing or ambiguous columns, unreadable values
        in the first rows) and assumptions worth checking (units without a suffix).
    """

    delimiter: str
    columns: list[str]
    rows: list[list[str]]
    mapping: dict[str, str | None]
    units: dict[str, str | None]
    gravity: str | None
    warnings: list[str]

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
        }


def preview_csv(data: bytes, n_rows: int = 10, options: CsvOptions | None = None) -> CsvPreview:
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
    raw = bytes(data)
    if raw[:2] == _GZIP_MAGIC:
        head, more = _gunzip_head(raw, PREVIEW_BYTES)
    else:
        head, more = raw[:PREVIEW_BYTES], len(raw) > PREVIEW_BYTES
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
                vals.append(_to_float(f[j], names[j], ln))
            except LogFormatError as e:
                if len(warns) < 20:
                    warns.append(str(e))
        values[role] = np.asarray(vals, dtype=np.float64)
        values[role] = values[role][np.isfinite(values[role])]

    units: dict[str, str | None] = dict.fromkeys(ROLES)
    for role in chosen:
        units[role] = getattr(opts, f"{role}_unit") or mapping.name_unit[role]
    gravity: str | None = None if opts.gravity == "auto" else opts.gravity
    if "time" in chosen and units["time"] is None and values["time"].size:
        units["time"] = _auto_time_unit(float(values["time"][0]))
    if "accel" in chosen:
        a = values["accel"]
        if units["accel"] is None:
            if a.size:
                units["accel"] = _auto_accel_unit(float(np.mean(a)), opts.gravity)
            warns.append(
                f"the unit of {names[chosen['accel']]!r} is not in its name: "
                f"{_label(units['accel'] or 'm/s2')} assumed (set accel_unit)"
            )
        if gravity is None and a.size:
            mean = float(np.mean(a)) * _ROLES["accel"].factors[units["accel"] or "m/s2"]
            gravity = _auto_gravity(mean)
            if gravity is None:
                warns.append(
                    f"the mean of {names[chosen['accel']]!r} in the first rows is "
                    f"{mean:.4g} m/s²: neither gravity included (~{GRAVITY}) nor removed (~0); "
                    "check accel_unit or set gravity"
                )
    for role, default in (("pitch_rate", "rad/s"), ("speed", "m/s"), ("chainage", "m")):
        if role in chosen and units[role] is None:
            units[role] = default
            if role != "chainage":
                warns.append(
                    f"the unit of {names[chosen[role]]!r} is not in its name: "
                    f"{_label(default)} assumed (set {role}_unit)"
                )
    return CsvPreview(
        delimiter=d,
        columns=list(names),
        rows=rows,
        mapping={r: (names[j] if j is not None else None) for r, j in mapping.index.items()},
        units=units,
        gravity=gravity,
        warnings=warns,
    )


# ---------------------------------------------------------------------------------------------
# Writing canonical CSV
# ---------------------------------------------------------------------------------------------

_WRITE_CHUNK = 100_000


def write_run_csv(
    log: RunLog, dest: str | os.PathLike[str] | TextIO, digits: int | None = None
) -> None:
    """Write a run log as canonical CSV.

    Columns ``time_s,accel_z_mps2,pitch_rate_radps`` then ``speed_mps`` and ``chainage_m``
    when the log has them; SI units (s, m/s², rad/s, m/s, m), gravity removed.

    Parameters
    ----------
    log : RunLog
        The run to write.
    dest : str, os.PathLike or text file object
        Where to write. A path ending in ``.gz`` is written gzip-compressed.
    digits : int, optional
        Significant digits per number (1 to 17). Default: the shortest text that reads back
        to exactly the same float (Python's ``repr``), so a round trip is lossless.

    Raises
    ------
    ParameterError
        ``digits`` is out of range.
    """
    if digits is not None and (not isinstance(digits, int) or not 1 <= digits <= 17):
        raise ParameterError(f"digits must be an integer from 1 to 17, got {digits!r}")
    names = ["time_s", "accel_z_mps2", "pitch_rate_radps"]
    cols = [log.time_s, log.accel_z_mps2, log.pitch_rate_radps]
    for name in ("speed_mps", "chainage_m"):
        arr = getattr(log, name)
        if arr is not None:
            names.append(name)
            cols.append(arr)
    one = "%r" if digits is None else f"%.{digits}g"
    fmt = ",".join([one] * len(cols))
    if isinstance(dest, str | os.PathLike):
        path = os.fspath(dest)
        opener = gzip.open if path.endswith(".gz") else open
        with opener(path, "wt", encoding="utf-8", newline="\n") as fh:
            _write_rows(fh, names, cols, fmt)
    else:
        _write_rows(dest, names, cols, fmt)


def _write_rows(fh: IO[str], names: list[str], cols: list[NDArray[np.float64]], fmt: str) -> None:
    fh.write(",".join(names) + "\n")
    n = cols[0].shape[0]
    for i in range(0, n, _WRITE_CHUNK):
        # tolist() gives Python floats, whose %r is the shortest round-trip text
        block = np.column_stack([c[i : i + _WRITE_CHUNK] for c in cols]).tolist()
        fh.write("\n".join([fmt % tuple(r) for r in block]))
        fh.write("\n")
