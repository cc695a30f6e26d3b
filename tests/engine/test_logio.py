"""Reading logger CSVs into RunLogs (engine.logio): formats, units, and every bad file we refuse.

The catalogue test (``test_bad_file_is_refused_with_a_precise_message``) holds the file-content
cases of issue 7: each must raise LogFormatError whose message names what is wrong (column,
line, unit or expected value) and whose ``row`` is the offending file line (header = line 1).
"""

from __future__ import annotations

import dataclasses
import gzip
import io
import json
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest

from engine import logio
from engine.errors import LogFormatError, ParameterError
from engine.logio import (
    MIN_SAMPLES,
    CsvOptions,
    parse_run_csv,
    preview_csv,
    read_run_csv,
    write_run_csv,
)
from engine.runlog import RunLog
from engine.vehicle import GRAVITY
from support.samples import shared_data_dir

HEADER = "time_s,accel_z_mps2,pitch_rate_radps,speed_mps"
N = 400


def _signals(n: int = N) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(7)
    return {
        "t": np.arange(n) * 1e-3,
        "a": 0.05 * rng.standard_normal(n),
        "w": 1e-3 * rng.standard_normal(n),
        "v": np.full(n, 20.0),
    }


def _lines(header: str = HEADER, cols: list[np.ndarray] | None = None, d: str = ",") -> list[str]:
    """CSV lines (header first) of the synthetic run, 8 significant digits like a logger."""
    s = _signals()
    cols = cols if cols is not None else [s["t"], s["a"], s["w"], s["v"]]
    return [header] + [d.join(f"{x:.8g}" for x in row) for row in zip(*cols, strict=True)]


def _repr_lines(header: str, cols: list[np.ndarray]) -> list[str]:
    """CSV lines written at full precision (shortest round-trip text)."""
    return [header] + [",".join(repr(float(x)) for x in row) for row in zip(*cols, strict=True)]


def _csv(lines: list[str], newline: str = "\n") -> bytes:
    return (newline.join(lines) + newline).encode()


def _edit(line: int, col: int, value: str, lines: list[str] | None = None) -> bytes:
    """The base file with field ``col`` (0-based) of file line ``line`` (1-based) replaced."""
    ls = list(lines or _lines())
    f = ls[line - 1].split(",")
    f[col] = value
    ls[line - 1] = ",".join(f)
    return _csv(ls)


BASE = _csv(_lines())


@pytest.fixture(scope="module")
def base_log() -> RunLog:
    return read_run_csv(BASE)


def _assert_same_log(got: RunLog, want: RunLog, atol_t: float = 0.0, atol: float = 0.0) -> None:
    assert got.n == want.n
    np.testing.assert_allclose(got.time_s, want.time_s, rtol=0, atol=atol_t)
    np.testing.assert_allclose(got.accel_z_mps2, want.accel_z_mps2, rtol=0, atol=atol)
    np.testing.assert_allclose(got.pitch_rate_radps, want.pitch_rate_radps, rtol=0, atol=atol)
    assert (got.speed_mps is None) == (want.speed_mps is None)
    if want.speed_mps is not None:
        np.testing.assert_allclose(got.speed_mps, want.speed_mps, rtol=1e-14, atol=atol)


# ---------------------------------------------------------------------------------------------
# The shared sample runs
# ---------------------------------------------------------------------------------------------


def _sample_path(name: str) -> Path:
    d = shared_data_dir()
    if d is None or not (d / f"{name}.csv").exists():
        pytest.skip(f"shared sample {name} not available (set SHARED_DIR)")
    return d / f"{name}.csv"


@pytest.mark.parametrize(
    ("name", "rows", "speed"), [("sample_clean_exact", 4071, 25.0), ("sample_noisy", 20534, 22.0)]
)
def test_sample_runs_load_with_every_value_exact(name: str, rows: int, speed: float) -> None:
    """Both shared samples load to their full length, 1 kHz, values bit-identical to the file."""
    path = _sample_path(name)
    ref = np.loadtxt(path, delimiter=",", skiprows=1)
    parsed = parse_run_csv(path)
    log = parsed.log
    assert log.n == rows == ref.shape[0]
    assert log.sample_rate_hz == pytest.approx(1000.0, rel=1e-9)
    np.testing.assert_array_equal(log.time_s, ref[:, 0])
    np.testing.assert_array_equal(log.accel_z_mps2, ref[:, 1])
    np.testing.assert_array_equal(log.pitch_rate_radps, ref[:, 2])
    assert log.speed_mps is not None
    np.testing.assert_array_equal(log.speed_mps, ref[:, 3])
    assert log.speed_mps[0] == speed
    assert log.chainage_m is None
    assert parsed.gravity == "removed"
    assert parsed.units == {
        "time": "s", "accel": "m/s2", "pitch_rate": "rad/s", "speed": "m/s", "chainage": None,
        "wheel_load": None,
        "lat": None, "lon": None,
    }  # fmt: skip


def _raw_imu_bytes(ref: np.ndarray) -> bytes:
    """A canonical run as a logger writes it: epoch s, g incl. gravity, deg/s, km/h."""
    cols = [
        1763800000.0 + ref[:, 0],
        (ref[:, 1] + GRAVITY) / GRAVITY,
        np.rad2deg(ref[:, 2]),
        ref[:, 3] * 3.6,
    ]
    return _csv(_repr_lines("timestamp,az_g,gyro_y_dps,speed_kmh", cols))


