"""One error shape for every 4xx/5xx answer: ``{"detail": {"message": ..., <facts>}}``.

The facts name what is wrong: ``field`` (request field), ``column`` and ``row`` (the uploaded
file: the column name and the 1-based line number, header = line 1), ``unit``, and for request
validation ``errors`` (each ``{"loc", "msg", "type"}``).
"""

from __future__ import annotations

import logging
import re
from collections.abc import Sequence
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from sqlalchemy.exc import DataError, OperationalError, StatementError
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.routing import Match

from app.services.errors import (
    Conflict,
    DomainError,
    Gone,
    Invalid,
    Malformed,
    NotFound,
    TooLarge,
    Unsupported,
    engine_error_facts,
)
from engine.errors import EngineError

log = logging.getLogger(__name__)


class ApiError(DomainError):
    """An error of the HTTP layer itself (a body that is not JSON, a missing file part, an
    unsupported content type), answered with ``status_code``; services raise domain errors."""

    def __init__(
        self,
        status_code: int,
        message: str,
        *,
        headers: dict[str, str] | None = None,
        **facts: Any,
    ) -> None:
        super().__init__(message, **facts)
        self.status_code = status_code
        self.headers = headers


RETRY_AFTER_S = 2
"""Retry-After of a 503 for a busy database, s."""


class BodyTooLarge(Exception):
    """The request body went over the upload size limit while it was being read."""

    def __init__(self, limit_bytes: int) -> None:
        super().__init__(limit_bytes)
        self.limit_bytes = limit_bytes


DOMAIN_STATUS: dict[type[DomainError], int] = {
    NotFound: 404,
    Conflict: 409,
    Invalid: 422,
    TooLarge: 413,
    Gone: 410,
    Unsupported: 415,
    Malformed: 400,
}
"""Status code of each domain error of the services (the only place that knows them)."""


def domain_status(exc: DomainError) -> int:
    """The status code of a domain error (its nearest class in :data:`DOMAIN_STATUS`)."""
    for cls in type(exc).__mro__:
        if cls in DOMAIN_STATUS:
            return DOMAIN_STATUS[cls]
    return 422


def too_large_detail(limit_bytes: int) -> dict[str, Any]:
    """Detail of a 413 answer."""
    return {
        "message": f"the request body is larger than the upload limit of "
        f"{limit_bytes / 1e6:g} MB (TRACKPROFILE_MAX_UPLOAD_MB)",
        "limit_bytes": limit_bytes,
    }


def internal_error_detail() -> dict[str, Any]:
    """Detail of a 500 answer (nothing about the cause: that goes to the log)."""
    return {"message": "internal error: the request was not completed", "kind": "InternalError"}


def out_of_range_detail() -> dict[str, Any]:
    """Detail of a 422 for a number the database cannot hold (ids, offsets: 64-bit)."""
    return {
        "message": "a number in the request is out of range: ids, offsets and limits must be "
        "whole numbers below 2^63 (9223372036854775807)",
        "kind": "OutOfRange",
    }


def data_error_detail(exc: DataError) -> dict[str, Any]:
    """Detail of a 422 for a request value the database refused (type, range, NUL in text)."""
    reason = str(exc.orig).strip().splitlines()[0] if exc.orig is not None else ""
    if "out of range" in reason:
        return out_of_range_detail()
    return {
        "message": f"a value in the request cannot be stored or searched by the database: "
        f"{reason[:200] or 'invalid value'}",
        "kind": "InvalidValue",
    }


def database_busy_error() -> ApiError:
    """503 for a database that is busy (locked) or unreachable: the client should retry."""
    return ApiError(
        503,
        "the database is busy or unavailable: try again in a moment",
        headers={"Retry-After": str(RETRY_AFTER_S)},
        kind="DatabaseBusy",
    )


def _loc_name(loc: Sequence[Any]) -> str:
    parts = [str(p) for p in loc if p not in ("body", "query", "path", "header", "form")]
    return ".".join(parts)


def validation_detail(errors: Sequence[Any]) -> dict[str, Any]:
    """Detail of a 422 for pydantic/FastAPI validation errors, naming the first bad field."""
    cleaned = [
        {
            "loc": list(e.get("loc", ())),
            "msg": str(e.get("msg", "")),
            "type": str(e.get("type", "")),
        }
        for e in errors
    ]
    if not cleaned:
        return {"message": "the request is not valid", "errors": []}
    first = cleaned[0]
    field = _loc_name(first["loc"])
    # pydantic prefixes the messages of custom validators with "Value error, "
    msg = str(first["msg"]).removeprefix("Value error, ")
    message = f"{field}: {msg}" if field else f"the request body is not valid: {msg}"
    if len(cleaned) > 1:
        message += f" (and {len(cleaned) - 1} more problem{'s' if len(cleaned) > 2 else ''})"
    detail: dict[str, Any] = {"message": message, "errors": cleaned}
    if field:
        detail["field"] = field
    return detail


HTTP_METHODS = ("DELETE", "GET", "HEAD", "OPTIONS", "PATCH", "POST", "PUT")


def _documented_methods(request: Request) -> set[str] | None:
    """The methods the OpenAPI document lists for the request's path (its first template
    that matches, in route order), or None for a path it does not describe."""
    path = request.url.path
    for template, item in request.app.openapi().get("paths", {}).items():
        pattern = re.sub(r"\\\{[^}]*\\\}", "[^/]+", re.escape(template))
        if re.fullmatch(pattern, path):
            methods = {m.upper() for m in item if m.upper() in HTTP_METHODS}
            return methods | ({"HEAD"} if "GET" in methods else set())
    return None


