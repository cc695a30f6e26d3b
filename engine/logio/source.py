"""Bytes in: a path, bytes or a file; gzip (with a cap on the expanded size); text encoding."""

from __future__ import annotations

import codecs
import gzip
import io
import os
import zlib
from dataclasses import dataclass
from typing import IO, Any, BinaryIO

from ..errors import InputTooLarge, LogFormatError
from .limits import MAX_LINE_CHARS

MAX_DECOMPRESSED_BYTES = 1 << 30
"""Largest gzip-decompressed size accepted, bytes (a guard against decompression bombs)."""

Source = str | os.PathLike[str] | bytes | bytearray | memoryview | BinaryIO | IO[bytes]

_GZIP_MAGIC = b"\x1f\x8b"
# bytes that never occur in text: C0 controls other than tab, LF, VT, FF, CR and DEL
_CONTROL_BYTES = bytes([*range(0, 9), *range(14, 32), 127])
_TEXT_BYTES_DELETE = bytes(b for b in range(256) if b not in _CONTROL_BYTES)


def _read_source(source: Source, max_bytes: int | None = None) -> bytes | bytearray:
    """The bytes of a source, gzip-decompressed when it is gzip (at most ``max_bytes``).

    A ``bytearray`` is read in place, not copied (an upload's buffer: 135 MB for an hour at
    1 kHz); the caller must not change it until the reader returns.
    """
    data: bytes | bytearray
    if isinstance(source, bytes | bytearray):
        data = source
    elif isinstance(source, memoryview):
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
        data = _gunzip(data, max_bytes)
    return data


_GUNZIP_CHUNK = 1 << 20
"""Decompressed bytes read at a time, B."""
_LONGEST_LINE_BYTES = 2 * MAX_LINE_CHARS
"""A line of more bytes is over :data:`MAX_LINE_CHARS` in every encoding read (1 or 2 bytes
per character): refused while decompressing, before the rest of the file is kept."""


def _gunzip(data: bytes | bytearray, limit: int | None = None) -> bytes | bytearray:
    """Decompress gzip data, refusing more than ``limit`` (default MAX_DECOMPRESSED_BYTES).

    :mod:`gzip` reads every member of a multi-member file and skips zero padding between
    them; the limit counts exactly what it yields (a pre-check that stopped at the padding
    let the rest through unmeasured), after at most ``limit + 1`` bytes.

    Decompressed a chunk at a time: a line over :data:`_LONGEST_LINE_BYTES` is refused as soon
    as it is seen, and the rest of it is only counted, never kept (a 40 kB gzip of one 40 MB
    line held the whole line, three uploads at once 120 MB, to refuse it afterwards).
    """
    cap = MAX_DECOMPRESSED_BYTES if limit is None else limit
    out = bytearray()
    line_start = 0  # offset in ``out`` where the current line starts
    try:
        with gzip.GzipFile(fileobj=io.BytesIO(data)) as gz:
            while len(out) <= cap:
                chunk = gz.read(min(_GUNZIP_CHUNK, cap + 1 - len(out)))
                if not chunk:
                    break
                at = len(out)
                out += chunk
                last = max(chunk.rfind(b"\n"), chunk.rfind(b"\r"))
                if last >= 0:
                    line_start = at + last + 1
                elif len(out) - line_start > _LONGEST_LINE_BYTES and out[:2] != _GZIP_MAGIC:
                    _refuse_long_line(gz, out, line_start, cap, limit is None)
    except (OSError, EOFError, zlib.error) as e:
        raise LogFormatError(f"the gzip-compressed file is corrupt or truncated ({e})") from None
    if len(out) > cap:
        _too_large(cap, limit is None)
    if out[:2] == _GZIP_MAGIC:
        raise LogFormatError("the file is gzip-compressed twice: compress the CSV only once")
    return out


def _refuse_long_line(
    gz: gzip.GzipFile, out: bytearray, line_start: int, cap: int, default_cap: bool
) -> None:
    """Raise for the over-long line starting at ``line_start``, counting the rest of it from
    ``gz`` without keeping it (a file expanding past the cap meanwhile is refused for that)."""
    # a file with \r line ends alone numbers its lines by \r (as engine.logio.limits does)
    breaks = out.count(b"\n", 0, line_start) or out.count(b"\r", 0, line_start)
    size = len(out) - line_start
    total = len(out)
    while chunk := gz.read(min(_GUNZIP_CHUNK, cap + 1 - total)):
        ends = [i for i in (chunk.find(b"\n"), chunk.find(b"\r")) if i >= 0]
        if ends:
            size += min(ends)
            break
        size += len(chunk)
        total += len(chunk)
    if total > cap:  # the size limit is the answer when both hold
        _too_large(cap, default_cap)
    line = breaks + 1
    raise LogFormatError(
        f"line {line} is {size} bytes long; any line may have at most {MAX_LINE_CHARS} "
        "characters: is this a CSV run log with one sample per line?",
        row=line,
    )


def _too_large(cap: int, default_cap: bool) -> None:
    raise InputTooLarge(
        f"the gzip-compressed file expands to more than {cap / 1e6:g} MB, over "
        f"{'MAX_DECOMPRESSED_BYTES' if default_cap else 'the upload limit'}, which applies "
        "to the CSV itself: split the run into shorter logs",
        limit_bytes=cap,
    )


def _gunzip_head(data: bytes | bytearray, size: int) -> tuple[bytes, bool]:
    """The first ``size`` decompressed bytes of gzip data, and whether there is more."""
    d = zlib.decompressobj(wbits=16 + zlib.MAX_WBITS)
    try:
        out = d.decompress(data, size)
    except zlib.error as e:
        raise LogFormatError(f"the gzip-compressed file is corrupt ({e})") from None
    return out, bool(d.unconsumed_tail) or not d.eof


def _line_of_offset(data: bytes | bytearray, offset: int) -> int:
    return data.count(b"\n", 0, offset) + 1


def _detect_encoding(data: bytes | bytearray, final: bool = True) -> tuple[str, str | None]:
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


class _BufferReader(io.RawIOBase):
    """A binary stream over a buffer without copying it (``io.BytesIO`` copies a
    ``bytearray``); the view is released on close, so the buffer can be resized again."""

    def __init__(self, data: bytes | bytearray) -> None:
        self._view: memoryview | None = memoryview(data)
        self._pos = 0

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        if self._view is None:
            raise ValueError("read from a closed stream")
        out = memoryview(buffer).cast("B")
        n = max(0, min(len(out), len(self._view) - self._pos))
        out[:n] = self._view[self._pos : self._pos + n]
        self._pos += n
        return n

    def close(self) -> None:
        if self._view is not None:
            self._view.release()
            self._view = None
        super().close()


@dataclass(frozen=True)
class _Source:
    data: bytes | bytearray
    encoding: str

    def lines(self) -> io.TextIOWrapper:
        # universal newlines: \r\n and \r become \n
        raw = (
            io.BytesIO(self.data)  # shares a bytes object's memory
            if isinstance(self.data, bytes)
            else io.BufferedReader(_BufferReader(self.data))
        )
        return io.TextIOWrapper(raw, encoding=self.encoding, newline=None)
