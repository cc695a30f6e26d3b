"""FastAPI dependencies: the app's services, a database session, access control."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Annotated

from fastapi import Depends, Path, Query, Request, Security
from fastapi.security import APIKeyHeader, HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy.orm import Session

from app.api.access import Caller
from app.db.models import ApiKey
from app.schemas.common import CHAINAGE_LIMIT_M
from app.services.context import AppContext
from app.services.views.charts import HEATMAP_MAX_SPAN_M
from app.services.views.window import Window

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


Offset = Annotated[int, Query(ge=0)]
"""``?offset=``: rows of a list skipped before the page."""
Limit = Annotated[int, Query(ge=1, le=1000)]
"""``?limit=``: most rows of a list answered (a page of at most 1000: a client pages through
more)."""


@dataclass(frozen=True)
class Page:
    """A page of a list: ``limit`` rows after the first ``offset``."""

    offset: int
    limit: int


def page(offset: Offset = 0, limit: Limit = 100) -> Page:
    """``?offset=&limit=``: a page of a list (100 rows unless told)."""
    return Page(offset, limit)


PageDep = Annotated[Page, Depends(page)]

RunId = Annotated[int, Path(ge=1, description="Run id")]
CalibrationId = Annotated[int, Path(ge=1, description="Calibration id")]
"""Ids start at 1 (the database's numbering): 0 or a negative id is a malformed request."""

_CHAINAGE = {"ge": -CHAINAGE_LIMIT_M, "le": CHAINAGE_LIMIT_M, "allow_inf_nan": False}
_RANGE = f"within ±{CHAINAGE_LIMIT_M / 1000:,.0f} km"
FROM_DOC = f"From, m (chainage, {_RANGE})"
TO_DOC = f"To, m (chainage, {_RANGE}); not below from_m (else 422)"

FromM = Annotated[float | None, Query(**_CHAINAGE, description=FROM_DOC)]
ToM = Annotated[float | None, Query(**_CHAINAGE, description=TO_DOC)]


def chainage_window(from_m: FromM = None, to_m: ToM = None) -> Window:
    """``?from_m=&to_m=``: an inclusive window of aligned chainage, either end open (the one
    rule of :class:`app.services.views.window.Window`: ``to_m`` not before ``from_m``)."""
    return Window(from_m, to_m)


def closed_chainage_window(
    from_m: Annotated[float, Query(**_CHAINAGE, description=FROM_DOC)],
    to_m: Annotated[
        float,
        Query(
            **_CHAINAGE,
            description=f"{TO_DOC}; at most {HEATMAP_MAX_SPAN_M / 1000:g} km after from_m",
            json_schema_extra={"x-max-span-m": HEATMAP_MAX_SPAN_M},
        ),
    ],
) -> Window:
    """``?from_m=&to_m=``, both required (same rule as :func:`chainage_window`), at most
    :data:`~app.services.views.charts.HEATMAP_MAX_SPAN_M` apart (the span is a rule between
    two parameters, which a schema cannot state: ``x-max-span-m`` names it)."""
    return Window(from_m, to_m)


WindowDep = Annotated[Window, Depends(chainage_window)]
ClosedWindowDep = Annotated[Window, Depends(closed_chainage_window)]


def caller_name(session: Session, caller: Caller) -> str | None:
    """Who is making a change, for the record: the API key's name (None without a key)."""
    if caller.key_id is None:
        return None
    key = session.get(ApiKey, caller.key_id)
    return key.name if key is not None else f"api key {caller.key_id}"
