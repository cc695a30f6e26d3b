"""Exceptions raised by the engine.

Every error that comes from bad input subclasses :class:`ValueError`, so callers that
only know the standard library can still catch it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any


class EngineError(ValueError):
    """Base class of every input error raised by the engine."""


class ParameterError(EngineError):
    """A model parameter or option (vehicle, track, sensor, solver, CSV option) is invalid.

    Attributes
    ----------
    field : str or None
        The parameter or option at fault, when the raiser names it.
    """

    def __init__(self, message: str, *, field: str | None = None):
        super().__init__(message)
        self.field = field


def reject_unknown_keys(data: Mapping[str, Any], known: Iterable[str], what: str) -> None:
    """Raise :class:`ParameterError` naming the keys of ``data`` not among ``known`` (the
    message lists those, as ``unknown <what>(s) [...]; expected some of [...]``)."""
    known = set(known)
    unknown = sorted(set(data) - known)
    if unknown:
        raise ParameterError(f"unknown {what}(s) {unknown}; expected some of {sorted(known)}")


def as_number(value: Any, name: str, what: str, unit: str) -> float:
    """``value`` as a float, or :class:`ParameterError` (``field=name``) saying that ``what``
    must be a number in ``unit``."""
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ParameterError(
            f"{what} must be a number in {unit}, got {value!r}", field=name
        ) from None


def check_settings(settings: object, checks: Mapping[str, bool], what: str) -> None:
    """:class:`ParameterError` (``field=<name>``) for the first of ``checks`` (a field of the
    ``settings`` dataclass -> whether its value is allowed) that fails; the message names
    ``what`` the settings are of and points to their class for the allowed values."""
    for name, ok in checks.items():
        if not ok:
            raise ParameterError(
                f"{what} {name} out of range: {getattr(settings, name)!r} (see "
                f"{type(settings).__name__} for the allowed values)",
                field=name,
            )


def check_range(value: float, name: str, what: str, lo: float, hi: float, unit: str) -> None:
    """:class:`ParameterError` (``field=name``) unless ``value`` is finite and within
    ``lo..hi`` (inclusive, in ``unit``); the message names ``what``."""
    if not (math.isfinite(value) and lo <= value <= hi):
        raise ParameterError(
            f"{what} must lie between {lo:g} and {hi:g} {unit}, got {value:g}", field=name
        )


class LogFormatError(EngineError):
    """A run log cannot be read: missing column, bad number, unknown unit, bad sampling.

    Attributes
    ----------
    column : str or None
        The column the problem is in, when there is one.
    row : int or None
        The 1-based line number in the file (the header is line 1), when there is one.
    """

    def __init__(self, message: str, *, column: str | None = None, row: int | None = None):
        super().__init__(message)
        self.column = column
        self.row = row


class InputTooLarge(LogFormatError):
    """A run log is larger than the limit it is read under (once decompressed).

    Attributes
    ----------
    limit_bytes : int
        The limit, B.
    """

    def __init__(self, message: str, *, limit_bytes: int) -> None:
        super().__init__(message)
        self.limit_bytes = limit_bytes


class InversionError(EngineError):
    """The log cannot be inverted (too short, speed out of range, not enough coverage)."""


class BudgetExceeded(EngineError):
    """A computation ran past its wall-time budget and was stopped.

    Attributes
    ----------
    budget_s : float
        The budget, s.
    elapsed_s : float
        Time spent when it was stopped, s.
    stage : str
        The last stage completed.
    """

    def __init__(self, message: str, *, budget_s: float, elapsed_s: float, stage: str) -> None:
        super().__init__(message)
        self.budget_s = budget_s
        self.elapsed_s = elapsed_s
        self.stage = stage
