"""Limits a CSV run log must keep before it is split into fields: size and line length.

Splitting a line into fields costs ~20x its length in Python objects (one ``str`` per field,
a list slot each, the tokenizer's buffers), so one 150 MB line of ``0,0,0,...`` takes
gigabytes before any check can see that it has 75 million fields where the header named 5.
:func:`check_lines` looks at the raw bytes first, a block at a time, and refuses

* any line longer than :data:`MAX_LINE_CHARS` (a header of ~1000 columns fits), and
* a data line longer than :func:`data_line_limit` of the header: :data:`CHARS_PER_FIELD`
  characters for each column the header names (numbers are never that long).

Its own memory is a few times :data:`BLOCK_BYTES` whatever the file. (The size limit of a
gzip file is applied to what it expands to, in :mod:`engine.logio.source`.)

Units: sizes in bytes of the decoded text's encoding (characters for ASCII/UTF-8 numbers).
"""

from __future__ import annotations

import re

import numpy as np

from ..errors import LogFormatError

MAX_LINE_CHARS = 65_536
"""Longest line of any kind (header, comment, data), characters."""
CHARS_PER_FIELD = 64
"""Longest text of one data field (a number, its delimiter and spaces), characters."""
MIN_DATA_LINE_CHARS = 512
"""Data lines up to this length are always accepted, characters."""
BLOCK_BYTES = 1 << 22
"""Bytes scanned at once, B."""

_SEPARATORS = re.compile(r"[,;\t]")


def header_fields(header: str) -> int:
    """How many columns a header line can name at most (any of the delimiters counted)."""
    seps = max(
        (len(_SEPARATORS.findall(header)),) + tuple(header.count(c) for c in ",;\t"),
        default=0,
    )
    return max(seps, len(header.split()) - 1) + 1


def data_line_limit(n_fields: int) -> int:
    """Longest data line accepted under a header of ``n_fields`` columns, characters."""
    return min(MAX_LINE_CHARS, max(MIN_DATA_LINE_CHARS, CHARS_PER_FIELD * n_fields))


def _line_number(data: bytes | bytearray, offset: int) -> int:
    newlines = data.count(b"\n", 0, offset)
    return (newlines if newlines else data.count(b"\r", 0, offset)) + 1


def check_lines(data: bytes | bytearray, char_bytes: int = 1) -> None:
    """Refuse over-long lines before anything splits them (see the module's description).

    Parameters
    ----------
    data : bytes
        The decompressed file.
    char_bytes : int
        Bytes per character of the encoding (2 for UTF-16), to state limits in characters.

    Raises
    ------
    LogFormatError
        Naming the line (``row``, 1-based) that is too long, its length and the limit.
    """
    if _short_lines_only(data):
        return
    limit: int | None = None  # data lines, once the header is known
    header_seen = False
    start = 0  # offset where the current line starts
    n = len(data)
    has_cr = data.find(b"\r") >= 0  # (memchr: most logs end lines with \n alone)
    for block_start in range(0, n, BLOCK_BYTES):
        block = np.frombuffer(data, dtype=np.uint8, count=min(BLOCK_BYTES, n - block_start),
                              offset=block_start)  # fmt: skip
        is_break = (block == 10) | (block == 13) if has_cr else block == 10
        breaks = np.flatnonzero(is_break) + block_start
        ends = np.append(breaks, n) if block_start + BLOCK_BYTES >= n else breaks
        if ends.size == 0:
            if (block_start + block.size - start) // char_bytes > MAX_LINE_CHARS:
                _too_long(data, start, block_start + block.size - start, MAX_LINE_CHARS,
                          char_bytes, "any line")  # fmt: skip
            continue
        starts = np.concatenate(([start], ends[:-1] + 1))
        next_start = int(ends[-1]) + 1
        lengths = (ends - starts) // char_bytes
        if not header_seen:
            # The header is the first line that is neither blank nor a comment.
            for s, e in zip(starts.tolist(), ends.tolist(), strict=True):
                if (e - s) // char_bytes > MAX_LINE_CHARS:
                    _too_long(data, s, e - s, MAX_LINE_CHARS, char_bytes, "any line")
                text = data[s:e].decode("latin-1").replace("\x00", "").strip()
                if text and not text.startswith("#"):
                    header_seen = True
                    limit = data_line_limit(header_fields(text))
                    keep = starts > s
                    starts, ends, lengths = starts[keep], ends[keep], lengths[keep]
                    break
            else:
                start = next_start
                continue
        assert limit is not None
        for k in np.flatnonzero(lengths > limit).tolist():
            s, e = int(starts[k]), int(ends[k])
            head = data[s : s + 64].decode("latin-1").replace("\x00", "").lstrip()
            if not head.startswith("#"):
                _too_long(data, s, e - s, limit, char_bytes, "a data line under this header")
            if lengths[k] > MAX_LINE_CHARS:  # a comment: only the absolute limit
                _too_long(data, s, e - s, MAX_LINE_CHARS, char_bytes, "any line")
        start = next_start


_PROBE_BYTES = MIN_DATA_LINE_CHARS // 2
"""Size of the aligned blocks :func:`_short_lines_only` looks for line feeds in, B."""


def _short_lines_only(data: bytes | bytearray) -> bool:
    """True when every line is shorter than :data:`MIN_DATA_LINE_CHARS` bytes, which every
    limit allows: a line feed in each aligned block of ``MIN_DATA_LINE_CHARS // 2`` bytes.
    (A run of ``2 * block - 1`` bytes without one contains a whole block.) About 3x faster
    than finding every line's end; False sends the file to the exact check."""
    n = len(data) // _PROBE_BYTES * _PROBE_BYTES
    blocks = np.frombuffer(data, dtype=np.uint8, count=n).reshape(-1, _PROBE_BYTES)
    rows = BLOCK_BYTES // _PROBE_BYTES
    return all(
        bool((blocks[at : at + rows] == 10).any(axis=1).all())
        for at in range(0, blocks.shape[0], rows)
    )


def _too_long(
    data: bytes | bytearray, start: int, size: int, limit: int, char_bytes: int, what: str
) -> None:
    line = _line_number(data, start)
    raise LogFormatError(
        f"line {line} is {size // char_bytes} characters long; {what} may have at most "
        f"{limit} ({CHARS_PER_FIELD} per column the header names): is this a CSV run log with "
        "one sample per line?",
        row=line,
    )