def allowed_methods(request: Request) -> list[str]:
    """Every method the path's resource serves (sorted): those some route answers on the
    path, less those the OpenAPI document gives to another resource (``PATCH
    /vehicles/presets`` would reach ``/vehicles/{vehicle}``, not the presets)."""
    routes = request.app.router.routes
    served = [
        m for m in HTTP_METHODS
        if any(r.matches({**request.scope, "method": m})[0] == Match.FULL for r in routes)
    ]  # fmt: skip
    documented = _documented_methods(request)
    return served if documented is None else [m for m in served if m in documented]


def method_not_allowed_error(request: Request) -> ApiError | None:
    """405 (with ``Allow``) when the request's path is served but not with its method; None
    when the method is allowed or no resource has the path (a 404 is not this one's)."""
    allowed = allowed_methods(request)
    if not allowed or request.method in allowed:
        return None
    return ApiError(
        405,
        f"method {request.method} is not allowed here; allowed: {', '.join(allowed)}",
        headers={"Allow": ", ".join(allowed)},
        allowed=allowed,
    )


def install_error_handlers(app: FastAPI) -> None:
    """Register the handlers that give every error the ``{"detail": {...}}`` shape."""

    @app.exception_handler(ApiError)
    async def _api_error(_request: Request, exc: ApiError) -> JSONResponse:
        return JSONResponse(
            status_code=exc.status_code, content={"detail": exc.detail()}, headers=exc.headers
        )

    @app.exception_handler(DomainError)
    async def _domain_error(_request: Request, exc: DomainError) -> JSONResponse:
        return JSONResponse(status_code=domain_status(exc), content={"detail": exc.detail()})

    @app.exception_handler(EngineError)
    async def _engine_error(_request: Request, exc: EngineError) -> JSONResponse:
        return JSONResponse(status_code=422, content={"detail": engine_error_facts(exc)})

    @app.exception_handler(BodyTooLarge)
    async def _too_large(_request: Request, exc: BodyTooLarge) -> JSONResponse:
        return JSONResponse(status_code=413, content={"detail": too_large_detail(exc.limit_bytes)})

    @app.exception_handler(RequestValidationError)
    async def _validation(_request: Request, exc: RequestValidationError) -> JSONResponse:
        return JSONResponse(status_code=422, content={"detail": validation_detail(exc.errors())})

    @app.exception_handler(StarletteHTTPException)
    async def _http(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        detail: dict[str, Any] = (
            exc.detail if isinstance(exc.detail, dict) else {"message": str(exc.detail)}
        )
        headers = dict(getattr(exc, "headers", None) or {})
        if exc.status_code == 405 and (not_allowed := method_not_allowed_error(request)):
            # Starlette names the methods of the first route whose path matched; a path
            # served by several routes (GET and DELETE /runs/{id}) allows all of theirs.
            headers |= not_allowed.headers or {}
            detail = not_allowed.detail()
        return JSONResponse(
            status_code=exc.status_code, content={"detail": detail}, headers=headers or None
        )

    # A value of the request that the database cannot take (an id or offset beyond 64 bits,
    # a NUL character in text on PostgreSQL) is the client's error, not the server's: 422,
    # and the connection stays usable (a 500 from the catch-all below drops it).
    @app.exception_handler(OverflowError)
    async def _overflow(request: Request, exc: OverflowError) -> JSONResponse:
        log.info("number out of range on %s %s: %s", request.method, request.url.path, exc)
        return JSONResponse(status_code=422, content={"detail": out_of_range_detail()})

    # A value that passed validation but cannot be converted for the database (a date-time
    # whose offset takes it outside years 1..9999 in UTC): the client's error as well.
    @app.exception_handler(StatementError)
    async def _statement_error(request: Request, exc: StatementError) -> JSONResponse:
        if isinstance(exc.orig, OverflowError | ValueError):
            log.info("value out of range on %s %s: %s", request.method, request.url.path,
                     exc.orig)  # fmt: skip
            return JSONResponse(status_code=422, content={"detail": out_of_range_detail()})
        log.error("database statement failed on %s %s", request.method, request.url.path,
                  exc_info=exc)  # fmt: skip
        return JSONResponse(status_code=500, content={"detail": internal_error_detail()})

    @app.exception_handler(DataError)
    async def _data_error(request: Request, exc: DataError) -> JSONResponse:
        log.info("value refused by the database on %s %s: %s", request.method,
                 request.url.path, exc.orig)  # fmt: skip
        return JSONResponse(status_code=422, content={"detail": data_error_detail(exc)})

    # A locked SQLite file (a long store holds the write lock beyond the busy timeout) or a
    # lost PostgreSQL connection is a temporary state of the server: 503 with Retry-After.
    @app.exception_handler(OperationalError)
    async def _busy(request: Request, exc: OperationalError) -> JSONResponse:
        log.warning("database busy on %s %s: %s", request.method, request.url.path, exc.orig)
        busy = database_busy_error()
        return JSONResponse(status_code=503, content={"detail": busy.detail()},
                            headers=busy.headers)  # fmt: skip

    @app.exception_handler(Exception)
    async def _unexpected(request: Request, exc: Exception) -> JSONResponse:
        log.exception("unhandled error on %s %s", request.method, request.url.path)
        return JSONResponse(status_code=500, content={"detail": internal_error_detail()})
