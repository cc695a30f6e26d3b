"""Raw signals against time, decimated for display (a min/max envelope per time bucket)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.runlog import RunLog

MAX_SIGNAL_POINTS = 5000
"""Most points kept per signal."""


def _clean(a: NDArray[np.float64]) -> list[float | None]:
    return [None if not np.isfinite(v) else float(v) for v in a]


def minmax_envelope(
    time_s: NDArray[np.float64],
    signals: dict[str, NDArray[np.float64]],
    max_points: int = MAX_SIGNAL_POINTS,
) -> tuple[dict[str, list[float | None]], bool]:
    """Decimate signals sharing one time axis to at most ``max_points`` points each.

    Every bucket of consecutive samples gives two points, at its first and last sample time,
    carrying the bucket's minimum and maximum in the order they occur; peaks (a soft spot's
    response, a spike) survive any decimation factor.

    Returns
    -------
    data : dict
        ``time_s`` (s from the first sample) and each signal, equal-length lists.
    decimated : bool
        False when the signals were short enough to keep whole.
    """
    t = np.asarray(time_s, dtype=np.float64)
    n = t.size
    t_rel = t - t[0]
    if n <= max_points:
        out: dict[str, list[float | None]] = {"time_s": _clean(t_rel)}
        out |= {k: _clean(np.asarray(v, dtype=np.float64)) for k, v in signals.items()}
        return out, False
    buckets = max_points // 2
    size = -(-n // buckets)
    buckets = -(-n // size)
    first = np.arange(buckets) * size
    last = np.minimum(first + size - 1, n - 1)
    times = np.empty(2 * buckets)
    times[0::2] = t_rel[first]
    times[1::2] = t_rel[last]
    out = {"time_s": _clean(times)}
    pad = buckets * size - n
    for name, values in signals.items():
        v = np.asarray(values, dtype=np.float64)
        if pad:
            v = np.concatenate([v, np.full(pad, v[-1])])
        blocks = v.reshape(buckets, size)
        i_min = blocks.argmin(axis=1)
        i_max = blocks.argmax(axis=1)
        rows = np.arange(buckets)
        vmin = blocks[rows, i_min]
        vmax = blocks[rows, i_max]
        min_first = i_min <= i_max
        pair = np.empty(2 * buckets)
        pair[0::2] = np.where(min_first, vmin, vmax)
        pair[1::2] = np.where(min_first, vmax, vmin)
        out[name] = _clean(pair)
    return out, True


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
