"""Bad input through the real API: a clear 4xx naming the problem, and nothing stored.

Every case of the catalogue is one request to the running app (multipart upload or JSON body)
built from a good run log with one defect. Each must be answered with the expected 4xx (never
5xx), with a detail that names the problem — the request field, the file's column and line,
or the unit, checked by value and by the words of the message — and must leave every table of
the database exactly as it was (row counts of all tables before and after).

A control case uploads the unmodified log (201), so every refusal is due to its defect; the
harmless variants (BOM, Windows line ends, gzip, semicolons) are accepted.
"""

from __future__ import annotations

import gzip
import io
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest

from api.api_support import assert_zones_match, row_counts, upload

HEADER = "time_s,accel_z_mps2,pitch_rate_radps,speed_mps"


# -- building bad logs from the good one ----------------------------------------------------
def _lines(base: bytes) -> list[str]:
    return base.decode().splitlines()


def _csv(lines: list[str], eol: str = "\n") -> bytes:
    return (eol.join(lines) + eol).encode()


def _edit(base: bytes, line: int, col: int, value: str) -> bytes:
    """The log with the field ``col`` (0-based) of file line ``line`` (1-based) replaced."""
    ls = _lines(base)
    parts = ls[line - 1].split(",")
    parts[col] = value
    ls[line - 1] = ",".join(parts)
    return _csv(ls)


def _drop_column(base: bytes, k: int) -> bytes:
    return _csv([",".join(f for i, f in enumerate(ln.split(",")) if i != k) for ln in _lines(base)])


def _constant_log(n: int, rate_hz: float, speed_mps: float) -> bytes:
    """A log of ``n`` quiet samples at ``rate_hz`` and constant speed (readable, plausible)."""
    rows = [f"{i / rate_hz:.6f},0.0,0.0,{speed_mps}" for i in range(n)]
    return _csv([HEADER, *rows])


def _columns(base: bytes) -> dict[str, list[float]]:
    a = np.loadtxt(io.BytesIO(base), delimiter=",", skiprows=1)
    names = HEADER.split(",")
    return {name: a[:, i].tolist() for i, name in enumerate(names)}


def _json_columns(base: bytes, edit: Callable[[dict[str, list[float]]], None]) -> dict[str, Any]:
    """A JSON ``columns`` upload of the good log with ``edit`` applied to its arrays."""
    cols = _columns(base)
    edit(cols)
    return {"track": "T", "start_chainage_m": 12, "columns": cols}


def _json_text_of(body: dict[str, Any]) -> bytes:
    return json.dumps(body).encode()


def _json_replace(old: str, new: str) -> Callable[[bytes], bytes]:
    """The JSON text of a ``columns`` upload of the good log, its first ``old`` made ``new``."""
    return lambda base: (
        json.dumps(_json_columns(base, lambda _c: None)).replace(old, new, 1).encode()
    )


def _set(name: str, i: int, value: float) -> Callable[[dict[str, list[float]]], None]:
    def edit(cols: dict[str, list[float]]) -> None:
        cols[name][i] = value

    return edit


def _shift_time(i: int, by_s: float) -> Callable[[dict[str, list[float]]], None]:
    def edit(cols: dict[str, list[float]]) -> None:
        cols["time_s"] = [t + by_s if k >= i else t for k, t in enumerate(cols["time_s"])]

    return edit


def _chainage_jump(i: int, jump_m: float) -> Callable[[dict[str, list[float]]], None]:
    """Speed replaced by an odometer chainage that jumps ``jump_m`` at sample ``i``."""

    def edit(cols: dict[str, list[float]]) -> None:
        t, v = np.asarray(cols["time_s"]), np.asarray(cols.pop("speed_mps"))
        c = 12.0 + np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))))
        c[i:] += jump_m
        cols["chainage_m"] = c.tolist()

    return edit


def _csv_of(cols: dict[str, list[float]]) -> bytes:
    names = list(cols)
    rows = zip(*(cols[n] for n in names), strict=True)
    return _csv([",".join(names), *(",".join(f"{x:.8f}" for x in r) for r in rows)])


