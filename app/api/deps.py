"""FastAPI dependencies: the app's services, a database session, access control."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated

from fastapi import Depends, Query, Request, Security
from fastapi.security import APIKeyHeader, HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy.orm import Session

from app.api.access import Caller
from app.db.models import ApiKey
from app.services.context import AppContext
from app.services.window import Window

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
    header_key: Annotated[str | None, Security(api_key_header)] = None,
    bearer_key: Annotated[HTTPAuthorizationCredentials | None, Security(bearer)] = None,
) -> Caller:
    """The caller, as checked by :class:`app.api.access.AccessMiddleware` before the body.

    The key parameters only document the headers in the OpenAPI document; the decision was
    taken on the headers before FastAPI read the body. Without the middleware's verdict the
    request is refused (fail closed).
    """
    del header_key, bearer_key
    caller = getattr(request.state, "caller", None)
    if not isinstance(caller, Caller):
        raise RuntimeError("the access middleware did not run for this request")
    return caller


CallerDep = Annotated[Caller, Depends(check_access)]


FromM = Annotated[float | None, Query(allow_inf_nan=False, description="From, m (chainage)")]
ToM = Annotated[
    float | None,
    Query(allow_inf_nan=False, description="To, m (chainage); not below from_m (else 422)"),
]


def chainage_window(from_m: FromM = None, to_m: ToM = None) -> Window:
    """``?from_m=&to_m=``: an inclusive window of aligned chainage, either end open (the one
    rule of :class:`app.services.window.Window`: ``to_m`` not before ``from_m``)."""
    return Window(from_m, to_m)


def closed_chainage_window(
    from_m: Annotated[float, Query(allow_inf_nan=False, description="From, m (chainage)")],
    to_m: Annotated[
        float,
        Query(allow_inf_nan=False, description="To, m (chainage); not below from_m (else 422)"),
    ],
) -> Window:
    """``?from_m=&to_m=``, both required (same rule as :func:`chainage_window`)."""
    return Window(from_m, to_m)


WindowDep = Annotated[Window, Depends(chainage_window)]
ClosedWindowDep = Annotated[Window, Depends(closed_chainage_window)]


def caller_name(session: Session, caller: Caller) -> str | None:
    """Who is making a change, for the record: the API key's name (None without a key)."""
    if caller.key_id is None:
        return None
    key = session.get(ApiKey, caller.key_id)
    return key.name if key is not None else f"api key {caller.key_id}"
