"""The one intake of request bodies that carry a file (runs, surveys, centerlines): the body's
content type checked, a multipart form's ``file`` part and text fields or a whole body read
into memory, and request fields validated by their schema.

Problems are domain errors (:mod:`app.services.errors`): a content type not taken is
:class:`~app.services.errors.Unsupported`, a form without its file part
:class:`~app.services.errors.Invalid`; :mod:`app.core.errors` gives them their status codes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

from fastapi.exceptions import RequestValidationError
from pydantic import BaseModel, ValidationError
from starlette.requests import Request

from app.api.multipart import BufferedUpload, read_form
from app.services.errors import Invalid, Unsupported

M = TypeVar("M", bound=BaseModel)

MULTIPART = "multipart/form-data"
JSON = "application/json"


def content_type(request: Request, accepted: Sequence[str], send: str) -> str:
    """The request's content type (lower case, without parameters), one of ``accepted``.

    Raises
    ------
    Unsupported
        Naming ``Content-Type`` and what to ``send`` instead, for any other type.
    """
    ctype = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if ctype not in accepted:
        raise Unsupported(
            f"unsupported content type {ctype or '(none)'!r}: send {send}", field="Content-Type"
        )
    return ctype


@dataclass
class FileForm:
    """A multipart upload: its ``file`` part's bytes and name, and its text fields."""

    data: bytearray
    filename: str | None
    fields: dict[str, str]


async def read_file_form(request: Request, *, what: str, max_fields: int) -> FileForm:
    """The request's multipart form with exactly one file part, named ``file``.

    ``what`` says what the file is, for the message when it is missing ("the run log").

    Raises
    ------
    Invalid
        Naming ``file`` when there is no file part of that name or ``file`` is a text field;
        naming the part when a file comes under another name.
    starlette.exceptions.HTTPException
        400 when the body is not a valid form (see :func:`app.api.multipart.read_form`).
    """
    form = await read_form(request, max_files=1, max_fields=max_fields)
    upload = form.get("file")
    if upload is None:
        raise Invalid(f"the upload has no 'file' part ({what})", field="file")
    if not isinstance(upload, BufferedUpload):
        raise Invalid("'file' must be a file, not a text field", field="file")
    fields: dict[str, Any] = {k: v for k, v in form.multi_items() if k != "file"}
    extra_files = [k for k, v in fields.items() if not isinstance(v, str)]
    if extra_files:
        raise Invalid(f"unexpected file part {extra_files[0]!r}", field=extra_files[0])
    return FileForm(upload.buffer, upload.filename, fields)


async def read_body(request: Request) -> bytearray:
    """The whole body, read into one growing buffer (not chunks joined at the end: half the
    peak memory of a large JSON upload)."""
    body = bytearray()
    async for chunk in request.stream():
        body += chunk
    return body


def validation_error(exc: ValidationError) -> RequestValidationError:
    """A schema's refusal of request fields, answered like FastAPI's own (422 naming the first
    bad field)."""
    return RequestValidationError(exc.errors(include_url=False, include_input=False))


def validated(model: type[M], data: Any) -> M:
    """``data`` (a form's fields) as ``model``; :class:`RequestValidationError` otherwise."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise validation_error(exc) from None


def validated_json(model: type[M], body: bytes | bytearray) -> M:
    """A JSON body as ``model``; :class:`RequestValidationError` otherwise (JSON that does not
    parse included)."""
    try:
        return model.model_validate_json(body)
    except ValidationError as exc:
        raise validation_error(exc) from None