# -- requests --------------------------------------------------------------------------------
FORM = {"track": "T", "start_chainage_m": "12"}


def multipart(
    data: bytes | Callable[[bytes], bytes], filename: str = "run.csv", **fields: Any
) -> Callable[[bytes], dict[str, Any]]:
    """A multipart upload of ``data`` (or ``data(base)``) with the usual form fields, changed
    by ``fields`` (None removes a field)."""

    def build(base: bytes) -> dict[str, Any]:
        content = data(base) if callable(data) else data
        form = {k: v for k, v in (FORM | fields).items() if v is not None}
        return {"files": {"file": (filename, content, "text/csv")}, "data": form}

    return build


def json_body(
    make: Callable[[bytes], Any], headers: dict[str, str] | None = None
) -> Callable[[bytes], dict[str, Any]]:
    """A JSON body: ``make(base)`` is serialised unless it is already bytes."""

    def build(base: bytes) -> dict[str, Any]:
        body = make(base)
        content = body if isinstance(body, bytes) else json.dumps(body).encode()
        all_headers = {"content-type": "application/json", **(headers or {})}
        return {"content": content, "headers": all_headers}

    return build


def raw(content: bytes, content_type: str | None) -> Callable[[bytes], dict[str, Any]]:
    """A request body sent as is, with that content type (None: no Content-Type header)."""
    headers = {} if content_type is None else {"content-type": content_type}
    return lambda _base: {"content": content, "headers": headers}


@dataclass(frozen=True)
class Bad:
    """One bad request, its expected status, the detail's facts and the message's words."""

    request: Callable[[bytes], dict[str, Any]]
    status: int = 422
    facts: dict[str, Any] = field(default_factory=dict)
    words: tuple[str, ...] = ()
    path: str = "/api/v1/runs"
    settings: dict[str, Any] = field(default_factory=dict)


def _meta(**extra: Any) -> Callable[[bytes], dict[str, Any]]:
    return lambda base: {"track": "T", "start_chainage_m": 12, "csv": base.decode(), **extra}