@pytest.fixture(scope="module")
def noisy_canonical(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A realistic canonical run (simulated 120 m at 22 m/s, 1 kHz, sensor noise and bias)
    written as CSV at full precision: the reference of the raw-format tests, in every clone."""
    from engine.synthetic import REALISTIC_SENSOR, make_run

    run = make_run(length=120.0, sensor=REALISTIC_SENSOR, speed=22.0, seed=5)
    path = tmp_path_factory.mktemp("canonical") / "noisy.csv"
    write_run_csv(run.log, path)
    return path


def test_raw_imu_log_gives_the_canonical_run(noisy_canonical: Path) -> None:
    """A raw IMU log (epoch s, g with gravity, deg/s, km/h) of a noisy run is recognised by its
    names and values alone and reads to the canonical RunLog within float rounding."""
    path = noisy_canonical
    ref = np.loadtxt(path, delimiter=",", skiprows=1)
    canonical = read_run_csv(path)
    parsed = parse_run_csv(_raw_imu_bytes(ref))
    assert parsed.columns == {
        "time": "timestamp", "accel": "az_g", "pitch_rate": "gyro_y_dps",
        "speed": "speed_kmh", "chainage": None, "wheel_load": None,
        "lat": None, "lon": None,
    }  # fmt: skip
    assert parsed.units == {
        "time": "epoch_s", "accel": "g", "pitch_rate": "deg/s", "speed": "km/h", "chainage": None,
        "wheel_load": None,
        "lat": None, "lon": None,
    }  # fmt: skip
    assert parsed.gravity == "included"
    # epoch seconds near 1.8e9 carry float64 steps of 2.4e-7 s; everything else is exact-ish
    _assert_same_log(parsed.log, canonical, atol_t=5e-7, atol=1e-13)


def test_raw_imu_log_with_explicit_options_and_unhelpful_names(noisy_canonical: Path) -> None:
    """Columns named c1..c4 read right when CsvOptions names columns, units and gravity."""
    path = noisy_canonical
    ref = np.loadtxt(path, delimiter=",", skiprows=1)
    data = _raw_imu_bytes(ref).replace(b"timestamp,az_g,gyro_y_dps,speed_kmh", b"c1,c2,c3,c4")
    with pytest.raises(LogFormatError, match="no time column"):
        read_run_csv(data)
    opts = CsvOptions(
        time_column="c1", accel_column="c2", pitch_rate_column="c3", speed_column="c4",
        time_unit="epoch_s", accel_unit="g", pitch_rate_unit="deg/s", speed_unit="km/h",
        gravity="included",
    )  # fmt: skip
    _assert_same_log(read_run_csv(data, opts), read_run_csv(path), atol_t=5e-7, atol=1e-13)


# ---------------------------------------------------------------------------------------------
# Issue 7's catalogue of malformed content
# ---------------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Bad:
    """A malformed file, the fragments its error message must contain, and its ``.row``."""

    data: Callable[[], bytes]
    fragments: tuple[str, ...]
    row: int | None = None
    column: str | None = None


def _drop_column(k: int) -> bytes:
    return _csv([",".join(f for i, f in enumerate(ln.split(",")) if i != k) for ln in _lines()])


def _with_extra_column(name: str, src_col: int) -> bytes:
    ls = _lines()
    return _csv([ls[0] + "," + name] + [ln + "," + ln.split(",")[src_col] for ln in ls[1:]])


def _gzip_bytes() -> bytes:
    return gzip.compress(BASE)


CATALOGUE: dict[str, Bad] = {
    "empty file": Bad(lambda: b"", ("empty",)),
    "blank lines only": Bad(lambda: b"\n  \r\n\n", ("empty",)),
    "header only": Bad(lambda: (HEADER + "\n").encode(), ("header", "no data rows"), row=1),
    "missing pitch-rate column": Bad(
        lambda: _drop_column(2),
        (
            "no pitch rate column",
            "'time_s', 'accel_z_mps2', 'speed_mps'",
            "gyro_y_dps",
            "pitch_rate_column",
        ),
        row=1,
    ),  # fmt: skip
    "missing speed and chainage": Bad(
        lambda: _drop_column(3),
        ("no speed or chainage column", "speed_kmh", "chainage_m"),
        row=1,
    ),
    "duplicated column": Bad(
        lambda: _csv(_lines("time_s,accel_z_mps2,pitch_rate_radps,accel_z_mps2")),
        ("'accel_z_mps2'", "twice", "columns 2 and 4"),
        row=1,
        column="accel_z_mps2",
    ),
    "text in a number": Bad(
        lambda: _edit(58, 1, "abc"),
        ("'accel_z_mps2'", "line 58", "'abc'", "not a number"),
        row=58,
        column="accel_z_mps2",
    ),
    "empty field": Bad(
        lambda: _edit(120, 2, ""),
        ("'pitch_rate_radps'", "empty", "line 120"),
        row=120,
        column="pitch_rate_radps",
    ),
    "NaN": Bad(
        lambda: _edit(58, 1, "nan"),
        ("'accel_z_mps2'", "line 58", "nan", "finite"),
        row=58,
        column="accel_z_mps2",
    ),
    "infinity": Bad(
        lambda: _edit(300, 3, "inf"),
        ("'speed_mps'", "line 300", "inf", "finite"),
        row=300,
        column="speed_mps",
    ),
    "non-monotonic time": Bad(
        lambda: _edit(58, 0, "0.01"),
        ("time goes backwards", "'time_s'", "line 58", "line 57", "strictly increasing"),
        row=58,
        column="time_s",
    ),
    "duplicated time": Bad(
        lambda: _edit(58, 0, "0.055"),
        ("duplicated time", "'time_s'", "line 58", "0.055", "line 57"),
        row=58,
        column="time_s",
    ),
    "irregular sampling": Bad(
        lambda: _edit(58, 0, "0.0562"),
        ("irregular sampling", "'time_s'", "line 58", "0.0012 s", "expected", "0.001 s"),
        row=58,
        column="time_s",
    ),
    "gap": Bad(
        lambda: _csv(_lines()[:100] + _lines()[103:]),
        ("gap", "'time_s'", "line 101", "0.004 s", "expected", "0.001 s"),
        row=101,
        column="time_s",
    ),
    "too short to invert": Bad(
        lambda: _csv(_lines()[:151]),
        ("150 samples", "MIN_SAMPLES", "200", "too short to invert"),
    ),
    "absurd acceleration 1e6": Bad(
        lambda: _edit(58, 1, "1e6"),
        ("'accel_z_mps2'", "line 58", "1e+06 m/s²", "±50 m/s²", "unit", "accel_unit"),
        row=58,
        column="accel_z_mps2",
    ),
    "whole column in absurd units": Bad(
        lambda: _csv(
            _lines(cols=[_signals()["t"], 1e6 * _signals()["a"], _signals()["w"], _signals()["v"]])
        ),
        ("'accel_z_mps2'", "line 2", "m/s²", "unit"),
        row=2,
    ),  # fmt: skip
    "absurd pitch rate (deg/s read as rad/s)": Bad(
        lambda: _edit(90, 2, "57.3"),
        ("'pitch_rate_radps'", "line 90", "57.3 rad/s", "±5 rad/s", "pitch_rate_unit='deg/s'"),
        row=90,
        column="pitch_rate_radps",
    ),
    "wrong delimiter": Bad(
        lambda: _csv([ln.replace(",", "|") for ln in _lines()]),
        ("single column", "','", "'|'"),
    ),
    "decimal comma with semicolons": Bad(
        lambda: _csv([ln.replace(",", ";").replace(".", ",") for ln in _lines()]),
        ("decimal comma", "line 2", "decimal point"),
        row=2,
    ),
    "decimal comma with commas": Bad(
        lambda: _csv(
            _lines()[:1]
            + [ln.replace(",", ";").replace(".", ",").replace(";", ",") for ln in _lines()[1:]]
        ),
        ("line 2", "fields", "header", "decimal comma"),
        row=2,
    ),  # fmt: skip
    "ambiguous acceleration columns": Bad(
        lambda: _with_extra_column("az", 1),
        ("2 columns could be the vertical acceleration", "'accel_z_mps2'", "'az'", "accel_column"),
        row=1,
    ),  # fmt: skip
    "negative speed": Bad(
        lambda: _edit(77, 3, "-20"),
        ("'speed_mps'", "line 77", "-20 m/s", "positive"),
        row=77,
        column="speed_mps",
    ),
    "standstill": Bad(
        lambda: _edit(77, 3, "0.2"),
        ("'speed_mps'", "line 77", "0.2 m/s", "0.5 m/s"),
        row=77,
    ),
    "speed in km/h read as m/s": Bad(
        lambda: _edit(77, 3, "200"),
        ("'speed_mps'", "line 77", "200 m/s", "150 m/s", "speed_unit='km/h'"),
        row=77,
    ),
    "wrong number of fields": Bad(
        lambda: _edit(33, 3, "20,5"),
        ("line 33", "5 fields", "4 columns"),
        row=33,
    ),
    "binary file": Bad(lambda: b"\x00\x01\x02\x03garbage\x00", ("not CSV text", "binary")),
    "xlsx workbook": Bad(lambda: b"PK\x03\x04\x14\x00\x06\x00" + b"x" * 50, ("zip", "CSV")),
    "corrupt gzip": Bad(lambda: _gzip_bytes()[:40], ("gzip", "corrupt or truncated")),
    "mean acceleration neither 0 nor 1 g": Bad(
        lambda: _csv(
            _lines(cols=[_signals()["t"], _signals()["a"] + 5.0, _signals()["w"], _signals()["v"]])
        ),
        ("mean", "'accel_z_mps2'", "5 m/s²", "9.81", "unit may be wrong", "gravity"),
    ),  # fmt: skip
    "no header line (numbers first)": Bad(
        lambda: _csv(_lines()[1:]),
        ("no time column", "header line"),
        row=1,
    ),
    "unsupported unit suffix": Bad(
        lambda: _csv(_lines("time_s,accel_z_mps2,pitch_rate_radps,speed_mph")),
        ("'speed_mph'", "'mph'", "not supported", "km/h"),
    ),
    "date-times in the time column": Bad(
        lambda: _edit(2, 0, "2025-11-22T10:00:00"),
        ("'time_s'", "line 2", "not a number", "dates"),
        row=2,
    ),
    "time in ms without a unit": Bad(
        lambda: _csv(
            _lines(
                "time,accel_z_mps2,pitch_rate_radps,speed_mps",
                cols=[np.arange(N) * 1.0, _signals()["a"], _signals()["w"], _signals()["v"]],
            )
        ),
        ("'time'", "1 Hz", "time_unit"),
    ),  # fmt: skip
}


@pytest.mark.parametrize("case", list(CATALOGUE.values()), ids=list(CATALOGUE))
def test_bad_file_is_refused_with_a_precise_message(case: Bad) -> None:
    """Each malformed file raises LogFormatError naming column/line/unit, with .row set."""
    with pytest.raises(LogFormatError) as info:
        read_run_csv(case.data())
    msg = str(info.value)
    for frag in case.fragments:
        assert frag in msg, f"{frag!r} missing from: {msg}"
    if case.row is not None:
        assert info.value.row == case.row, msg
    if case.column is not None:
        assert info.value.column == case.column, msg


ACCEPTED: dict[str, Callable[[], bytes]] = {
    "UTF-8 BOM": lambda: b"\xef\xbb\xbf" + BASE,
    "Windows line ends (CRLF)": lambda: _csv(_lines(), "\r\n"),
    "old Mac line ends (CR)": lambda: _csv(_lines(), "\r"),
    "gzip-compressed": _gzip_bytes,
    "gzip + BOM + CRLF": lambda: gzip.compress(b"\xef\xbb\xbf" + _csv(_lines(), "\r\n")),
    "semicolon delimiter": lambda: _csv(_lines(HEADER.replace(",", ";"), d=";")),
    "tab delimiter": lambda: _csv(_lines(HEADER.replace(",", "\t"), d="\t")),
    "whitespace delimiter": lambda: _csv(_lines(HEADER.replace(",", "  "), d=" ")),
    "spaces after commas": lambda: _csv([ln.replace(",", ", ") for ln in _lines()]),
    "comment and blank lines": lambda: _csv(
        ["# logger v2", "#"] + _lines()[:10] + ["# pause", "", "   "] + _lines()[10:]
    ),
    "quoted header": lambda: _csv(['"' + HEADER.replace(",", '","') + '"'] + _lines()[1:]),
    "trailing delimiter everywhere": lambda: _csv([ln + "," for ln in _lines()]),
    "trailing delimiter on data lines": lambda: _csv(
        _lines()[:1] + [ln + "," for ln in _lines()[1:]]
    ),
    "trailing delimiter on the header only": lambda: _csv([_lines()[0] + ","] + _lines()[1:]),
    "unused text column": lambda: _csv(
        [_lines()[0] + ",status"] + [ln + ',"OK, 3D fix"' for ln in _lines()[1:]]
    ),
    "UTF-16 with BOM": lambda: BASE.decode().encode("utf-16"),
    "Windows-1252 header": lambda: (
        _csv(["time_s,accel_z [m/s²],pitch_rate_radps,speed_mps"] + _lines()[1:])
        .decode()
        .encode("cp1252")
    ),
}


@pytest.mark.parametrize("make", list(ACCEPTED.values()), ids=list(ACCEPTED))
def test_harmless_format_variants_read_like_the_plain_file(make, base_log: RunLog) -> None:
    """BOM, CRLF, gzip, other delimiters, comments, quotes, extra columns: same RunLog."""
    _assert_same_log(read_run_csv(make()), base_log, atol=1e-12)


def test_bom_is_not_part_of_the_first_column_name() -> None:
    """With a UTF-8 BOM the first column is still recognised as 'time_s'."""
    parsed = parse_run_csv(b"\xef\xbb\xbf" + BASE)
    assert parsed.columns["time"] == "time_s"


def test_fast_and_line_by_line_paths_read_identical_numbers() -> None:
    """A text column forces the careful line-by-line path; its floats equal the fast path's."""
    s = _signals()
    cols = [s["t"], s["a"] * 1.2345678901234567, s["w"], s["v"]]
    plain = _repr_lines(HEADER, cols)
    fast = read_run_csv(_csv(plain))
    slow = read_run_csv(_csv([plain[0] + ",note"] + [ln + ",x" for ln in plain[1:]]))
    for name in ("time_s", "accel_z_mps2", "pitch_rate_radps", "speed_mps"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(slow, name))


@pytest.mark.parametrize("path", ["fast", "careful"])
def test_line_numbers_count_comment_and_blank_lines(path: str) -> None:
    """The reported line is the file's line, comments and blank lines included, on both paths."""
    ls = ["# exported by logger", ""] + _lines()  # header is line 3, data row k is line 3 + k
    if path == "careful":
        ls = [ls[0], ls[1], ls[2] + ",note"] + [ln + ",x" for ln in ls[3:]]
    ls.insert(50, "# a comment in the middle")  # shifts later lines by one
    f = ls[60].split(",")
    f[1] = "nan"
    ls[60] = ",".join(f)
    with pytest.raises(LogFormatError) as info:
        read_run_csv(_csv(ls))
    assert info.value.row == 61
    assert "line 61" in str(info.value)


def test_min_samples_boundary() -> None:
    """MIN_SAMPLES samples are enough; one fewer is refused as too short."""
    assert read_run_csv(_csv(_lines()[: MIN_SAMPLES + 1])).n == MIN_SAMPLES
    with pytest.raises(LogFormatError, match="too short"):
        read_run_csv(_csv(_lines()[:MIN_SAMPLES]))


def test_rounding_jitter_of_written_times_passes_but_two_percent_does_not() -> None:
    """Times written with 4 decimals pass; one step 2 % off is irregular sampling."""
    ls = [HEADER] + [f"{k * 1e-3:.4f},0.01,0.0001,20" for k in range(N)]
    assert read_run_csv(_csv(ls)).sample_rate_hz == pytest.approx(1000.0)
    with pytest.raises(LogFormatError, match="irregular sampling") as info:
        read_run_csv(_edit(200, 0, f"{197e-3 + 1.02e-3:.6f}", ls))  # line 199 holds 0.197
    assert info.value.row == 200


def test_gzip_bomb_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    """A gzip file expanding beyond MAX_DECOMPRESSED_BYTES is refused, naming the limit."""
    monkeypatch.setattr(logio.source, "MAX_DECOMPRESSED_BYTES", 10_000)
    with pytest.raises(LogFormatError, match="MAX_DECOMPRESSED_BYTES"):
        read_run_csv(gzip.compress(BASE))


def test_every_kind_of_source_reads_the_same(tmp_path: Path, base_log: RunLog) -> None:
    """bytes, str path, Path, binary file object and a .gz path all give the same RunLog."""
    p = tmp_path / "run.csv"
    p.write_bytes(BASE)
    pgz = tmp_path / "run.csv.gz"
    pgz.write_bytes(gzip.compress(BASE))
    for source in (BASE, bytearray(BASE), str(p), p, io.BytesIO(BASE), pgz):
        _assert_same_log(read_run_csv(source), base_log)
    with p.open("rb") as fh:
        _assert_same_log(read_run_csv(fh), base_log)


# ---------------------------------------------------------------------------------------------
# Units, gravity, chainage
# ---------------------------------------------------------------------------------------------


def test_unit_suffixes_and_brackets_are_recognised() -> None:
    """Names like 'Acc Z (m/s^2)', 'gyroY_dps', 'v_kph', 't_ms' give the units they say."""
    s = _signals()
    cols = [s["t"] * 1e3, s["a"], np.rad2deg(s["w"]), s["v"] * 3.6]
    for header in (
        "t_ms,Acc Z (m/s^2),gyroY_dps,v_kph",
        "time [ms],acc_z_ms2,Gyro Y [°/s],Speed [km/h]",
    ):
        parsed = parse_run_csv(_csv(_repr_lines(header, cols)))
        assert parsed.units == {
            "time": "ms", "accel": "m/s2", "pitch_rate": "deg/s", "speed": "km/h",
            "chainage": None, "wheel_load": None,
            "lat": None, "lon": None,
        }, header  # fmt: skip
        log = parsed.log
        np.testing.assert_allclose(log.time_s, s["t"], rtol=0, atol=1e-15)
        np.testing.assert_allclose(log.accel_z_mps2, s["a"], rtol=0, atol=0)
        np.testing.assert_allclose(log.pitch_rate_radps, s["w"], rtol=1e-15, atol=0)
        np.testing.assert_allclose(log.speed(), s["v"], rtol=1e-15, atol=0)


def test_epoch_milliseconds_are_recognised_and_shifted_to_zero() -> None:
    """A time column of epoch milliseconds reads as seconds from 0 at the first sample."""
    s = _signals()
    data = _csv(_repr_lines("ts,az,gy,v", [1.7638e12 + s["t"] * 1e3, s["a"], s["w"], s["v"]]))
    parsed = parse_run_csv(data)
    assert parsed.units["time"] == "ms"
    assert parsed.log.time_s[0] == 0.0
    np.testing.assert_allclose(parsed.log.time_s, s["t"], atol=1e-9)
    assert any("epoch milliseconds" in n for n in parsed.notes)


def test_epoch_seconds_in_a_column_named_time_s_are_shifted_and_reported() -> None:
    """'time_s' holding epoch seconds reads as epoch_s from 0, with a note saying so."""
    s = _signals()
    data = _csv(_repr_lines(HEADER, [1.7638e9 + s["t"], s["a"], s["w"], s["v"]]))
    parsed = parse_run_csv(data)
    assert parsed.units["time"] == "epoch_s" and parsed.log.time_s[0] == 0.0
    np.testing.assert_allclose(parsed.log.time_s, s["t"], atol=5e-7)
    assert any("epoch seconds" in n for n in parsed.notes)
    explicit = read_run_csv(data, CsvOptions(time_unit="s"))  # taken literally when explicit
    assert explicit.time_s[0] == pytest.approx(1.7638e9)


def test_explicit_options_win_over_names() -> None:
    """accel_unit='m/s2' overrides the '_g' suffix; the same file read by name differs by g."""
    s = _signals()
    data = _csv(_lines("time_s,az_g,pitch_rate_radps,speed_mps"))
    by_name = read_run_csv(data)  # read as g: 9.81 times larger
    forced = read_run_csv(data, CsvOptions(accel_unit="m/s2"))
    np.testing.assert_allclose(forced.accel_z_mps2, s["a"], atol=1e-9)
    np.testing.assert_allclose(by_name.accel_z_mps2, s["a"] * GRAVITY, atol=1e-8)


def test_explicit_column_resolves_an_ambiguity() -> None:
    """Two acceleration candidates are fine once accel_column picks one."""
    data = _with_extra_column("az", 1)
    log = read_run_csv(data, CsvOptions(accel_column="az"))
    np.testing.assert_allclose(log.accel_z_mps2, _signals()["a"], atol=1e-9)


def test_explicit_column_that_does_not_exist_lists_the_columns() -> None:
    """A column option naming no column of the file says so and lists the columns found."""
    with pytest.raises(LogFormatError) as info:
        read_run_csv(BASE, CsvOptions(speed_column="velocity"))
    msg = str(info.value)
    assert "speed_column 'velocity'" in msg and "'time_s', 'accel_z_mps2'" in msg


def test_column_option_matches_ignoring_case_and_spaces() -> None:
    """speed_column=' SPEED_MPS ' finds 'speed_mps'."""
    parsed = parse_run_csv(BASE, CsvOptions(speed_column=" SPEED_MPS "))
    assert parsed.columns["speed"] == "speed_mps"


@pytest.mark.parametrize(
    ("gravity", "offset", "fragment"),
    [
        ("included", 0.0, "gravity='included' but the mean"),
        ("removed", GRAVITY, "gravity='removed' but the mean"),
        ("auto", -GRAVITY, "z axis may point down"),
    ],
)
def test_gravity_contradicting_the_data_is_refused(gravity: str, offset: float, fragment: str):
    """An explicit gravity option the mean contradicts, or an upside-down axis, is an error."""
    s = _signals()
    data = _csv(_lines(cols=[s["t"], s["a"] + offset, s["w"], s["v"]]))
    with pytest.raises(LogFormatError, match=fragment):
        read_run_csv(data, CsvOptions(gravity=gravity))


def test_gravity_included_is_subtracted_exactly() -> None:
    """gravity='included' subtracts 9.81 m/s² (engine.vehicle.GRAVITY) after conversion."""
    s = _signals()
    data = _csv(_repr_lines(HEADER, [s["t"], s["a"] + GRAVITY, s["w"], s["v"]]))
    for opt in ("included", "auto"):
        parsed = parse_run_csv(data, CsvOptions(gravity=opt))
        assert parsed.gravity == "included"
        np.testing.assert_allclose(parsed.log.accel_z_mps2, s["a"], atol=1e-14)


def test_chainage_column_in_km_and_decreasing() -> None:
    """A 'km' column (kilometres, decreasing) is read in metres, with no speed column needed."""
    s = _signals()
    km = 12.5 - 0.02 * s["t"]  # 20 m/s towards lower chainage
    parsed = parse_run_csv(
        _csv(_repr_lines("time_s,accel_z_mps2,pitch_rate_radps,km", [s["t"], s["a"], s["w"], km]))
    )
    assert parsed.units["chainage"] == "km" and parsed.log.speed_mps is None
    assert parsed.log.chainage_m is not None
    np.testing.assert_allclose(parsed.log.chainage_m, km * 1000.0)
    np.testing.assert_allclose(parsed.log.speed(), 20.0, rtol=1e-6)


def test_chainage_that_turns_back_is_refused_at_its_line() -> None:
    """A chainage stepping backwards names the column and the line."""
    s = _signals()
    c = 100.0 + 20.0 * s["t"]
    c[150:] -= 0.5
    data = _csv(
        _lines("time_s,accel_z_mps2,pitch_rate_radps,chainage_m", [s["t"], s["a"], s["w"], c])
    )
    with pytest.raises(LogFormatError, match="'chainage_m' at line 152") as info:
        read_run_csv(data)
    assert info.value.row == 152


def test_chainage_disagreeing_with_speed_flags_a_unit_error() -> None:
    """Speed in km/h without a suffix against a chainage in m: the mismatch is reported."""
    s = _signals()
    cols = [s["t"], s["a"], s["w"], s["v"] * 3.6, 100.0 + 20.0 * s["t"]]
    data = _csv(_lines("time_s,accel_z_mps2,pitch_rate_radps,speed,chainage_m", cols))
    with pytest.raises(LogFormatError, match="one of the units is wrong"):
        read_run_csv(data)
    log = read_run_csv(data, CsvOptions(speed_unit="km/h"))
    assert log.speed_mps is not None
    np.testing.assert_allclose(log.speed_mps, 20.0)


# ---------------------------------------------------------------------------------------------
# Options
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("option", "spelling", "canonical"),
    [
        ("accel_unit", "m/s^2", "m/s2"), ("accel_unit", "mps2", "m/s2"),
        ("accel_unit", "m/s²", "m/s2"), ("accel_unit", "G", "g"),
        ("speed_unit", "km/h", "km/h"), ("speed_unit", "kmh", "km/h"),
        ("speed_unit", "kph", "km/h"), ("speed_unit", "mps", "m/s"),
        ("pitch_rate_unit", "deg/s", "deg/s"),
        ("pitch_rate_unit", "dps", "deg/s"), ("pitch_rate_unit", "°/s", "deg/s"),
        ("pitch_rate_unit", "rad/s", "rad/s"), ("pitch_rate_unit", "radps", "rad/s"),
        ("time_unit", "ms", "ms"), ("time_unit", "epoch_s", "epoch_s"), ("time_unit", "s", "s"),
    ],
)  # fmt: skip
def test_unit_spellings_are_accepted(option: str, spelling: str, canonical: str) -> None:
    """Common unit spellings normalise to the canonical option value."""
    assert getattr(CsvOptions(**{option: spelling}), option) == canonical


