"""Shared schema pieces: names, the error body."""

from __future__ import annotations

import re
import unicodedata
from collections.abc import Callable, Iterable
from datetime import UTC, datetime
from typing import Annotated, Any, Literal, get_args

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    JsonValue,
    ValidationInfo,
    field_validator,
)
from pydantic.json_schema import JsonDict

_CONTROL = re.compile(r"[\x00-\x1f\x7f]")


def _invisible(value: str) -> str | None:
    """The first character of ``value`` that shows as something else or nothing: format
    characters (right-to-left overrides, zero-width joiners, BOM) and spaces other than the
    plain one (no-break, thin, ideographic...), which make two names look alike."""
    for ch in value:
        cat = unicodedata.category(ch)
        if cat == "Cf" or (cat in ("Zs", "Zl", "Zp") and ch != " "):
            return ch
    return None


def _clean_name(value: str) -> str:
    value = unicodedata.normalize("NFC", value).strip()
    if not value:
        raise ValueError("must not be empty")
    if _CONTROL.search(value):
        raise ValueError("must not contain control characters (newlines, tabs, NUL)")
    bad = _invisible(value)
    if bad is not None:
        raise ValueError(
            f"must not contain U+{ord(bad):04X} ({unicodedata.name(bad, 'unnamed')}): "
            "invisible characters and spaces other than ' ' make names look alike"
        )
    return value


NAME_PATTERN = r"^[^\x00-\x1f\x7f]*[^\s\x00-\x1f\x7f][^\x00-\x1f\x7f]*$"
"""The rules of :data:`Name` a schema can state: something besides spaces, no control
characters (invisible characters and spaces other than ' ' are refused too)."""

URL_NAME_PATTERN = r"^(?![0-9]+$)(?!\.\.?$)" + NAME_PATTERN[1:]
""":data:`NAME_PATTERN`, and not digits only, nor ``.`` or ``..`` (see :data:`UrlName`)."""

Name = Annotated[
    str,
    Field(min_length=1, max_length=200, json_schema_extra={"pattern": NAME_PATTERN}),
    AfterValidator(_clean_name),
]
"""A user-given name: 1-200 characters, NFC-normalised, trimmed, no control or invisible
characters and no spaces but ' ' (any other text, markup included, is kept as typed and must
be shown as text)."""


CHAINAGE_LIMIT_M = 1e7
"""Largest chainage magnitude the service takes, m (10 000 km, longer than any line): far
beyond it a chainage is a typing or unit error, and grid indices would leave 64 bits."""

AlignmentStatus = Literal["reference", "aligned", "placed", "unaligned"]
"""How a run or survey sits on its track's chainage (``app.db.models.ALIGNMENT_STATUSES``)."""

MAX_ID_DIGITS = 18
"""Longest id written in a URL or filter: every id of 18 digits is below 2^63."""


def is_id_text(ref: str) -> bool:
    """Whether ``ref`` reads as an id: ASCII digits only (``'²'``, ``'٣'`` or ``'①'`` are
    names, not ids: ``str.isdigit`` accepts them and ``int('٣')`` is 3)."""
    return ref.isascii() and ref.isdigit()


def as_id(ref: str) -> int | None:
    """The id ``ref`` spells (ASCII digits), or None when it is a name.

    Raises
    ------
    ValueError
        When ``ref`` is digits but longer than :data:`MAX_ID_DIGITS` (no id is that large).
    """
    if not is_id_text(ref):
        return None
    if len(ref) > MAX_ID_DIGITS:
        raise ValueError(f"out of range: ids are whole numbers of at most {MAX_ID_DIGITS} digits")
    return int(ref)


_NUMBER = re.compile(r"\s*[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?\s*")


def _not_a_number(value: Any) -> Any:
    # pydantic reads numbers (and numeric strings) as Unix times: 0.5 would be 1970.
    if isinstance(value, int | float) or (isinstance(value, str) and _NUMBER.fullmatch(value)):
        raise ValueError(
            "must be an ISO 8601 date or date-time (e.g. 2026-03-01 or 2026-03-01T08:00:00Z), "
            "not a number"
        )
    return value


def _in_utc_range(value: datetime) -> datetime:
    try:
        (value if value.tzinfo is not None else value.replace(tzinfo=UTC)).astimezone(UTC)
    except OverflowError:
        raise ValueError("is outside the range of dates in UTC (years 1 to 9999)") from None
    return value


Timestamp = Annotated[datetime, BeforeValidator(_not_a_number), AfterValidator(_in_utc_range)]
"""A date-time from a client: ISO 8601 text (UTC when no offset), representable in UTC."""


def url_name_problem(value: str) -> str | None:
    """Why a new track or vehicle name would address the wrong thing in URLs, or None.

    Tracks and vehicles are addressed by id or name (``/api/v1/tracks/{track}``, ``?track=``),
    the id first: a name of digits only would be read as another track's id, and ``.`` or
    ``..`` are removed from paths by HTTP clients. Names with a ``/`` are accepted (markup
    such as ``</b>`` is legitimate text) but address their track by id only, as the dashboard
    always does; other characters work by name once percent-encoded.
    """
    if value in (".", ".."):
        return "must not be '.' or '..' (HTTP clients drop them from URLs)"
    if is_id_text(value):
        return (
            "must not be digits only: in URLs and filters a number is read as an id; add a "
            f"word, e.g. 'line {value}'"
        )
    return None