CATALOGUE: dict[str, Bad] = {
    # -- the file: structure ----------------------------------------------------------------
    "empty file": Bad(multipart(b""), facts={"field": "file"}, words=("empty",)),
    "blank lines only": Bad(multipart(b"\n  \r\n\n"), facts={"field": "file"}, words=("empty",)),
    "header only": Bad(
        multipart((HEADER + "\n").encode()), facts={"row": 1}, words=("no data rows",)
    ),
    "missing pitch-rate column": Bad(
        multipart(lambda b: _drop_column(b, 2)),
        facts={"row": 1},
        words=("no pitch rate column", "pitch_rate_column"),
    ),
    "missing speed and chainage columns": Bad(
        multipart(lambda b: _drop_column(b, 3)),
        facts={"row": 1},
        words=("no speed or chainage column",),
    ),
    "duplicated column": Bad(
        multipart(
            lambda b: _csv(["time_s,accel_z_mps2,pitch_rate_radps,accel_z_mps2", *_lines(b)[1:]])
        ),
        facts={"column": "accel_z_mps2", "row": 1},
        words=("twice",),
    ),
    "no header line": Bad(
        multipart(lambda b: _csv(_lines(b)[1:])), facts={"row": 1}, words=("header line",)
    ),
    "wrong delimiter": Bad(
        multipart(lambda b: _csv([ln.replace(",", "|") for ln in _lines(b)])),
        words=("single column", "'|'"),
    ),
    "decimal comma": Bad(
        multipart(lambda b: _csv([ln.replace(",", ";").replace(".", ",") for ln in _lines(b)])),
        facts={"row": 2},
        words=("decimal comma",),
    ),
    "wrong number of fields": Bad(
        multipart(lambda b: _edit(b, 33, 3, "25,5")), facts={"row": 33}, words=("5 fields",)
    ),
    "binary file": Bad(multipart(b"\x00\x01\x02\x03garbage\x00"), words=("binary",)),
    "xlsx workbook": Bad(multipart(b"PK\x03\x04\x14\x00\x06\x00" + b"x" * 50), words=("zip",)),
    "corrupt gzip": Bad(
        multipart(lambda b: gzip.compress(b)[:40], "run.csv.gz"), words=("gzip", "corrupt")
    ),
    # -- the file: values -------------------------------------------------------------------
    "text in a number": Bad(
        multipart(lambda b: _edit(b, 58, 1, "abc")),
        facts={"column": "accel_z_mps2", "row": 58},
        words=("'abc'", "not a number", "line 58"),
    ),
    "empty field": Bad(
        multipart(lambda b: _edit(b, 120, 2, "")),
        facts={"column": "pitch_rate_radps", "row": 120},
        words=("empty",),
    ),
    "NaN": Bad(
        multipart(lambda b: _edit(b, 58, 1, "nan")),
        facts={"column": "accel_z_mps2", "row": 58},
        words=("finite",),
    ),
    "infinity": Bad(
        multipart(lambda b: _edit(b, 300, 3, "inf")),
        facts={"column": "speed_mps", "row": 300},
        words=("finite",),
    ),
    "date-times in the time column": Bad(
        multipart(lambda b: _edit(b, 2, 0, "2025-11-22T10:00:00")),
        facts={"column": "time_s", "row": 2},
        words=("not a number",),
    ),
    # -- the file: time base ----------------------------------------------------------------
    "time going backwards": Bad(
        multipart(lambda b: _edit(b, 58, 0, "0.01")),
        facts={"column": "time_s", "row": 58},
        words=("backwards", "strictly increasing"),
    ),
    "duplicated time": Bad(
        multipart(lambda b: _edit(b, 58, 0, "0.055")),
        facts={"column": "time_s", "row": 58},
        words=("duplicated time",),
    ),
    "irregular sampling": Bad(
        multipart(lambda b: _edit(b, 58, 0, "0.0562")),
        facts={"column": "time_s", "row": 58},
        words=("irregular sampling", "expected"),
    ),
    "gap in the time": Bad(
        multipart(lambda b: _csv(_lines(b)[:100] + _lines(b)[103:])),
        facts={"column": "time_s", "row": 101},
        words=("gap", "0.004 s"),
    ),
    "time in ms without a unit": Bad(
        multipart(
            lambda b: _csv(
                ["time,accel_z_mps2,pitch_rate_radps,speed_mps"]
                + [f"{i}," + ",".join(ln.split(",")[1:]) for i, ln in enumerate(_lines(b)[1:])]
            )
        ),
        words=("1 Hz", "time_unit"),
    ),
    # -- the file: units --------------------------------------------------------------------
    "absurd acceleration (1e6)": Bad(
        multipart(lambda b: _edit(b, 58, 1, "1e6")),
        facts={"column": "accel_z_mps2", "row": 58},
        words=("m/s²", "unit"),
    ),
    "whole acceleration column 1e6 too large": Bad(
        multipart(
            lambda b: _csv(
                _lines(b)[:1]
                + [
                    ",".join([p[0], f"{float(p[1]) * 1e6:.6g}", *p[2:]])
                    for p in (ln.split(",") for ln in _lines(b)[1:])
                ]
            )
        ),
        facts={"row": 2},
        words=("'accel_z_mps2'", "unit"),
    ),
    "pitch rate in deg/s read as rad/s": Bad(
        multipart(lambda b: _edit(b, 90, 2, "57.3")),
        facts={"column": "pitch_rate_radps", "row": 90},
        words=("pitch_rate_unit='deg/s'",),
    ),
    "speed in km/h read as m/s": Bad(
        multipart(lambda b: _edit(b, 77, 3, "200")),
        facts={"row": 77},
        words=("200 m/s", "speed_unit='km/h'"),
    ),
    "unsupported unit in the header": Bad(
        multipart(
            lambda b: _csv(["time_s,accel_z_mps2,pitch_rate_radps,speed_mph", *_lines(b)[1:]])
        ),
        words=("'mph'", "not supported"),
    ),
    # -- cannot be inverted (the engine's pre-flight, before anything is stored) -------------
    "too few samples to read": Bad(
        multipart(lambda b: _csv(_lines(b)[:151])), words=("150 samples", "too short")
    ),
    "too short a distance to invert": Bad(
        multipart(lambda b: _csv(_lines(b)[:2001])),
        facts={"kind": "InversionError"},
        words=("covers 50.0 m", "at least 80 m"),
    ),
    "too slow to invert": Bad(
        multipart(_constant_log(3000, 1000.0, 0.8)),
        facts={"kind": "InversionError"},
        words=("0.80 m/s", "1.0 m/s"),
    ),
    "too coarsely sampled to invert": Bad(
        multipart(_constant_log(600, 25.0, 25.0)),
        facts={"kind": "InversionError"},
        words=("25 Hz", "cannot resolve", "3.0 m"),
    ),
    # -- request fields -----------------------------------------------------------------------
    "no start chainage": Bad(
        multipart(lambda b: b, start_chainage_m=None), facts={"field": "start_chainage_m"}
    ),
    "start chainage not a number": Bad(
        multipart(lambda b: b, start_chainage_m="ten"), facts={"field": "start_chainage_m"}
    ),
    "start chainage infinite": Bad(
        multipart(lambda b: b, start_chainage_m="inf"), facts={"field": "start_chainage_m"}
    ),
    "no track": Bad(multipart(lambda b: b, track=None), words=("track",)),
    "track and track id both": Bad(
        multipart(lambda b: b, track_id="1"), words=("either track", "track_id")
    ),
    "unknown track id": Bad(
        multipart(lambda b: b, track=None, track_id="77"),
        facts={"field": "track_id"},
        words=("77", "does not exist"),
    ),
    "unknown vehicle": Bad(
        multipart(lambda b: b, vehicle="tgv"), facts={"field": "vehicle"}, words=("'tgv'", "table1")
    ),
    "unknown vehicle id": Bad(
        multipart(lambda b: b, vehicle_id="99"), facts={"field": "vehicle_id"}, words=("99",)
    ),
    "bad direction": Bad(multipart(lambda b: b, direction="up"), facts={"field": "direction"}),
    "bad recorded_at": Bad(
        multipart(lambda b: b, recorded_at="yesterday"), facts={"field": "recorded_at"}
    ),
    "unknown form field": Bad(multipart(lambda b: b, colour="red"), facts={"field": "colour"}),
    "new track named by digits only": Bad(
        multipart(lambda b: b, track="4011"), facts={"field": "track"}, words=("'line 4011'",)
    ),
    # -- column/unit options ---------------------------------------------------------------
    "unsupported speed unit option": Bad(
        multipart(lambda b: b, speed_unit="mph"), facts={"field": "speed_unit"}, words=("mph",)
    ),
    "unknown time unit option": Bad(
        multipart(lambda b: b, time_unit="minutes"),
        facts={"field": "time_unit"},
        words=("minutes",),
    ),
    "bad gravity option": Bad(
        multipart(lambda b: b, gravity="sometimes"),
        facts={"field": "gravity"},
        words=("sometimes",),
    ),
    "column option naming no column": Bad(
        multipart(lambda b: b, accel_column="az"), words=("'az'", "accel_z_mps2")
    ),
    "too long an option value": Bad(
        multipart(lambda b: b, time_column="t" * 300), facts={"field": "time_column"}
    ),
    "wait is not a boolean": Bad(
        lambda b: {**multipart(b)(b), "params": {"wait": "maybe"}}, facts={"field": "wait"}
    ),
    "Idempotency-Key too long": Bad(
        lambda b: {**multipart(b)(b), "headers": {"Idempotency-Key": "k" * 300}},
        facts={"field": "Idempotency-Key"},
    ),
    # -- the multipart body itself ----------------------------------------------------------
    "no file part": Bad(
        lambda _b: {"data": {"track": "T"}, "files": {"other": ("x", b"1")}},
        facts={"field": "file"},
    ),
    "file sent as a text field": Bad(
        lambda _b: {
            "content": b'--x\r\nContent-Disposition: form-data; name="file"\r\n\r\nnot a file'
            b"\r\n--x--\r\n",
            "headers": {"content-type": "multipart/form-data; boundary=x"},
        },
        facts={"field": "file"},
    ),
    "two files": Bad(
        lambda b: {"files": [("file", ("a.csv", b)), ("file", ("b.csv", b))], "data": FORM},
        status=400,
        words=("files",),
    ),
    "over the size limit (Content-Length)": Bad(
        multipart(lambda b: b),
        status=413,
        facts={"limit_bytes": 50_000},
        words=("limit", "TRACKPROFILE_MAX_UPLOAD_MB"),
        settings={"max_upload_mb": 0.05},
    ),
    "gzip expanding over the size limit": Bad(
        multipart(gzip.compress(b"0" * 1_000_000), "bomb.csv.gz"),
        status=413,
        facts={"field": "file", "limit_bytes": 100_000},
        words=("expands to more than", "TRACKPROFILE_MAX_UPLOAD_MB"),
        settings={"max_upload_mb": 0.1},
    ),
    "over the size limit (chunked, no length)": Bad(
        lambda b: {
            "content": iter(
                [json.dumps(_meta()(b)).encode()[i : i + 8192] for i in range(0, 250_000, 8192)]
            ),
            "headers": {"content-type": "application/json"},
        },
        status=413,
        words=("limit",),
        settings={"max_upload_mb": 0.05},
    ),
    # -- content types and JSON ---------------------------------------------------------------
    "CSV sent as text/csv": Bad(
        raw(b"time_s,accel\n0,1\n", "text/csv"), status=415, facts={"field": "Content-Type"}
    ),
    "no content type": Bad(raw(b"abc", None), status=415, facts={"field": "Content-Type"}),
    "invalid JSON": Bad(raw(b"{not json", "application/json"), status=400, words=("JSON",)),
    "empty JSON body": Bad(raw(b"", "application/json"), status=400, words=("empty",)),
    "JSON array instead of an object": Bad(raw(b"[1, 2, 3]", "application/json")),
    "JSON without csv or columns": Bad(
        json_body(lambda _b: {"track": "T", "start_chainage_m": 1}), words=("csv", "columns")
    ),
    "JSON with both csv and columns": Bad(
        json_body(lambda b: {**_meta()(b), "columns": _columns(b)}), words=("exactly one",)
    ),
    "JSON csv of the wrong type": Bad(
        json_body(lambda _b: {"track": "T", "start_chainage_m": 1, "csv": 5}),
        facts={"field": "csv"},
    ),
    "JSON column of text": Bad(
        json_body(lambda b: {**_meta(csv=None)(b), "columns": {**_columns(b), "time_s": "abc"}}),
        facts={"field": "columns.time_s"},
    ),
    "JSON columns of unequal length": Bad(
        json_body(
            lambda b: {
                **_meta(csv=None)(b),
                "columns": {**_columns(b), "accel_z_mps2": _columns(b)["accel_z_mps2"][:-5]},
            }
        ),
        words=("accel_z_mps2",),
    ),
    "JSON column with time going backwards": Bad(
        json_body(
            lambda b: {
                **_meta(csv=None)(b),
                "columns": {
                    **_columns(b),
                    "time_s": [t if i != 56 else 0.01 for i, t in enumerate(_columns(b)["time_s"])],
                },
            }
        ),
        facts={"column": "time_s", "row": 58},
    ),
    "JSON column with NaN": Bad(
        json_body(
            lambda b: json.dumps(
                {
                    **_meta(csv=None)(b),
                    "columns": {
                        **_columns(b),
                        "accel_z_mps2": [float("nan")] + _columns(b)["accel_z_mps2"][1:],
                    },
                }
            ).encode()
        ),
        words=("accel_z_mps2",),
    ),
    "JSON csv text with a bad number": Bad(
        json_body(lambda b: _meta()(_edit(b, 58, 1, "abc"))),
        facts={"field": "csv", "column": "accel_z_mps2", "row": 58},
    ),
    "JSON with an unknown key": Bad(
        json_body(lambda b: {**_meta()(b), "colour": "red"}), facts={"field": "colour"}
    ),
    "JSON with options for columns": Bad(
        json_body(lambda b: {**_meta(csv=None)(b), "columns": _columns(b), "accel_unit": "g"}),
        words=("options apply to csv only",),
    ),
    # -- the same plausibility on every path (issue 16): JSON columns, CSV chainage ---------
    "JSON columns with a 100 s gap in time": Bad(
        json_body(lambda b: _json_columns(b, _shift_time(99, 100.0))),
        facts={"column": "time_s", "row": 101, "kind": "LogFormatError", "field": "columns"},
        words=("gap", "without gaps"),
    ),
    # -- JSON columns read without a Python object per number (issue 16) -----------------
    "JSON column item that is not a JSON number": Bad(
        json_body(_json_replace('"accel_z_mps2": [', '"accel_z_mps2": [.5, ')),
        facts={"field": "columns.accel_z_mps2", "column": "accel_z_mps2", "row": 2},
        words=("'.5'", "not a JSON number"),
    ),
    "JSON column array ending in a comma": Bad(
        json_body(_json_replace("]", ",]")),
        facts={"column": "time_s", "row": 5357}, words=("empty",),
    ),
    "JSON column given twice": Bad(
        json_body(_json_replace('"time_s": [', '"time_s": [1, 2], "time_s": [')),
        facts={"field": "columns.time_s"}, words=("twice",),
    ),
    "JSON columns of nulls beyond the body limit": Bad(
        json_body(lambda _b: _json_text_of({"track": "T", "start_chainage_m": 12, "columns": {
            "time_s": [None] * 2000, "accel_z_mps2": [0.0], "pitch_rate_radps": [0.0]}})),
        status=413, facts={"field": "columns", "limit_bytes": 5000}, words=("plain JSON numbers",),
        settings={"max_body_kb": 5},
    ),
    "JSON columns with the gap of the CSV case": Bad(
        json_body(lambda b: _json_columns(b, _shift_time(99, 0.003))),
        facts={"column": "time_s", "row": 101},
        words=("gap", "0.004 s"),
    ),
    "JSON acceleration of 1e308": Bad(
        json_body(lambda b: _json_columns(b, _set("accel_z_mps2", 56, 1e308))),
        facts={"column": "accel_z_mps2", "row": 58, "kind": "LogFormatError"},
        words=("m/s²", "50 m/s²"),
    ),
    "JSON pitch rate of 7 rad/s": Bad(
        json_body(lambda b: _json_columns(b, _set("pitch_rate_radps", 88, 7.0))),
        facts={"column": "pitch_rate_radps", "row": 90},
        words=("rad/s",),
    ),
    "JSON speed of 1e308": Bad(
        json_body(lambda b: _json_columns(b, _set("speed_mps", 75, 1e308))),
        facts={"column": "speed_mps", "row": 77},
        words=("m/s", "150 m/s"),
    ),
    "JSON speed of zero": Bad(
        json_body(lambda b: _json_columns(b, _set("speed_mps", 75, 0.0))),
        facts={"column": "speed_mps", "row": 77},
        words=("standstill",),
    ),
    "JSON chainage jumping 1e6 m": Bad(
        json_body(lambda b: _json_columns(b, _chainage_jump(200, 1e6))),
        facts={"column": "chainage_m", "row": 202, "kind": "LogFormatError"},
        words=("jumps", "150 m/s"),
    ),
    "CSV chainage column jumping 2000 m": Bad(
        multipart(lambda b: _csv_of(_json_columns(b, _chainage_jump(200, 2000.0))["columns"])),
        facts={"column": "chainage_m", "row": 202, "field": "file"},
        words=("jumps", "150 m/s"),
    ),
    "JSON csv text with a chainage jump": Bad(
        json_body(lambda b: _meta()(_csv_of(_json_columns(b, _chainage_jump(200, 2000.0))
                                             ["columns"]))),
        facts={"column": "chainage_m", "row": 202, "field": "csv"},
        words=("jumps",),
    ),
    # -- the simulate path --------------------------------------------------------------------
    "simulate faster than the schema allows": Bad(
        json_body(lambda _b: {"speed_mps": 1e308}), facts={"field": "speed_mps"},
        path="/api/v1/simulate",
    ),
    "simulate a zone beyond the track": Bad(
        json_body(lambda _b: {"length_m": 200, "zones": ["150:250:0.5"]}),
        facts={"field": "zones.0.end_m"}, path="/api/v1/simulate",
    ),
    "simulate with an unknown vehicle": Bad(
        json_body(lambda _b: {"vehicle": "tgv"}), facts={"field": "vehicle"},
        path="/api/v1/simulate",
    ),
    "simulate a run too long": Bad(
        json_body(lambda _b: {"length_m": 5000, "speed_mps": 5}), facts={"field": "length_m"},
        path="/api/v1/simulate",
    ),
    "simulate sensor noise beyond the schema": Bad(
        json_body(lambda _b: {"sensor": {"accel_noise": 1e308}}),
        facts={"field": "sensor.SensorSpec.accel_noise"}, path="/api/v1/simulate",
    ),
    # -- vehicles and tracks ----------------------------------------------------------------
    "negative vehicle mass": Bad(
        json_body(lambda _b: {"name": "v", "params": {"ms": -16200}}),
        facts={"field": "params.ms"},
        words=("greater than or equal to 500",),
        path="/api/v1/vehicles",
    ),
    "negative vehicle mass, flat (inline) form": Bad(
        json_body(lambda _b: {"name": "v", "ms": -16200}),
        facts={"field": "params.ms"},
        words=("greater than or equal to 500",),
        path="/api/v1/vehicles",
    ),
    "vehicle parameter of the wrong type": Bad(
        json_body(lambda _b: {"name": "v", "params": {"kt1": "stiff"}}),
        facts={"field": "params.kt1"},
        path="/api/v1/vehicles",
    ),
    "vehicle body of the wrong shape": Bad(
        json_body(lambda _b: ["v", 16200]), path="/api/v1/vehicles"
    ),
    "negative support stiffness": Bad(
        json_body(lambda _b: {"name": "L", "k_nominal": -1}),
        facts={"field": "k_nominal"},
        path="/api/v1/tracks",
    ),
}  # fmt: skip