@pytest.mark.parametrize(
    ("kwargs", "fragments"),
    [
        ({"accel_unit": "mm/s2"}, ("accel_unit", "'m/s2', 'g'")),
        ({"speed_unit": "mph"}, ("speed_unit", "'m/s', 'km/h'")),
        ({"pitch_rate_unit": "rpm"}, ("pitch_rate_unit", "'rad/s', 'deg/s'")),
        ({"time_unit": "us"}, ("time_unit", "'s', 'ms', 'epoch_s'")),
        ({"gravity": "maybe"}, ("gravity", "'auto', 'included', 'removed'")),
        ({"time_column": "x", "accel_column": "x"}, ("time_column", "accel_column", "'x'")),
        ({"speed_column": 3}, ("speed_column",)),
    ],
)
def test_bad_option_values_name_the_option_and_allowed_values(kwargs, fragments) -> None:
    """CsvOptions refuses bad values with ParameterError listing what is allowed."""
    with pytest.raises(ParameterError) as info:
        CsvOptions(**kwargs)
    for frag in fragments:
        assert frag in str(info.value)


def test_options_from_dict_treat_empty_as_automatic_and_refuse_unknown_keys() -> None:
    """Form fields: '' and None mean automatic; an unknown key is a ParameterError."""
    opts = CsvOptions.from_dict({"time_column": "", "speed_unit": "kph", "gravity": None})
    assert opts == CsvOptions(speed_unit="km/h")
    assert CsvOptions.from_dict(opts.to_dict()) == opts
    with pytest.raises(ParameterError, match="delimiter"):
        CsvOptions.from_dict({"delimiter": ";"})


