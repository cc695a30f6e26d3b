"""FastAPI dependencies: the app's services, a database session, access control."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated

from fastapi import Depends, Request, Security
from fastapi.security import APIKeyHeader, HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy import select, update
from sqlalchemy.orm import Session

from app.core.errors import ApiError
from app.core.security import hash_key
from app.db.base import utcnow
from app.db.models import ApiKey
from app.services.context import AppContext

READ_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})

api_key_header = APIKeyHeader(name="X-API-Key", auto_error=False, description="Pipeline API key")
bearer = HTTPBearer(auto_error=False, description="The API key as a bearer token")


def get_ctx(request: Request) -> AppContext:
    """The services of the app handling the request."""
    ctx: AppContext = request.app.state.ctx
    return ctx


CtxDep = Annotated[AppContext, Depends(get_ctx)]


def get_session(ctx: CtxDep) -> Iterator[Session]:
    """A database session for the request, closed afterwards."""
    with ctx.db.session() as session:
        yield session


SessionDep = Annotated[Session, Depends(get_session)]


def check_access(
    request: Request,
    ctx: CtxDep,
    header_key: Annotated[str | None, Security(api_key_header)] = None,
    bearer_key: Annotated[HTTPAuthorizationCredentials | None, Security(bearer)] = None,
) -> None:
    """Enforce read-only mode and, when configured, API keys (writes; reads if asked)."""
    settings = ctx.settings
    is_read = request.method in READ_METHODS
    if not is_read and settings.read_only:
        raise ApiError(403, "this service is read-only: uploads and changes are disabled")
    if not settings.require_api_key or (is_read and not settings.require_api_key_for_reads):
        return
    key = header_key or (bearer_key.credentials if bearer_key else None)
    if not key:
        raise ApiError(
            401,
            "an API key is required: send it in the X-API-Key header",
            field="X-API-Key",
            headers={"WWW-Authenticate": "Bearer"},
        )
    digest = hash_key(key)
    with ctx.db.session() as s:
        row = s.scalar(select(ApiKey).where(ApiKey.key_hash == digest, ApiKey.revoked_at.is_(None)))
        if row is None:
            raise ApiError(
                401,
                "the API key is not valid (unknown or revoked)",
                field="X-API-Key",
                headers={"WWW-Authenticate": "Bearer"},
            )
        s.execute(update(ApiKey).where(ApiKey.id == row.id).values(last_used_at=utcnow()))
        s.commit()
