"""Compressed column blocks: how a run's per-chainage arrays are kept in the database.

A block holds a few equal-length columns (NaN = no data) as scaled integers: each value is
rounded to a stated resolution (``scale``: 0.0001 mm for levels, 1 N for forces), the
columns are first-differenced along chainage (neighbouring grid points differ little), their
bytes shuffled (high bytes together, mostly zeros) and the lot compressed with Zstandard
(pyarrow's codec: ~10x faster than zlib level 6 here for 5 % more bytes). Missing values
travel as a bit mask per column. A block decodes exactly to the rounded values.

Why integers and not float32: a smooth level differenced at 0.1 µm is a few thousand counts
per 0.25 m step, two significant bytes of four (the other two are zeros that compress away);
float32 mantissas are noise to a compressor.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping, Sequence

import numpy as np
import pyarrow as pa
from numpy.typing import NDArray

from engine.kept import KeptArrays

LEVEL_RESOLUTION_MM = 0.0001
"""Resolution of a stored level, mm (values are rounded to it)."""

FORCE_RESOLUTION_N = 1.0
"""Resolution of a stored wheel force, N."""

_MAGIC = b"TPB1"
_HEADER = struct.Struct("<4sIBI")  # magic, points, columns, payload bytes uncompressed
_CODEC = pa.Codec("zstd")
_LIMIT = 2**31 - 1


def encode_block(columns: Sequence[NDArray[np.float64]], scales: Sequence[float]) -> bytes:
    """Pack equal-length columns (NaN = no data), each rounded to its ``scale``.

    Raises
    ------
    ValueError
        Columns of different lengths, or a value beyond ±2^31 scale steps.
    """
    n = int(columns[0].size) if columns else 0
    if any(c.size != n for c in columns) or len(columns) != len(scales):
        raise ValueError("a block needs equal-length columns and one scale per column")
    masks = []
    deltas = np.zeros((len(columns), n), dtype=np.int32)
    for k, (col, scale) in enumerate(zip(columns, scales, strict=True)):
        ok = np.isfinite(col)
        masks.append(np.packbits(ok).tobytes())
        q = np.zeros(n, dtype=np.float64)
        q[ok] = np.rint(np.asarray(col, dtype=np.float64)[ok] / scale)
        if q.size and np.abs(q).max() > _LIMIT:
            raise ValueError(f"a value exceeds the storable range (±{_LIMIT * scale:g})")
        qi = q.astype(np.int64)
        # No data carries the previous value: the difference there is 0.
        if not ok.all() and ok.any():
            idx = np.where(ok, np.arange(n), 0)
            np.maximum.accumulate(idx, out=idx)
            qi = qi[idx]
        deltas[k] = np.diff(qi, prepend=0).astype(np.int32)
    shuffled = deltas.view(np.uint8).reshape(len(columns), n, 4).transpose(2, 0, 1).tobytes()
    raw = b"".join(masks) + shuffled
    return _HEADER.pack(_MAGIC, n, len(columns), len(raw)) + _CODEC.compress(raw, asbytes=True)


def decode_block(
    blob: bytes, scales: Sequence[float], which: Sequence[int] | None = None
) -> list[NDArray[np.float64]]:
    """Inverse of :func:`encode_block`: the columns as float64 (NaN = no data).

    ``which`` lists the column indices wanted (default: all), returned in that order; the
    others are not reconstructed (a window read of the level needs two of seven).
    """
    magic, n, k, size = _HEADER.unpack_from(blob)
    if magic != _MAGIC or k != len(scales):
        raise ValueError("not a column block of this layout")
    cols = list(range(k)) if which is None else list(which)
    raw = _CODEC.decompress(memoryview(blob)[_HEADER.size :], size, asbytes=True)
    nm = (n + 7) // 8
    b = np.frombuffer(raw, np.uint8, 4 * k * n, k * nm).reshape(4, k, n)
    out = []
    for j in cols:
        mask = np.unpackbits(np.frombuffer(raw, np.uint8, nm, j * nm), count=n).astype(bool)
        deltas = np.ascontiguousarray(b[:, j, :].T).view("<i4").reshape(n)
        v = np.cumsum(deltas, dtype=np.int32).astype(np.float64) * scales[j]
        v[~mask] = np.nan
        out.append(v)
    return out


_ARRAY_MAGIC = b"TPA1"
_ARRAY_HEADER = struct.Struct("<4s2sI")  # magic, dtype ("f4" or "f8", little-endian), values


def _shuffled(a: NDArray[np.floating]) -> NDArray[np.uint8]:
    """The bytes of ``a`` grouped by significance (all first bytes, then all second, ...),
    transposed in blocks that stay in cache, into a numpy array (large ones get huge pages:
    a fraction of the page faults of a ``bytes`` copy)."""
    width = a.itemsize
    v = a.view(np.uint8).reshape(a.size, width)
    out = np.empty((width, a.size), dtype=np.uint8)
    step = 1 << 16
    for at in range(0, a.size, step):
        out[:, at : at + step] = v[at : at + step].T
    return out


def _float_parts(values: NDArray[np.floating], dtype: str) -> list[bytes | pa.Buffer]:
    """:func:`pack_floats`'s blob as its parts (header, compressed payload), not joined."""
    if dtype not in ("f4", "f8"):
        raise ValueError(f"dtype must be 'f4' or 'f8', not {dtype!r}")
    a = np.ascontiguousarray(values, dtype="<" + dtype)
    header = _ARRAY_HEADER.pack(_ARRAY_MAGIC, dtype.encode(), a.size)
    return [header, _CODEC.compress(_shuffled(a), asbytes=False)]