# ---------------------------------------------------------------------------------------------
# Preview
# ---------------------------------------------------------------------------------------------


def test_preview_of_a_raw_log_shows_mapping_units_and_gravity() -> None:
    """The preview recognises a raw IMU header and guesses epoch time and gravity included."""
    s = _signals()
    cols = [1763800000.0 + s["t"], (s["a"] + GRAVITY) / GRAVITY, np.rad2deg(s["w"]), s["v"] * 3.6]
    data = _csv(_repr_lines("timestamp,az_g,gyro_y_dps,speed_kmh", cols))
    pv = preview_csv(data, n_rows=3)
    assert pv.delimiter == ","
    assert pv.columns == ["timestamp", "az_g", "gyro_y_dps", "speed_kmh"]
    assert len(pv.rows) == 3 and pv.rows[0][0] == "1763800000.0"
    assert pv.mapping == {
        "time": "timestamp", "accel": "az_g", "pitch_rate": "gyro_y_dps", "speed": "speed_kmh",
        "chainage": None, "wheel_load": None,
        "lat": None, "lon": None,
    }  # fmt: skip
    assert pv.units["time"] == "epoch_s" and pv.units["speed"] == "km/h"
    assert pv.gravity == "included"
    assert pv.warnings == []
    assert json.loads(json.dumps(pv.to_dict())) == pv.to_dict()


