"""Domain errors of the services: what went wrong, with the facts that name it, no HTTP.

Services (and the CLI and worker that call them) raise these; :mod:`app.core.errors` alone maps
them, and the engine's own errors, to status codes:

- :class:`NotFound`: a thing addressed by the caller does not exist;
- :class:`Conflict`: the request contradicts what is stored (a name taken, a key reused, a run
  not in the state the request needs);
- :class:`Invalid`: an input is wrong; ``field`` names it, ``column``/``row``/``unit`` point
  into an uploaded file;
- :class:`TooLarge`: an input is over a size limit;
- :class:`Unsupported`: an input comes in a form that is not taken (a body's content type);
- :class:`Malformed`: an input cannot be read at all (an empty body, JSON that is not JSON);
- :class:`Gone`: it existed and was removed on purpose (a run's detail after retention).

Facts are keyword arguments; those left None are not reported. ``kind`` names the error class
clients can branch on (``"LogFormatError"``, ``"ParameterError"``, ...).
"""

from __future__ import annotations

from typing import Any

from engine.errors import BudgetExceeded, EngineError, LogFormatError, ParameterError


class DomainError(Exception):
    """A service error: a message for people and facts for programs."""

    def __init__(
        self,
        message: str,
        *,
        field: str | None = None,
        column: str | None = None,
        row: int | None = None,
        unit: str | None = None,
        **extra: Any,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.facts: dict[str, Any] = {
            "field": field, "column": column, "row": row, "unit": unit, **extra
        }  # fmt: skip

    def detail(self) -> dict[str, Any]:
        """``{"message", <facts>}``, facts that are None left out."""
        return {"message": self.message} | {k: v for k, v in self.facts.items() if v is not None}


class NotFound(DomainError):
    """Something the caller addressed (a run, a track, a vehicle) does not exist."""


class Conflict(DomainError):
    """The request contradicts what is stored."""


class Gone(DomainError):
    """Something the caller addressed existed but was removed on purpose (a run's detail
    under the retention policy)."""


class Invalid(DomainError):
    """An input is wrong: ``field`` names it; ``column``, ``row`` and ``unit`` point into a file."""

    @classmethod
    def from_engine(cls, exc: EngineError, field: str | None = None) -> Invalid:
        """The engine's input error with its facts; ``field`` names the request field it came
        from when the engine does not (the uploaded file, the column options)."""
        facts = engine_error_facts(exc)
        message = facts.pop("message")
        if field is not None:
            facts.setdefault("field", field)
        return cls(message, **facts)


class TooLarge(DomainError):
    """An input is over a size limit (``limit_bytes`` says which)."""


class Unsupported(DomainError):
    """An input comes in a form that is not taken (``field`` names what says the form, such as
    ``Content-Type``)."""


class Malformed(DomainError):
    """An input cannot be read at all, before any of its fields can be named (an empty body,
    a body that is not the JSON it claims to be)."""


def engine_error_facts(exc: EngineError) -> dict[str, Any]:
    """Message and facts of an engine input error: column, row, field and its ``kind``."""
    detail: dict[str, Any] = {"message": str(exc)}
    if isinstance(exc, LogFormatError):
        if exc.column is not None:
            detail["column"] = exc.column
        if exc.row is not None:
            detail["row"] = exc.row
    if isinstance(exc, ParameterError) and exc.field is not None:
        detail["field"] = exc.field
    quantity = getattr(exc, "quantity", None)
    if quantity is not None:  # a derived quantity out of range (whole-vehicle plausibility)
        detail["quantity"] = quantity
    if isinstance(exc, BudgetExceeded):
        detail["limit_s"] = exc.budget_s
    detail["kind"] = type(exc).__name__
    return detail
