"""Units: the one resolution of each column's unit (option, name, data) shared by parsing and
preview, and gravity (the limits that tell a wrong unit are :mod:`engine.plausibility`'s)."""

from __future__ import annotations

import re
from collections.abc import Mapping
from datetime import UTC, datetime

from ..vehicle import GRAVITY
from .options import CsvOptions
from .roles import ROLES, _label

EPOCH_THRESHOLD_S = 1e8
"""Time values above this (about 1973 in Unix seconds) are taken as epoch seconds."""

EPOCH_MS_THRESHOLD = 1e11
"""Time values above this are taken as epoch milliseconds."""

GRAVITY_TOLERANCE_MPS2 = 1.5
"""How far the mean acceleration may be from 9.81 (included) or 0 (removed), m/s²."""


PLAUSIBLE_EPOCH_S = (631_152_000.0, 4_102_444_800.0)
"""Epoch seconds taken as a recording time: 1990-01-01 to 2100-01-01 (UTC)."""


def epoch_start(t0: float, unit: str | None) -> datetime | None:
    """The clock time of a log's first sample when its time column holds epoch times.

    Parameters
    ----------
    t0 : float
        The first value of the time column, in the column's own unit.
    unit : {'s', 'ms', 'epoch_s'} or None
        The unit the column is read in (:func:`resolve_units`).

    Returns
    -------
    datetime or None
        UTC; None for relative times (seconds from the start) or implausible dates.
    """
    if unit == "epoch_s":
        seconds = t0
    elif unit == "ms" and abs(t0) > EPOCH_MS_THRESHOLD:
        seconds = t0 * 1e-3
    else:
        return None
    lo, hi = PLAUSIBLE_EPOCH_S
    if not lo <= seconds <= hi:
        return None
    return datetime.fromtimestamp(seconds, UTC)


_ISO_DATETIME = re.compile(r"\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}")


def iso_start(value: str) -> datetime | None:
    """The clock time a field holds when it is an ISO 8601 date and time.

    Parameters
    ----------
    value : str
        A CSV field, e.g. ``2025-11-03T10:15:02.125Z``, ``2025-11-03 10:15:02+01:00`` or
        ``2025-11-03T10:15:02`` (no offset: taken as UTC, loggers' usual clock).

    Returns
    -------
    datetime or None
        UTC; None for anything else (a date without a time, a number) or an implausible date
        (outside :data:`PLAUSIBLE_EPOCH_S`).
    """
    text = value.strip().strip("\"'")
    if not _ISO_DATETIME.match(text):
        return None
    try:
        when = datetime.fromisoformat(text)
    except ValueError:
        return None
    when = when.replace(tzinfo=UTC) if when.tzinfo is None else when.astimezone(UTC)
    lo, hi = PLAUSIBLE_EPOCH_S
    return when if lo <= when.timestamp() <= hi else None


def _auto_time_unit(t0: float) -> str:
    if abs(t0) > EPOCH_MS_THRESHOLD:
        return "ms"
    if abs(t0) > EPOCH_THRESHOLD_S:
        return "epoch_s"
    return "s"


def _auto_accel_unit(mean: float, gravity: str) -> str:
    # a mean of about 1 only makes sense as g with gravity included
    if gravity != "removed" and abs(mean - 1.0) < 0.15:
        return "g"
    return "m/s2"


def _auto_gravity(mean_mps2: float) -> str | None:
    if abs(mean_mps2 - GRAVITY) < GRAVITY_TOLERANCE_MPS2:
        return "included"
    if abs(mean_mps2) < GRAVITY_TOLERANCE_MPS2:
        return "removed"
    return None


DEFAULT_UNITS: dict[str, str] = {
    "pitch_rate": "rad/s", "speed": "m/s", "chainage": "m", "wheel_load": "kN", "lat": "deg",
    "lon": "deg",
}  # fmt: skip
"""Unit assumed for a column whose option and name say nothing (time and acceleration are
told from their values instead)."""


def _assumed(what: str, name: str, unit: str, role: str) -> str:
    return (
        f"{what} column {name!r} has no unit in its name: {_label(unit)} assumed "
        f"(set {role}_unit to be sure)"
    )


def resolve_units(
    columns: Mapping[str, str],
    options: CsvOptions,
    name_units: Mapping[str, str | None],
    *,
    t0: float | None,
    accel_mean: float | None,
) -> tuple[dict[str, str | None], list[str], list[str]]:
    """The unit each recognised column is read in: the one rule of parsing and preview.

    The option wins; else the unit the column's name implies; else the data decide (time:
    epoch seconds or milliseconds by the size of the first value; acceleration: g when its
    mean is about 1 and gravity may be included) or :data:`DEFAULT_UNITS` is assumed. A name
    saying seconds over values that are epoch seconds reads as epoch seconds.

    Parameters
    ----------
    columns : mapping
        Role -> header name, for the roles the file has.
    options : CsvOptions
        The user's choices.
    name_units : mapping
        Role -> unit implied by the column's name, or None.
    t0 : float or None
        First value of the time column in the file's unit (None: not known yet).
    accel_mean : float or None
        Mean of the acceleration column in the file's unit (None: not known yet).

    Returns
    -------
    units : dict
        Role (every one of ``ROLES``) -> unit, None when the file has no such column or the
        data needed to tell are missing.
    assumed : list of str
        Units assumed because neither an option nor the name said them (worth checking).
    notes : list of str
        What was read differently from what the name says (epoch time shifted to start at 0).
    """
    units: dict[str, str | None] = dict.fromkeys(ROLES)
    assumed: list[str] = []
    notes: list[str] = []
    for role in ROLES:
        if role not in columns:
            continue
        name = columns[role]
        chosen: str | None = getattr(options, f"{role}_unit")
        unit = chosen if chosen is not None else name_units.get(role)
        if role == "time":
            if t0 is not None and chosen is None:
                if unit is None:
                    unit = _auto_time_unit(t0)
                elif unit == "s" and abs(t0) > EPOCH_THRESHOLD_S:
                    unit = "epoch_s"  # seconds by its name, epoch seconds by its values
                if unit == "epoch_s" or abs(t0) > EPOCH_MS_THRESHOLD:
                    what = "epoch milliseconds" if unit == "ms" else "epoch seconds"
                    notes.append(f"time column {name!r} read as {what}, shifted to start at 0")
        elif unit is None and role == "accel":
            if accel_mean is not None:
                unit = _auto_accel_unit(accel_mean, options.gravity)
            assumed.append(_assumed("acceleration", name, unit or "m/s2", role))
        elif unit is None:
            unit = DEFAULT_UNITS[role]
            if role not in ("chainage", "lat", "lon"):  # the only unit they come in
                assumed.append(_assumed(role.replace("_", "-"), name, unit, role))
        units[role] = unit
    return units, assumed, notes