def test_preview_of_header_only_does_not_raise() -> None:
    """A header without data previews: columns and mapping shown, a warning, no rows."""
    pv = preview_csv((HEADER + "\n").encode())
    assert pv.columns == HEADER.split(",") and pv.rows == []
    assert pv.mapping["pitch_rate"] == "pitch_rate_radps"
    assert any("no data rows" in w for w in pv.warnings)


def test_preview_reports_problems_as_warnings() -> None:
    """Ambiguous columns, a single-column header and assumed units become warnings."""
    pv = preview_csv(_with_extra_column("az", 1))
    assert pv.mapping["accel"] is None
    assert any("'accel_z_mps2' and 'az'" in w for w in pv.warnings)
    pv = preview_csv(_csv([ln.replace(",", "|") for ln in _lines()]))
    assert pv.columns == [HEADER.replace(",", "|")]
    assert any("'|'" in w for w in pv.warnings)
    pv = preview_csv(_csv(_lines("time_s,acc,gyro,speed")))
    assert pv.units == {
        "time": "s", "accel": "m/s2", "pitch_rate": "rad/s", "speed": "m/s", "chainage": None,
        "wheel_load": None,
        "lat": None, "lon": None,
    }  # fmt: skip
    assert sum("assumed" in w for w in pv.warnings) == 3


