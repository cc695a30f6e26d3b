"""Access control before the body: read-only mode and API keys, checked on the headers alone.

FastAPI reads (and parses) a request's body before it runs the route's dependencies, so a
check made as a dependency lets an anonymous client make the server read, spool and parse
hundreds of MB before its 401. :class:`AccessMiddleware` decides from the method, the path
and the key headers, and answers 401/403 without receiving a byte of the body.

The key's ``last_used_at`` is stamped at most once per :data:`STAMP_INTERVAL_S` per key and
process, by a background thread in its own short transaction: a keyed read never writes in
its own request, and a busy database delays (or drops) a stamp, never an answer.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import anyio.to_thread
from sqlalchemy import select, update
from sqlalchemy.exc import SQLAlchemyError
from starlette.requests import Request
from starlette.types import ASGIApp, Receive, Scope, Send

from app.core.config import Settings
from app.core.errors import ApiError, database_busy_error, method_not_allowed_error
from app.core.scopes import READ_METHODS, KeyScope, required_scope
from app.core.security import hash_key
from app.db.base import utcnow
from app.db.models import ApiKey
from app.db.session import Database

log = logging.getLogger(__name__)

PROTECTED_PREFIX = "/api/"
"""Paths whose requests go through the access check (the whole API)."""
DOCS_PATHS = frozenset({"/openapi.json", "/docs"})
"""The API's document and its Swagger UI page: checked like reads unless
``settings.public_docs`` (Swagger UI's own script and style files are not checked)."""
STAMP_INTERVAL_S = 60.0
"""A key's ``last_used_at`` is written at most this often per process, s."""


@dataclass(frozen=True)
class Caller:
    """Who sends a request: the API key's id and scopes (None when no key was needed)."""

    key_id: int | None = None
    scopes: frozenset[str] | None = None

    def may(self, scope: KeyScope) -> bool:
        """Whether the caller holds ``scope`` (always, when no key was needed)."""
        return self.scopes is None or scope in self.scopes


def missing_scope_error(scope: KeyScope, what: str) -> ApiError:
    """403 for a key without the scope ``what`` (e.g. ``"DELETE /api/v1/runs/1"``) needs."""
    return ApiError(
        403,
        f"this API key lacks the {scope!r} scope, which {what} needs (the key's scopes are "
        f"set by `python -m app create-key NAME --scopes ...`)",
        field="X-API-Key",
        kind="MissingScope",
        scope=scope,
    )


def key_from_headers(headers: Mapping[str, str]) -> str | None:
    """The API key of a request: ``X-API-Key``, else an ``Authorization: Bearer`` token
    (``headers`` with lower-case names, or Starlette's, which ignore case)."""
    key = headers.get("x-api-key")
    if key:
        return key
    auth = headers.get("authorization", "")
    scheme, _, token = auth.partition(" ")
    if scheme.lower() == "bearer" and token.strip():
        return token.strip()
    return None


def keys_required(settings: Settings, method: str) -> bool:
    """Whether a request with ``method`` needs an API key under ``settings``.

    ``require_api_key_for_reads`` closes reads *and* writes: asking for keys on reads while
    writes stayed open would be a configuration mistake, so it is read as "keys everywhere".
    """
    if method in READ_METHODS:
        return settings.require_api_key_for_reads
    return settings.require_api_key or settings.require_api_key_for_reads


class KeyRegister:
    """API key lookups for one app, with throttled ``last_used_at`` stamps."""

    def __init__(self, db: Database) -> None:
        self.db = db
        self._stamped: dict[int, float] = {}
        self._lock = threading.Lock()
        self._stamper = ThreadPoolExecutor(max_workers=1, thread_name_prefix="key-stamp")

    def lookup(self, key: str) -> Caller | None:
        """The caller holding the valid (known, not revoked) key ``key``, or None."""
        digest = hash_key(key)
        with self.db.session() as s:
            row = s.execute(
                select(ApiKey.id, ApiKey.scopes).where(
                    ApiKey.key_hash == digest, ApiKey.revoked_at.is_(None)
                )
            ).first()
        if row is None:
            return None
        self._maybe_stamp(row.id)
        return Caller(key_id=row.id, scopes=frozenset(row.scopes.split()))

    def _maybe_stamp(self, key_id: int) -> None:
        now = time.monotonic()
        with self._lock:
            last = self._stamped.get(key_id)
            if last is not None and now - last < STAMP_INTERVAL_S:
                return
            self._stamped[key_id] = now
        self._stamper.submit(self._stamp, key_id)

    def _stamp(self, key_id: int) -> None:
        try:
            with self.db.session() as s:
                s.execute(update(ApiKey).where(ApiKey.id == key_id).values(last_used_at=utcnow()))
                s.commit()
        except SQLAlchemyError as exc:  # a busy database: the stamp waits for the next use
            log.info("could not stamp the use of API key %d: %s", key_id, exc)
            with self._lock:
                self._stamped.pop(key_id, None)

    def flush(self) -> None:
        """Wait for the pending stamps (tests, shutdown)."""
        self._stamper.submit(lambda: None).result()

    def close(self) -> None:
        """Stop the stamping thread after the pending stamps."""
        self._stamper.shutdown(wait=True)


def decide(
    settings: Settings, keys: KeyRegister, method: str, headers: dict[str, str], path: str = ""
) -> Caller:
    """The caller of a request, or :class:`ApiError` 401/403 when it may not proceed (403
    also for a key without the scope the method and path need, :mod:`app.core.scopes`)."""
    if method not in READ_METHODS and settings.read_only:
        raise ApiError(403, "this service is read-only: uploads and changes are disabled")
    key = key_from_headers(headers)
    if not keys_required(settings, method):
        return Caller()
    if not key:
        raise ApiError(
            401,
            "an API key is required: send it in the X-API-Key header",
            field="X-API-Key",
            headers={"WWW-Authenticate": "Bearer"},
        )
    caller = keys.lookup(key)
    if caller is None:
        raise ApiError(
            401,
            "the API key is not valid (unknown or revoked)",
            field="X-API-Key",
            headers={"WWW-Authenticate": "Bearer"},
        )
    scope = required_scope(method, path)
    if not caller.may(scope):
        raise missing_scope_error(scope, f"{method} {path}")
    return caller


class AccessMiddleware:
    """Checks access to ``/api/`` on the request line and headers, before any body is read.

    The caller is left in ``scope["state"]["caller"]`` for the routes (see
    :func:`app.api.deps.get_caller`).
    """

    def __init__(self, app: ASGIApp, settings: Settings, keys: KeyRegister) -> None:
        self.app = app
        self.settings = settings
        self.keys = keys

    def _checked(self, path: str) -> bool:
        if path.startswith(PROTECTED_PREFIX):
            return True
        return path in DOCS_PATHS and not self.settings.public_docs

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or not self._checked(scope.get("path", "")):
            await self.app(scope, receive, send)
            return
        method: str = scope["method"]
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope["headers"]}
        try:
            if keys_required(self.settings, method) and key_from_headers(headers):
                caller = await anyio.to_thread.run_sync(
                    decide, self.settings, self.keys, method, headers, scope["path"]
                )
            else:  # no database work: decide here
                caller = decide(self.settings, self.keys, method, headers, scope["path"])
        except ApiError as exc:
            # A method the path does not have is a 405 whoever asks (read-only mode, no key,
            # a key without the scope): what the path serves is in the API's document anyway.
            await _send_error(send, method_not_allowed_error(Request(scope)) or exc)
            return
        except SQLAlchemyError:
            log.warning("API key lookup failed: database unavailable", exc_info=True)
            await _send_error(send, database_busy_error())
            return
        scope.setdefault("state", {})["caller"] = caller
        await self.app(scope, receive, send)


async def _send_error(send: Send, exc: ApiError) -> None:
    payload = json.dumps({"detail": exc.detail()}).encode()
    headers: list[tuple[bytes, bytes]] = [
        (b"content-type", b"application/json"),
        (b"content-length", str(len(payload)).encode()),
        # The body was not read: the connection cannot carry another request.
        (b"connection", b"close"),
    ]
    for k, v in (exc.headers or {}).items():
        headers.append((k.lower().encode("latin-1"), v.encode("latin-1")))
    message: dict[str, Any] = {"type": "http.response.start", "status": exc.status_code}
    message["headers"] = headers
    await send(message)
    await send({"type": "http.response.body", "body": payload})