def pack_floats(values: NDArray[np.floating], dtype: str = "f4") -> bytes:
    """Values as little-endian float32 (``"f4"``) or float64 (``"f8"``), losslessly
    compressed (bytes shuffled, Zstandard); NaN kept.

    float32 is for the chunks of aligned levels and wheel forces the aggregate and the
    separation are recomputed from (kept for ever, so not rounded further than float32);
    float64 for a run's log, which calibration and reprocessing read back bit for bit.
    """
    return b"".join(_float_parts(values, dtype))


def unpack_floats(blob: bytes | memoryview) -> NDArray[np.float64]:
    """Inverse of :func:`pack_floats`, as float64."""
    magic, dtype, n = _ARRAY_HEADER.unpack_from(blob)
    if magic != _ARRAY_MAGIC or dtype not in (b"f4", b"f8"):
        raise ValueError("not a packed float array")
    width = 4 if dtype == b"f4" else 8
    raw = _CODEC.decompress(memoryview(blob)[_ARRAY_HEADER.size :], width * n, asbytes=True)
    b = np.frombuffer(raw, np.uint8).reshape(width, n).T
    out = np.ascontiguousarray(b).view("<" + dtype.decode()).reshape(n)
    return out.astype(np.float64)


def pack_f4(values: NDArray[np.floating]) -> bytes:
    """:func:`pack_floats` as float32 (a chunk of aligned levels or wheel forces)."""
    return pack_floats(values, "f4")


unpack_f4 = unpack_floats


class KeptUnpacks(KeptArrays):
    """:func:`unpack_floats` of the blobs unpacked last, kept by the blobs' bytes.

    A track's chunks of aligned levels and wheel forces are read again by every pass that
    arrives over them (the aggregate's rebuild, each detection unit, the separation), and
    an earlier run's blobs do not change: their arrays are taken from here (a dictionary
    look-up of the blob, ~1 µs, against ~25 µs to unpack a chunk). The key is the blob's
    content, so a changed blob is unpacked again and the numbers are the same either way.
    Thread-safe; the least recently used go first once the blobs and arrays kept exceed
    ``max_bytes``.

    Parameters
    ----------
    max_bytes : int
        Memory the kept blobs and their arrays may take, bytes. The default, 32 MiB, holds
        some 2900 chunks of 1000 points (a 4 kB blob and an 8 kB array each).
    """

    def __init__(self, max_bytes: int = 32 * 2**20) -> None:
        super().__init__(max_bytes)

    def __call__(self, blob: bytes | memoryview) -> NDArray[np.float64]:
        """``unpack_floats(blob)``, read-only (the kept array is shared by every caller)."""
        key = bytes(blob)
        got = self.get(key)
        if got is not None:
            return got
        out = unpack_floats(key)
        out.flags.writeable = False
        self.put(key, out, len(key) + out.nbytes)
        return out


unpack_f4_kept = KeptUnpacks()
"""The process's kept unpacks of stored level and force chunks (:class:`KeptUnpacks`)."""


_NAMED_MAGIC = b"TPN1"


def pack_named(
    columns: Mapping[str, NDArray[np.floating] | None], names: Sequence[str], dtype: str = "f8"
) -> bytes:
    """Named columns (``names`` in order; None = absent) packed one after the other with
    :func:`pack_floats` in ``dtype``: a run's log (float64, bit for bit) or its display
    signals. (Joined once: a run's log is ~50 MB, each copy of it ~0.05 s of page faults.)"""
    parts: list[bytes | pa.Buffer] = [_NAMED_MAGIC]
    for name in names:
        arr = columns.get(name)
        blob = [] if arr is None else _float_parts(arr, dtype)
        size = sum(len(b) if isinstance(b, bytes) else b.size for b in blob)
        parts.append(struct.pack("<I", size))
        parts.extend(blob)
    return b"".join(parts)


def unpack_named(blob: bytes, names: Sequence[str]) -> dict[str, NDArray[np.float64]]:
    """Inverse of :func:`pack_named`: the columns present, as float64."""
    if bytes(blob[:4]) != _NAMED_MAGIC:
        raise ValueError("not packed named columns")
    view = memoryview(blob)
    at = 4
    out: dict[str, NDArray[np.float64]] = {}
    for name in names:
        (size,) = struct.unpack_from("<I", view, at)
        at += 4
        if size:
            out[name] = unpack_floats(view[at : at + size])
        at += size
    return out