def test_preview_applies_options() -> None:
    """Options given to the preview change its mapping and units."""
    data = _with_extra_column("az", 1)
    pv = preview_csv(data, options=CsvOptions(accel_column="az", accel_unit="g"))
    assert pv.mapping["accel"] == "az" and pv.units["accel"] == "g"


def test_preview_reads_only_the_head_of_a_truncated_gzip() -> None:
    """An incomplete gzip upload still previews from what has arrived."""
    big = _csv(_lines() * 40)
    pv = preview_csv(gzip.compress(big)[:2000], n_rows=5)
    assert pv.columns == HEADER.split(",") and len(pv.rows) == 5


@pytest.mark.parametrize(
    ("data", "fragment"),
    [(b"", "empty"), (b"\x00\x9f\x92binary", "not CSV text"), (b"# just a comment\n", "header")],
)
def test_preview_raises_on_empty_or_undecodable_input(data: bytes, fragment: str) -> None:
    """Nothing to show: LogFormatError."""
    with pytest.raises(LogFormatError, match=fragment):
        preview_csv(data)


def test_preview_rejects_a_silly_row_count() -> None:
    """n_rows outside 0..1000 is a ParameterError."""
    with pytest.raises(ParameterError, match="n_rows"):
        preview_csv(BASE, n_rows=-1)