@pytest.fixture(scope="module")
def base_log(synthetic_run: dict[str, Any]) -> bytes:
    """The good log every case is made from (5355 samples, 1 kHz, 25 m/s, 134 m)."""
    return synthetic_run["csv"]


def test_catalogue_is_large_enough() -> None:
    """The issue asks for at least 25 malformed uploads."""
    assert len(CATALOGUE) >= 25


def test_the_unmodified_log_is_accepted(client, base_log) -> None:
    """Control: the log the cases are made from is stored (201), so every refusal below is
    due to its defect alone."""
    r = client.post("/api/v1/runs", **multipart(base_log)(base_log))
    assert r.status_code == 201, r.text
    assert r.json()["n_samples"] == 5355


@pytest.mark.parametrize("case", list(CATALOGUE))
def test_bad_input_is_refused_clearly_and_stores_nothing(start_app, settings, base_log, case):
    """The case is answered with its 4xx (never 5xx); the detail names the problem (its
    facts: field, column, row, kind) and the message says what is wrong; every table of the
    database keeps its row count."""
    bad = CATALOGUE[case]
    c = start_app(**bad.settings)
    before = row_counts(settings)
    r = c.post(bad.path, **bad.request(base_log))
    assert r.status_code == bad.status, r.text
    detail = r.json()["detail"]
    message = detail["message"]
    assert isinstance(message, str) and len(message) >= 15, detail
    for key, value in bad.facts.items():
        assert detail.get(key) == value, f"{key}: {detail}"
    for word in bad.words:
        assert word.lower() in message.lower(), f"{word!r} missing from {message!r}"
    assert row_counts(settings) == before


