"""engine.logio.limits: over-long lines refused before splitting; gzip bounded by what it
yields (engine.logio.source)."""

from __future__ import annotations

import gzip
import time
import tracemalloc

import pytest

from engine.errors import InputTooLarge, LogFormatError
from engine.logio import read_run_csv
from engine.logio.limits import (
    MAX_LINE_CHARS,
    MIN_DATA_LINE_CHARS,
    _short_lines_only,
    check_lines,
    data_line_limit,
    header_fields,
)
from engine.logio.source import _gunzip


def gunzip_bounded(data: bytes, limit: int) -> bytes:
    return _gunzip(data, limit)


HEADER = b"time_s,accel_z_mps2,pitch_rate_radps,speed_mps\n"
ROW = b"0.00100000,-0.12345678,0.00012345,25.00000000\n"


def test_ordinary_files_pass() -> None:
    """Plain, CRLF, CR-only, commented, blank-lined and UTF-16 logs pass untouched."""
    body = ROW * 20_000
    check_lines(HEADER + body)
    check_lines((HEADER + body).replace(b"\n", b"\r\n"))
    check_lines((HEADER + body).replace(b"\n", b"\r"))
    check_lines(b"# logger v2, " + b"x" * 2000 + b"\n\n" + HEADER + b"\n" + body)
    check_lines(b"\xff\xfe" + (HEADER + ROW * 100).decode().encode("utf-16-le"), char_bytes=2)
    check_lines(b"")


@pytest.mark.parametrize("offset", [0, 1, 100, 255])
@pytest.mark.parametrize("length", [509, 510, 511, 512, 513, 600])
def test_the_short_line_probe_never_passes_a_line_it_should_look_at(offset, length) -> None:
    """The block probe (a line feed in every aligned 256-byte block) answers True only for
    files whose lines are all under MIN_DATA_LINE_CHARS bytes, wherever the long line sits;
    check_lines then decides exactly as its line-by-line scan (a 1-column header allows 512
    characters)."""
    lines = [b"t"] + [b"1"] * offset + [b"9" * length] + [b"2"] * 300
    data = b"\n".join(lines) + b"\n"
    longest = max(len(line) for line in lines)
    assert _short_lines_only(data) is False or longest < MIN_DATA_LINE_CHARS
    if longest <= data_line_limit(1):
        check_lines(data)
    else:
        with pytest.raises(LogFormatError) as e:
            check_lines(data)
        assert e.value.row == offset + 2
    assert _short_lines_only(HEADER + ROW * 50_000) is True


@pytest.mark.parametrize("eol", [b"\n", b"\r\n", b"\r"])
def test_a_line_with_far_more_fields_than_the_header_is_refused(eol) -> None:
    """A data line of 100 000 fields under a 4-column header: 422-style error naming line 4."""
    data = (HEADER + ROW * 2 + b"0," * 100_000 + b"0\n" + ROW).replace(b"\n", eol)
    with pytest.raises(LogFormatError) as e:
        check_lines(data)
    assert e.value.row == 4
    assert "line 4 is 200001 characters long" in str(e.value)
    assert str(data_line_limit(4)) in str(e.value)


def test_an_endless_header_or_comment_is_refused() -> None:
    """A header (or a comment) longer than MAX_LINE_CHARS is refused, found without reading
    past the first block that holds it."""
    with pytest.raises(LogFormatError) as e:
        check_lines(b"a," * 20_000_000)
    assert e.value.row == 1
    with pytest.raises(LogFormatError) as e:
        check_lines(HEADER + ROW + b"#" + b" " * (MAX_LINE_CHARS + 1) + b"\n" + ROW)
    assert e.value.row == 3


def test_the_check_is_fast_and_small() -> None:
    """The probe's line (here 20 M fields, 40 MB) is refused in well under a second with a
    few MB of working memory (splitting it took ~20x its size)."""
    data = HEADER + b"0," * 20_000_000 + b"0\n"
    tracemalloc.start()
    t0 = time.perf_counter()
    with pytest.raises(LogFormatError):
        check_lines(data)
    elapsed = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert elapsed < 1.0
    assert peak < 64e6, peak


def test_header_fields_counts_any_delimiter() -> None:
    assert header_fields("t,a,q,v") == 4
    assert header_fields("t;a;q;v;s") == 5
    assert header_fields("t\ta\tq") == 3
    assert header_fields("time accel pitch speed") == 4


def test_gunzip_bounded_reads_every_member_and_counts_them() -> None:
    """Multi-member gzip with zero padding between members is read whole (as gzip does) and
    refused past the limit after decompressing at most limit + 1 bytes."""
    member = gzip.compress((b"1" * 99 + b"\n") * 6_000)
    assert len(gunzip_bounded(member + b"\x00" + member, 2_000_000)) == 1_200_000
    with pytest.raises(InputTooLarge) as e:
        gunzip_bounded(member + b"\x00\x00" + member, 1_000_000)
    assert e.value.limit_bytes == 1_000_000
    with pytest.raises(LogFormatError, match="corrupt or truncated"):
        gunzip_bounded(member[:50], 1_000_000)
    with pytest.raises(LogFormatError, match="twice"):
        gunzip_bounded(gzip.compress(member), 10_000_000)
    bomb = gzip.compress(b"0" * 50_000_000)  # one line, also refused for its size
    t0 = time.perf_counter()
    with pytest.raises(InputTooLarge):
        gunzip_bounded(bomb, 2_000_000)
    assert time.perf_counter() - t0 < 0.5


def test_gunzip_refuses_a_long_line_without_keeping_it() -> None:
    """A gzip'd 40 MB line is refused while decompressing: its line and full length named,
    and the decompressor never holds more than a few MB (not the 40 MB line)."""
    data = b"# logger\n" + HEADER + b"0," * 20_000_000 + b"0\n" + ROW
    packed = gzip.compress(data)
    tracemalloc.start()
    try:
        with pytest.raises(LogFormatError) as e:
            _gunzip(packed, 100_000_000)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert e.value.row == 3
    assert "40000001 bytes" in str(e.value)
    assert peak < 8_000_000, peak
    cr = gzip.compress(data.replace(b"\n", b"\r"))
    with pytest.raises(LogFormatError) as e:
        _gunzip(cr, 100_000_000)
    assert e.value.row == 3


def test_the_reader_refuses_the_long_line_before_splitting() -> None:
    """read_run_csv itself refuses the probe's line (plain and gzip), naming line 2."""
    data = HEADER + b"0," * 5_000_000 + b"0\n" + ROW * 10
    for source in (data, gzip.compress(data)):
        with pytest.raises(LogFormatError) as e:
            read_run_csv(source)
        assert e.value.row == 2
    with pytest.raises(InputTooLarge):
        read_run_csv(gzip.compress(HEADER + ROW * 100_000), max_bytes=1_000_000)
