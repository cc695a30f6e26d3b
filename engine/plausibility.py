"""The one plausibility check of a run log, whatever path it came by (CSV, JSON arrays,
simulation): sampling without gaps, magnitudes a vehicle body can have, a chainage that moves
like a vehicle.

A log that passes :class:`~engine.runlog.RunLog`'s structural checks (finite numbers, equal
lengths, strictly increasing time) can still be nonsense that the inversion would turn into
kilometres of invented profile: a 100 s gap in time, one acceleration sample of 1e308 m/s², a
chainage that jumps 2 km between two samples. :func:`check_plausible` refuses those with a
:class:`~engine.errors.LogFormatError` naming the column and the row. The CSV reader calls it
with the file's column names and line numbers; every other path gets the canonical names and
row ``i + 2`` for sample ``i`` (as if written as a CSV with one header line).

Units: SI throughout (s, m/s², rad/s, m/s, m).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np
from numpy.typing import NDArray

from .errors import LogFormatError
from .runlog import RunLog
from .scan import first_at_most, first_beyond, first_outside, first_true

ACCEL_LIMIT_MPS2 = 50.0
"""Largest plausible vertical body acceleration, m/s² (gravity removed); beyond it the unit is
wrong (e.g. counts or mm/s²)."""

PITCH_RATE_LIMIT_RADPS = 5.0
"""Largest plausible body pitch rate, rad/s; beyond it the unit is wrong (e.g. deg/s)."""

SPEED_MIN_MPS = 0.5
"""Slowest speed accepted at any sample, m/s (standstills cannot be inverted)."""

SPEED_MAX_MPS = 150.0
"""Fastest plausible speed, m/s (540 km/h); beyond it the unit is wrong (e.g. km/h)."""

MIN_RATE_HZ = 10.0
"""Lowest plausible sample rate, Hz; a slower time column is in the wrong unit (ms read as s)."""

MAX_RATE_HZ = 100_000.0
"""Highest plausible sample rate, Hz."""

STEP_TOLERANCE = 0.01
"""Allowed deviation of a time step from the median step, as a fraction of it."""

GAP_FACTOR = 1.5
"""A step longer than this many median steps is reported as a gap."""

WHEEL_LOAD_MIN_N = 5e3
"""Lightest plausible static wheel load, N (a light railcar's empty wheel is ~30 kN)."""

WHEEL_LOAD_MAX_N = 300e3
"""Heaviest plausible static wheel load, N (a 40 t axle is ~196 kN per wheel)."""

CHAINAGE_RESOLUTION_M = 0.1
"""Coarsest odometer resolution allowed for, m: a chainage step may exceed the fastest
plausible speed times the time step by this much."""

CANONICAL_NAMES = {
    "time_s": "time_s", "accel_z_mps2": "accel_z_mps2", "pitch_rate_radps": "pitch_rate_radps",
    "speed_mps": "speed_mps", "chainage_m": "chainage_m", "wheel_load_n": "wheel_load_n",
}  # fmt: skip

MAGNITUDES: dict[str, tuple[float, float, str, str]] = {
    "accel_z_mps2": (
        -ACCEL_LIMIT_MPS2, ACCEL_LIMIT_MPS2, "m/s²",
        f"a vertical body acceleration (gravity removed) stays within ±{ACCEL_LIMIT_MPS2:g} m/s²",
    ),
    "pitch_rate_radps": (
        -PITCH_RATE_LIMIT_RADPS, PITCH_RATE_LIMIT_RADPS, "rad/s",
        f"a body pitch rate stays within ±{PITCH_RATE_LIMIT_RADPS:g} rad/s",
    ),
    "speed_mps": (
        SPEED_MIN_MPS, SPEED_MAX_MPS, "m/s",
        f"the speed must be between {SPEED_MIN_MPS:g} m/s (standstills cannot be inverted: "
        f"cut them out) and {SPEED_MAX_MPS:g} m/s ({SPEED_MAX_MPS * 3.6:g} km/h)",
    ),
    "wheel_load_n": (
        WHEEL_LOAD_MIN_N, WHEEL_LOAD_MAX_N, "N",
        f"a static wheel load lies between {WHEEL_LOAD_MIN_N / 1e3:g} and "
        f"{WHEEL_LOAD_MAX_N / 1e3:g} kN (is the unit right? N, kN or t)",
    ),
}  # fmt: skip
"""The range of each sampled field of a log: lowest, highest, unit, and what the user is told
when a sample lies outside; an optional field is checked where the log has it."""

RowOf = Callable[[int], int]
"""Maps a 0-based sample index to the 1-based row reported to the user."""


def _default_row(i: int) -> int:
    return i + 2


def check_time_steps(
    t: NDArray[np.float64], name: str = "time_s", row_of: RowOf = _default_row, hint: str = ""
) -> float:
    """Refuse gaps, irregular sampling and implausible rates; the median step, s.

    Parameters
    ----------
    t : ndarray
        Sample times, s, strictly increasing.
    name : str
        Column name for messages.
    row_of : callable
        Row of sample ``i`` for messages.
    hint : str
        Appended to the message of an implausible rate (e.g. which unit option to set).

    Raises
    ------
    LogFormatError
        Naming the column and the row of the first bad step.
    """
    dt = np.diff(t)
    h = float(np.median(dt))
    i = first_beyond(dt, STEP_TOLERANCE * h, center=h)
    if i is not None:
        ln, prev = row_of(i + 1), row_of(i)
        step = float(dt[i])
        if step > GAP_FACTOR * h:
            msg = (
                f"gap in the time column {name!r} at line {ln}: {step:.6g} s after line {prev}, "
                f"{step / h:.3g} times the expected constant step of {h:.6g} s "
                f"({1 / h:.6g} Hz); the log must be sampled without gaps"
            )
        else:
            msg = (
                f"irregular sampling in the time column {name!r} at line {ln}: the step from "
                f"line {prev} is {step:.6g} s, expected a constant step of {h:.6g} s "
                f"({1 / h:.6g} Hz, within {STEP_TOLERANCE:.0%}); resample the log to a constant "
                "rate"
            )
        raise LogFormatError(msg, column=name, row=ln)
    rate = 1.0 / h
    if not (MIN_RATE_HZ <= rate <= MAX_RATE_HZ):
        raise LogFormatError(
            f"the time column {name!r} steps by {h:.6g} s, a sample rate of {rate:.6g} Hz, "
            f"outside the plausible {MIN_RATE_HZ:g} Hz to {MAX_RATE_HZ:g} Hz{hint}",
            column=name,
        )
    return h


def _magnitude(
    values: NDArray[np.float64], name: str, row_of: RowOf, lo: float, hi: float, unit: str,
    what: str,
) -> None:  # fmt: skip
    i = first_outside(values, lo, hi)
    if i is not None:
        raise LogFormatError(
            f"column {name!r} at line {row_of(i)} is {float(values[i]):.6g} {unit}: {what}",
            column=name,
            row=row_of(i),
        )


def check_chainage(
    c: NDArray[np.float64],
    t: NDArray[np.float64],
    name: str = "chainage_m",
    row_of: RowOf = _default_row,
) -> None:
    """Refuse a chainage that stands still, turns back or jumps faster than a vehicle moves.

    Raises
    ------
    LogFormatError
        Naming the column and the row of the first bad sample.
    """
    total = float(c[-1] - c[0])
    if total == 0:
        raise LogFormatError(
            f"column {name!r} does not change: the chainage must move with the vehicle",
            column=name,
        )
    sign = 1.0 if total > 0 else -1.0
    step = np.diff(c) * sign
    i = first_at_most(step, 0.0)
    if i is not None:
        raise LogFormatError(
            f"column {name!r} at line {row_of(i + 1)} is {float(c[i + 1])!r} m, not beyond "
            f"{float(c[i])!r} m at line {row_of(i)}: the chainage must move steadily "
            f"{'up' if sign > 0 else 'down'} through the run",
            column=name,
            row=row_of(i + 1),
        )
    dt = np.diff(t)
    i = first_true(step > SPEED_MAX_MPS * dt + CHAINAGE_RESOLUTION_M)
    if i is not None:
        raise LogFormatError(
            f"column {name!r} jumps by {float(step[i]):.6g} m at line {row_of(i + 1)} (from line "
            f"{row_of(i)}, {float(dt[i]):.6g} s earlier): a speed of "
            f"{float(step[i] / dt[i]):.6g} m/s, beyond the {SPEED_MAX_MPS:g} m/s a vehicle can "
            "run; the chainage must move steadily with the vehicle",
            column=name,
            row=row_of(i + 1),
        )


def check_plausible(
    log: RunLog, names: Mapping[str, str] | None = None, row_of: RowOf = _default_row
) -> None:
    """Refuse a run log that no instrumented vehicle can have written.

    Parameters
    ----------
    log : RunLog
        The run, SI units, gravity removed.
    names : mapping, optional
        Column name to report for each of the log's fields (``time_s``, ``accel_z_mps2``,
        ``pitch_rate_radps``, ``speed_mps``, ``chainage_m``); default the field names.
    row_of : callable, optional
        Row reported for sample ``i``; default ``i + 2`` (line 1 = a header).

    Raises
    ------
    LogFormatError
        The first problem found, naming the column and the row: a gap or irregular step in
        time, a sample rate outside :data:`MIN_RATE_HZ`..:data:`MAX_RATE_HZ`, an acceleration
        beyond ±:data:`ACCEL_LIMIT_MPS2`, a pitch rate beyond ±:data:`PITCH_RATE_LIMIT_RADPS`,
        a speed outside :data:`SPEED_MIN_MPS`..:data:`SPEED_MAX_MPS`, a chainage that stands
        still, turns back or moves faster than :data:`SPEED_MAX_MPS` between two samples, or
        a chainage whose mean speed disagrees with the speed column by more than 2x, or a
        static wheel load outside :data:`WHEEL_LOAD_MIN_N`..:data:`WHEEL_LOAD_MAX_N`.

    Notes
    -----
    Called once per log by :func:`engine.setup.prepare_run` (the way into processing); the
    CSV reader makes the same checks column by column with its own names and hints, and its
    logs are prepared without repeating them.
    """
    n = {**CANONICAL_NAMES, **(names or {})}
    check_time_steps(log.time_s, n["time_s"], row_of)
    for field, (lo, hi, unit, what) in MAGNITUDES.items():
        values = getattr(log, field)
        if values is not None:
            _magnitude(values, n[field], row_of, lo, hi, unit, what)
    if log.chainage_m is not None:
        check_chainage(log.chainage_m, log.time_s, n["chainage_m"], row_of)
        mean_v = abs(float(log.chainage_m[-1] - log.chainage_m[0])) / log.duration_s
        if log.speed_mps is not None:
            ratio = mean_v / float(np.mean(log.speed_mps))
            if not (0.5 <= ratio <= 2.0):
                raise LogFormatError(
                    f"column {n['chainage_m']!r} advances at {mean_v:.4g} m/s on average but "
                    f"the speed column {n['speed_mps']!r} averages "
                    f"{float(np.mean(log.speed_mps)):.4g} m/s: one of them is wrong",
                    column=n["chainage_m"],
                )
        elif not (SPEED_MIN_MPS <= mean_v <= SPEED_MAX_MPS):
            raise LogFormatError(
                f"column {n['chainage_m']!r} moves at {mean_v:.4g} m/s on average, outside "
                f"{SPEED_MIN_MPS:g} to {SPEED_MAX_MPS:g} m/s",
                column=n["chainage_m"],
            )