QUEUED_CASES = [
    "too short a distance to invert", "too slow to invert", "too coarsely sampled to invert",
]  # fmt: skip


@pytest.mark.parametrize("case", QUEUED_CASES)
def test_log_that_cannot_be_inverted_is_refused_even_when_it_would_be_queued(
    start_app, settings, base_log, case
) -> None:
    """With every log going to the background worker (inline limit 0), a log the engine's
    pre-flight rejects is still answered 422 at once with the engine's reason, and nothing is
    queued."""
    bad = CATALOGUE[case]
    c = start_app(inline_max_samples=0)
    before = row_counts(settings)
    r = c.post(bad.path, **bad.request(base_log))
    assert r.status_code == 422, r.text
    assert r.json()["detail"]["kind"] == "InversionError"
    assert row_counts(settings) == before
    assert c.get("/api/v1/runs").json()["count"] == 0


ACCEPTED: dict[str, Callable[[bytes], bytes]] = {
    "UTF-8 BOM": lambda b: b"\xef\xbb\xbf" + b,
    "Windows line ends (CRLF)": lambda b: _csv(_lines(b), "\r\n"),
    "gzip-compressed": lambda b: gzip.compress(b),
    "gzip + BOM + CRLF": lambda b: gzip.compress(b"\xef\xbb\xbf" + _csv(_lines(b), "\r\n")),
    "semicolon delimiter": lambda b: b.replace(b",", b";"),
}