def _url_name(value: str) -> str:
    problem = url_name_problem(value)
    if problem is not None:
        raise ValueError(problem)
    return value


UrlName = Annotated[
    Name, AfterValidator(_url_name), Field(json_schema_extra={"pattern": URL_NAME_PATTERN})
]
"""The name of a resource addressed by id or name in URLs (tracks, vehicles): a :data:`Name`
that is not digits only, nor ``.`` or ``..``."""


def closed_list(names: Iterable[str]) -> Callable[[JsonDict], None]:
    """``json_schema_extra`` stating a closed list of names (an engine registry's keys) as
    the enum of a field's text: of the field itself, of its array's items or of its
    object's keys, in each alternative of a nullable field. The schema then says what the
    registry accepts (validation stays with the registry, whose 422 names the field)."""
    enum: list[JsonValue] = list(names)

    def extra(schema: JsonDict) -> None:
        alts = schema.get("anyOf")
        for alt in [schema, *(alts if isinstance(alts, list) else [])]:
            if not isinstance(alt, dict):
                continue
            items = alt.get("items")
            if alt.get("type") == "string":
                alt["enum"] = enum
            elif alt.get("type") == "array" and isinstance(items, dict):
                items["enum"] = enum
            elif alt.get("type") == "object":
                alt["propertyNames"] = {"enum": enum}

    return extra


def _accepts_bool(annotation: Any) -> bool:
    if annotation is bool:
        return True
    return any(_accepts_bool(a) for a in get_args(annotation))


class StrictModel(BaseModel):
    """A request body: unknown keys are an error rather than silently ignored, and ``true``
    or ``false`` is not a number (pydantic reads them as 1 and 0)."""

    model_config = ConfigDict(extra="forbid")

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_as_number(cls, value: Any, info: ValidationInfo) -> Any:
        if isinstance(value, bool) and info.field_name is not None:
            field = cls.model_fields.get(info.field_name)
            if field is not None and not _accepts_bool(field.annotation):
                raise ValueError("must not be true or false here")
        return value


class ErrorDetail(BaseModel):
    """What went wrong, with the facts that locate it (more facts may follow)."""

    model_config = ConfigDict(extra="allow")

    message: str = Field(description="Human-readable description of the problem")
    kind: str | None = Field(
        default=None,
        description="The class of the problem, e.g. LogFormatError, ParameterError, "
        "InputTooLarge, BudgetExceeded, MissingScope, OutOfRange, DatabaseBusy, InternalError",
    )
    limit_bytes: int | None = Field(default=None, description="The size limit exceeded, B")
    limit_s: float | None = Field(default=None, description="The time budget exceeded, s")
    scope: str | None = Field(default=None, description="The API key scope that is missing")
    allowed: list[str] | None = Field(default=None, description="Methods allowed (405)")
    field: str | None = Field(default=None, description="Request field concerned")
    column: str | None = Field(default=None, description="Column of the uploaded file")
    row: int | None = Field(default=None, description="1-based line of the file (header = 1)")
    unit: str | None = Field(default=None, description="Unit concerned")
    errors: list[dict[str, Any]] | None = Field(
        default=None, description="Every validation error: {loc, msg, type}"
    )


class ErrorResponse(BaseModel):
    """The body of every error answer."""

    detail: ErrorDetail


ERROR_RESPONSES: dict[int | str, dict[str, Any]] = {
    code: {"model": ErrorResponse, "description": text}
    for code, text in (
        (400, "Malformed request"),
        (401, "API key missing or not valid"),
        (403, "Writes are disabled (read-only mode) or the API key lacks the scope needed"),
        (404, "Not found"),
        (409, "Conflict with stored data"),
        (413, "Upload larger than the limit"),
        (415, "Unsupported content type"),
        (422, "The input is not valid: the detail names the field, column, row or unit"),
        (503, "The database is busy: retry after the Retry-After header's seconds"),
    )
}
"""Error answers documented on every API route."""


PROVISIONAL_DOC = (
    "True while a vehicle behind this separated result has neither a calibration applied to "
    "the version its runs were processed with nor a declared load (payload_kg or "
    "static_wheel_load_n) on every one of its runs: the separation reads an error in a "
    "vehicle's parameters or load as a stiffness change, so such a result is far less "
    "trustworthy. False for results every vehicle is known for, and for defects the "
    "separation did not find"
)
"""The ``provisional`` field of every answer that gives separated results."""

PROVISIONAL_REASON_DOC = (
    "Why it is provisional: each vehicle and its runs ('vehicle X: no calibration and no "
    "declared load on its runs 3, 5'); calibrate the vehicle or declare the runs' loads. "
    "Null when not provisional"
)
"""The ``provisional_reason`` field beside :data:`PROVISIONAL_DOC`."""
