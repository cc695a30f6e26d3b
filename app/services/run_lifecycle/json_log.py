"""A JSON run upload read without a Python object per number.

``{"columns": {"time_s": [0, 0.01, ...], ...}}`` parsed as JSON makes one Python float (and a
list slot) per number: ~35 bytes in memory for as little as 2 bytes of text (``0,``), so a
50 MB body grew the server by more than a gigabyte. :func:`split_json_columns` finds each
column's array of plain numbers in the raw body, parses it into a float64 array a chunk at a
time (8 bytes per number, at most 4x the text), and hands the rest of the body, with those arrays
emptied, to the ordinary JSON validation; that rest must then be small (the size limit of
every other body). The number of samples is capped by the upload limit exactly as a CSV's:
a sample of the three required columns takes at least 6 bytes (``0,0,0``) either way.

A column array holding anything but numbers (``null``, strings, ``NaN``) is not taken out:
it is validated by the JSON model as before, within the small size limit.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

import numpy as np
import orjson
from numpy.typing import NDArray

from app.services.errors import Invalid, TooLarge

_NUMBERS = rb"[0-9eE+\-.,\s]*"


def _pattern(names: Iterable[str]) -> re.Pattern[bytes]:
    keys = b"|".join(re.escape(n.encode()) for n in names)
    # A key can only match outside strings: inside one, its quotes would be escaped (\").
    return re.compile(rb'"(' + keys + rb')"\s*:\s*\[(' + _NUMBERS + rb")\]")


CHUNK_BYTES = 1 << 16
"""Text parsed at once, B: its Python objects (~16x the text) are freed before the next."""


def _first_bad(text: bytes) -> tuple[int, bytes]:
    """The index and text of the first item of ``text`` (``1,2,x``) that is not a number."""
    start, i = 0, 0
    while True:
        end = text.find(b",", start)
        item = (text[start:] if end < 0 else text[start:end]).strip()
        try:
            value = orjson.loads(item)
        except orjson.JSONDecodeError:
            return i, item
        if not isinstance(value, int | float) or end < 0:
            return i, item
        start, i = end + 1, i + 1


_SPACE = frozenset(b" \t\r\n")


def parse_numbers(
    body: bytes | bytearray, name: str, start: int = 0, stop: int | None = None
) -> NDArray[np.float64]:
    """The numbers of a JSON array's inside (``1, 2.5, -3e-2``) as a float64 array.

    ``body[start:stop]`` is read in place (no copy of the whole text), as JSON (strict number
    syntax) a chunk of :data:`CHUNK_BYTES` at a time, each chunk's values copied into the
    array before the next is read.

    Raises
    ------
    Invalid
        Naming the column and its row (line 2 = first sample, as in a CSV) at the first item
        that is not a number.
    """
    stop = len(body) if stop is None else stop
    while start < stop and body[start] in _SPACE:
        start += 1
    while stop > start and body[stop - 1] in _SPACE:
        stop -= 1
    if start == stop:
        return np.empty(0)
    out = np.empty(body.count(b",", start, stop) + 1)
    filled = 0
    while True:
        end = body.find(b",", min(start + CHUNK_BYTES, stop), stop)
        chunk = bytes(body[start:stop] if end < 0 else body[start:end])
        try:
            values = np.asarray(orjson.loads(b"[" + chunk + b"]"), dtype=np.float64)
        except (orjson.JSONDecodeError, TypeError, ValueError, OverflowError):
            i, item = _first_bad(chunk)
            what = f"({item[:20].decode(errors='replace')!r})" if item else "is empty:"
            raise Invalid(
                f"columns.{name}: item {filled + i} {what} is not a JSON number",
                field=f"columns.{name}", column=name, row=filled + i + 2, kind="LogFormatError",
            ) from None  # fmt: skip
        out[filled : filled + values.size] = values
        filled += values.size
        if end < 0:
            break
        start = end + 1
    if filled != out.size:  # a trailing comma at a chunk's end
        raise Invalid(
            f"columns.{name}: item {filled} is empty: is not a JSON number",
            field=f"columns.{name}", column=name, row=filled + 2, kind="LogFormatError",
        )  # fmt: skip
    return out


_COLUMNS_KEY = re.compile(rb'"columns"\s*:')


def has_columns(body: bytes | bytearray) -> bool:
    """Whether a JSON body has a ``columns`` key (outside strings, where quotes are escaped)."""
    return _COLUMNS_KEY.search(body) is not None


def split_json_columns(
    body: bytes | bytearray, names: Iterable[str], max_rest_bytes: int
) -> tuple[bytes, dict[str, NDArray[np.float64]]]:
    """Take the number arrays of ``columns`` out of a JSON body.

    Parameters
    ----------
    body : bytes or bytearray
        The request body (read in place).
    names : iterable of str
        The column names of ``columns``.
    max_rest_bytes : int
        Largest size of the body once its number arrays are emptied, B.

    Returns
    -------
    rest : bytes
        The body with each number array taken out left as ``[]`` (to validate as JSON).
    arrays : dict
        Each column taken out, by name (float64, SI units as sent).

    Raises
    ------
    Invalid
        A column given twice, or an item that is not a number.
    TooLarge
        The rest of the body is over ``max_rest_bytes`` (arrays holding something else than
        numbers, or other oversized content).
    """
    pieces: list[bytes | bytearray] = []
    spans: dict[str, tuple[int, int]] = {}
    pos = 0
    for m in _pattern(names).finditer(body):
        name = m.group(1).decode()
        if name in spans:
            raise Invalid(f"columns.{name} is given twice", field=f"columns.{name}")
        spans[name] = m.span(2)
        pieces.append(body[pos : m.start(2)])
        pos = m.end(2)
    pieces.append(body[pos:])
    rest = b"".join(pieces)
    del pieces
    if len(rest) > max_rest_bytes:
        raise TooLarge(
            f"the JSON body without its number arrays is {len(rest)} bytes, more than the "
            f"{max_rest_bytes} allowed (TRACKPROFILE_MAX_BODY_KB): each column must be an array "
            "of plain JSON numbers",
            field="columns",
            limit_bytes=max_rest_bytes,
        )
    arrays = {name: parse_numbers(body, name, a, b) for name, (a, b) in spans.items()}
    return rest, arrays