@pytest.mark.parametrize("variant", list(ACCEPTED))
def test_harmless_format_variants_are_accepted(client, synthetic_run, base_log, variant) -> None:
    """BOM, Windows line ends, gzip (and all three) and semicolons are read like the plain
    file: stored (201) with every sample and the true soft zone found."""
    r = upload(client, ACCEPTED[variant](base_log), "run.csv", **FORM)
    assert r.status_code == 201, r.text
    assert r.json()["n_samples"] == 5355
    spots = client.get(f"/api/v1/runs/{r.json()['id']}/soft-spots").json()
    assert_zones_match(spots, synthetic_run["zones"])


def test_windows_line_ends_in_json_csv_are_accepted(client, synthetic_run, base_log) -> None:
    """CSV text with CRLF inside a JSON body is read like the plain file."""
    body = _meta()(_csv(_lines(base_log), "\r\n"))
    r = client.post("/api/v1/runs", json=body)
    assert r.status_code == 201, r.text
    assert r.json()["n_samples"] == 5355


def test_gzip_limit_counts_what_the_reader_reads(start_app, settings, base_log) -> None:
    """A gzip upload is limited by the bytes it decompresses to, whatever its members: two
    members with a zero byte between them (Python's reader skips the padding, the probe's
    size check stopped at it: 26 MB accepted under 10 MB) are 413 naming the limit."""
    c = start_app(max_upload_mb=1)
    member = gzip.compress(b"0" * 900_000)
    before = row_counts(settings)
    for data in (member + b"\x00" + member, member + b"\x00" * 7 + member, member * 2):
        r = upload(c, data, "run.csv.gz", **FORM)
        assert r.status_code == 413, r.text
        assert r.json()["detail"]["limit_bytes"] == 1_000_000
    assert row_counts(settings) == before
    r = upload(c, gzip.compress(base_log[: len(base_log) // 2]) + b"\x00\x00"
               + gzip.compress(base_log[len(base_log) // 2 :]), "run.csv.gz", **FORM)  # fmt: skip
    assert r.status_code == 201, r.text  # padding between members is harmless under the limit