# ---------------------------------------------------------------------------------------------
# Writing
# ---------------------------------------------------------------------------------------------


def _random_log(with_speed: bool = True, with_chainage: bool = False) -> RunLog:
    rng = np.random.default_rng(3)
    n = 500
    t = np.arange(n) / 1000.0
    return RunLog(
        time_s=t,
        accel_z_mps2=rng.standard_normal(n) * 0.1,
        pitch_rate_radps=rng.standard_normal(n) * 1e-3,
        speed_mps=20.0 + rng.random(n) if with_speed else None,
        chainage_m=100.0 + 20.5 * t if with_chainage else None,
    )


def test_written_csv_reads_back_bit_exact(tmp_path: Path) -> None:
    """Default full precision: write then read gives exactly the same floats."""
    log = _random_log(with_chainage=True)
    p = tmp_path / "out.csv"
    write_run_csv(log, p)
    assert p.read_text().splitlines()[0] == (
        "time_s,accel_z_mps2,pitch_rate_radps,speed_mps,chainage_m"
    )
    back = read_run_csv(p)
    for name in ("time_s", "accel_z_mps2", "pitch_rate_radps", "speed_mps", "chainage_m"):
        np.testing.assert_array_equal(getattr(back, name), getattr(log, name))


def test_written_csv_with_digits_rounds_to_significant_digits() -> None:
    """digits=6 writes 6 significant digits (and reads back within that precision)."""
    log = _random_log()
    buf = io.StringIO()
    write_run_csv(log, buf, digits=6)
    lines = buf.getvalue().splitlines()
    assert lines[0] == HEADER
    a1 = lines[2].split(",")[1]
    assert a1 == f"{log.accel_z_mps2[1]:.6g}"
    back = read_run_csv(buf.getvalue().encode())
    np.testing.assert_allclose(back.accel_z_mps2, log.accel_z_mps2, rtol=5e-6, atol=0)
    assert not np.array_equal(back.accel_z_mps2, log.accel_z_mps2)


