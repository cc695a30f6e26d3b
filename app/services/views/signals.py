"""Raw signals against time, decimated for display (a min/max envelope per time bucket)."""

from __future__ import annotations

import struct
from typing import Any

import numpy as np
from numpy.typing import NDArray

from app.services.storage.packing import pack_named, unpack_named
from app.services.storage.profiles import nullable
from engine.decimate import minmax_indices
from engine.runlog import RunLog

MAX_SIGNAL_POINTS = 5000
"""Most points kept per signal."""

SIGNAL_NAMES = ("time_s", "accel_z_mps2", "pitch_rate_radps", "speed_mps")
"""What is stored, in order: time (float64) and the signals (float32, plenty for display)."""


def pack_signals(data: dict[str, list[float | None]]) -> bytes:
    """Display signals as stored (``RunSignals.packed``): time as float64, the signals as
    float32, compressed (~10x smaller than JSON numbers); None stays missing."""
    arrays = {
        k: np.array([np.nan if v is None else v for v in data[k]], dtype=np.float64)
        for k in SIGNAL_NAMES
    }
    return pack_named({"time_s": arrays["time_s"]}, ("time_s",), "f8") + pack_named(
        arrays, SIGNAL_NAMES[1:], "f4"
    )


def unpack_signals(blob: bytes) -> dict[str, list[float | None]]:
    """Inverse of :func:`pack_signals`: equal-length lists, None where there is no value."""
    (size,) = struct.unpack_from("<I", blob, 4)
    split = 8 + size
    arrays = unpack_named(blob[:split], ("time_s",)) | unpack_named(blob[split:], SIGNAL_NAMES[1:])
    return {k: nullable(arrays[k]) for k in SIGNAL_NAMES}


def minmax_envelope(
    time_s: NDArray[np.float64],
    signals: dict[str, NDArray[np.float64]],
    max_points: int = MAX_SIGNAL_POINTS,
) -> tuple[dict[str, list[float | None]], bool]:
    """Decimate signals sharing one time axis to at most ``max_points`` points each.

    The samples kept are :func:`engine.decimate.minmax_indices` over all signals: each keeps
    its extremes, so peaks (a soft spot's response, a spike) survive any decimation factor.

    Returns
    -------
    data : dict
        ``time_s`` (s from the first sample) and each signal, equal-length lists.
    decimated : bool
        False when the signals were short enough to keep whole.
    """
    t = np.asarray(time_s, dtype=np.float64)
    values = [np.asarray(v, dtype=np.float64) for v in signals.values()]  # (not stacked)
    idx = minmax_indices(values, max_points)
    out: dict[str, list[float | None]] = {"time_s": nullable(t[idx] - t[0])}
    out |= {k: nullable(row[idx]) for k, row in zip(signals, values, strict=True)}
    return out, idx.size < t.size


def log_signals(log: RunLog, max_points: int = MAX_SIGNAL_POINTS) -> tuple[dict[str, Any], bool]:
    """The display signals of a run log: acceleration, pitch rate and speed against time."""
    return minmax_envelope(
        log.time_s,
        {
            "accel_z_mps2": log.accel_z_mps2,
            "pitch_rate_radps": log.pitch_rate_radps,
            "speed_mps": log.speed(),
        },
        max_points,
    )
