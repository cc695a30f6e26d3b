"""The header line, the delimiter and splitting a line into fields."""

from __future__ import annotations

import csv
import re
from collections.abc import Iterable
from dataclasses import dataclass

from ..errors import LogFormatError

_SAMPLE_LINES = 20  # data lines used to sniff the delimiter

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