def test_write_chainage_only_and_gzip_path(tmp_path: Path) -> None:
    """A log without speed writes the chainage column only; a .gz path is gzip-compressed."""
    log = _random_log(with_speed=False, with_chainage=True)
    p = tmp_path / "out.csv.gz"
    write_run_csv(log, p)
    assert p.read_bytes()[:2] == b"\x1f\x8b"
    text = gzip.decompress(p.read_bytes()).decode()
    assert text.splitlines()[0] == "time_s,accel_z_mps2,pitch_rate_radps,chainage_m"
    back = read_run_csv(p)
    assert back.speed_mps is None and back.chainage_m is not None
    np.testing.assert_array_equal(back.chainage_m, log.chainage_m)


@pytest.mark.parametrize("digits", [0, 18, 2.5])
def test_write_rejects_bad_digits(digits) -> None:
    """digits outside 1..17 (or not an integer) is a ParameterError."""
    with pytest.raises(ParameterError, match="digits"):
        write_run_csv(_random_log(), io.StringIO(), digits=digits)


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        ("2025-11-03T10:15:02.125Z", datetime(2025, 11, 3, 10, 15, 2, 125000, tzinfo=UTC)),
        ("2025-11-03 10:15:02+01:00", datetime(2025, 11, 3, 9, 15, 2, tzinfo=UTC)),
        ("'2025-11-03T10:15'", datetime(2025, 11, 3, 10, 15, tzinfo=UTC)),  # no offset: UTC
        ("2025-11-03", None),  # a day without a time
        ("1762164902.125", None),
        ("1890-01-01T00:00:00", None),  # implausible
        ("2025-13-03T10:15:02", None),
    ],
)
def test_iso_start_reads_iso_date_times_as_utc(value: str, expected: datetime | None) -> None:
    """A field with an ISO 8601 date and time is a clock time (UTC); anything else is not."""
    from engine.logio.units import iso_start

    assert iso_start(value) == expected
