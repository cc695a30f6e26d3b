"""Pure ASGI middleware: security headers on every answer, and the request body size limit."""

from __future__ import annotations

import json
import logging
from typing import Any

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from .errors import BodyTooLarge, internal_error_detail, too_large_detail

log = logging.getLogger(__name__)

CSP = (
    "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; "
    "img-src 'self' data: blob:; font-src 'self' data:; connect-src 'self'; "
    "object-src 'none'; base-uri 'self'; form-action 'self'; frame-ancestors 'none'"
)
# Swagger UI starts itself with an inline script.
DOCS_CSP = CSP.replace("script-src 'self'", "script-src 'self' 'unsafe-inline'")

SECURITY_HEADERS = [
    (b"x-content-type-options", b"nosniff"),
    (b"x-frame-options", b"DENY"),
    (b"referrer-policy", b"no-referrer"),
    (b"cross-origin-opener-policy", b"same-origin"),
    (b"cross-origin-resource-policy", b"same-origin"),
    (b"permissions-policy", b"camera=(), microphone=(), geolocation=(), payment=()"),
]


class AnswerStarted:
    """A ``send`` that remembers whether the answer has begun: after its start is sent, an
    error can no longer be answered with a status of its own."""

    def __init__(self, send: Send) -> None:
        self.send = send
        self.started = False

    async def __call__(self, message: Message) -> None:
        if message["type"] == "http.response.start":
            self.started = True
        await self.send(message)


class SecurityHeadersMiddleware:
    """Adds the security headers (and a Content-Security-Policy) to every HTTP answer."""

    def __init__(self, app: ASGIApp, docs_paths: tuple[str, ...] = ("/docs",)) -> None:
        self.app = app
        self.docs_paths = docs_paths

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        path: str = scope.get("path", "")
        csp = DOCS_CSP if path.startswith(self.docs_paths) else CSP

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers: list[tuple[bytes, bytes]] = list(message.get("headers", []))
                present = {k.lower() for k, _ in headers}
                for k, v in SECURITY_HEADERS:
                    if k not in present:
                        headers.append((k, v))
                if b"content-security-policy" not in present:
                    headers.append((b"content-security-policy", csp.encode()))
                message["headers"] = headers
            await send(message)

        tracking_send = AnswerStarted(send_with_headers)

        # Starlette answers an unhandled exception from its outermost layer, outside every
        # middleware: the 500 is sent from here instead, so that it carries the headers too.
        try:
            await self.app(scope, receive, tracking_send)
        except Exception:
            if tracking_send.started:
                raise
            log.exception("unhandled error on %s %s", scope.get("method"), path)
            await _send_error(tracking_send, 500, internal_error_detail())


class BodySizeLimitMiddleware:
    """Refuses request bodies over their route's limit with 413, before anything is stored.

    ``large_paths`` (the run upload) may carry up to ``upload_limit_bytes``; every other body
    (JSON objects, the CSV preview's head of a file) up to ``body_limit_bytes``. A declared
    ``Content-Length`` over the limit is answered at once without reading the body; a body
    without one (chunked) is counted while the app reads it: at the first byte over the limit
    the 413 is sent from here and the app's reading is stopped (:class:`BodyTooLarge` raised
    into it; whatever it answers after that is dropped), so a framework that turns a failed
    read into a 400 cannot hide the 413. The small bodies are read whole (up to their limit)
    before the app sees them: a parser that fails on a malformed first chunk (a multipart form
    of spaces) would otherwise answer 400 or 413 depending on how much had arrived.
    """

    def __init__(
        self,
        app: ASGIApp,
        upload_limit_bytes: int,
        body_limit_bytes: int,
        large_paths: frozenset[str] = frozenset(),
    ) -> None:
        self.app = app
        self.upload_limit_bytes = upload_limit_bytes
        self.body_limit_bytes = body_limit_bytes
        self.large_paths = large_paths

    def limit_for(self, path: str) -> int:
        """The largest body accepted on ``path``, bytes."""
        path = path.rstrip("/") or "/"
        return self.upload_limit_bytes if path in self.large_paths else self.body_limit_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope.get("method") in ("GET", "HEAD", "OPTIONS"):
            await self.app(scope, receive, send)
            return
        limit = self.limit_for(scope.get("path", ""))
        declared = _content_length(scope)
        if declared is not None and declared > limit:
            await _send_413(send, limit)
            return
        if scope.get("path", "") not in self.large_paths:
            await self._whole_body_first(scope, receive, send, limit)
            return
        seen = 0
        refused = False
        sending = AnswerStarted(send)

        async def counting_receive() -> Message:
            nonlocal seen, refused
            if refused:
                raise BodyTooLarge(limit)
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > limit:
                    refused = True
                    if not sending.started:
                        await _send_413(send, limit)
                    raise BodyTooLarge(limit)
            return message

        async def guarded_send(message: Message) -> None:
            if refused:
                return  # the 413 went out already
            await sending(message)

        try:
            await self.app(scope, counting_receive, guarded_send)
        except Exception:
            if not refused:
                raise
            # The app failed on the refused body (after the 413 was sent): nothing to add.

    async def _whole_body_first(
        self, scope: Scope, receive: Receive, send: Send, limit: int
    ) -> None:
        messages: list[Message] = []
        seen = 0
        while True:
            message = await receive()
            messages.append(message)
            if message["type"] != "http.request":
                break
            seen += len(message.get("body", b""))
            if seen > limit:
                await _send_413(send, limit)
                return
            if not message.get("more_body", False):
                break
        pending = iter(messages)

        async def replay() -> Message:
            return next(pending, None) or await receive()

        await self.app(scope, replay, send)


def _content_length(scope: Scope) -> int | None:
    for key, value in scope.get("headers", []):
        if key == b"content-length":
            try:
                return int(value)
            except ValueError:
                return None
    return None


async def _send_error(send: Send, status: int, detail: Any, *, close: bool = False) -> None:
    """Answer ``{"detail": detail}`` as JSON with ``status``; ``close``: and close the
    connection (the rest of the request is not read)."""
    payload = json.dumps({"detail": detail}).encode()
    headers = [
        (b"content-type", b"application/json"),
        (b"content-length", str(len(payload)).encode()),
    ]
    if close:
        headers.append((b"connection", b"close"))
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": payload})


async def _send_413(send: Send, limit: int) -> None:
    await _send_error(send, 413, too_large_detail(limit), close=True)
