"""Numbers: the threaded path (pyarrow, :mod:`.threaded`), the reference fast path (numpy's
C tokenizer) and the careful line-by-line path that names the bad line."""

from __future__ import annotations

import re
import warnings
from array import array

import numpy as np
from numpy.typing import NDArray

from ..errors import LogFormatError
from .header import (
    _DATE_LIKE,
    _DECIMAL_COMMA,
    _DELIMITER_LABEL,
    _field_count_ok,
    _Header,
    _is_skipped,
    _short,
    _split,
    _strip_comment,
)
from .source import (
    _Source,
)
from .threaded import parse_arrow


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


def _sparse_cell(text: str) -> float:
    return float(text) if text.strip() else float("nan")


def _parse_fast(
    src: _Source, header: _Header, sparse: frozenset[int] = frozenset()
) -> NDArray[np.float64] | None:
    """All columns via numpy's C tokenizer, or None when the file needs the careful path.
    Empty cells of the ``sparse`` columns read as NaN (a converter for those columns only)."""
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
                    converters=dict.fromkeys(sparse, _sparse_cell) if sparse else None,
                )
        except (ValueError, UnicodeDecodeError):
            return None
    if arr.shape[0] == 0 or arr.shape[1] != len(header.names):
        return None
    return arr


def _to_float(text: str, column: str, line: int, sparse: bool = False) -> float:
    t = text.strip()
    if len(t) >= 2 and t[0] == t[-1] == '"':
        t = t[1:-1].strip()
    if not t and sparse:
        return float("nan")
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


def _parse_careful(
    src: _Source, header: _Header, needed: list[int], sparse: frozenset[int] = frozenset()
) -> _Table:
    """Read line by line, converting only the needed columns; raises at the first bad line.
    Empty cells of the ``sparse`` columns read as NaN."""
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
                out.append(_to_float(parts[j], header.names[j], ln, j in sparse))
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


def _parse_table(
    src: _Source, header: _Header, needed: list[int], sparse: frozenset[int] = frozenset()
) -> _Table:
    got = parse_arrow(src, header, needed, sparse)
    if got is not None:
        columns, n = got
        return _Table(columns, n, src, header, None)
    return _parse_reference(src, header, needed, sparse)


def _parse_reference(
    src: _Source, header: _Header, needed: list[int], sparse: frozenset[int] = frozenset()
) -> _Table:
    """The reference reading: numpy's tokenizer, else line by line (naming a bad line)."""
    arr = _parse_fast(src, header, sparse)
    if arr is None:
        return _parse_careful(src, header, needed, sparse)
    return _Table({j: arr[:, j] for j in needed}, arr.shape[0], src, header, None)
