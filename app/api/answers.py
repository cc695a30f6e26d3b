"""Answers other than JSON models: CSV downloads (whole or streamed) and their operations.

Each resource that can be downloaded as CSV has two operations: the JSON one
(``GET /runs/{id}/profile``) and its CSV twin (``GET /runs/{id}/profile.csv``, answering
``text/csv`` only), so that a client generated from the OpenAPI document can tell the two
answers apart. The JSON operation still takes ``?format=csv`` (links made before the twins
existed), left out of the document.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Iterator
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query, Response
from fastapi.responses import StreamingResponse

Format = Annotated[Literal["json", "csv"], Query(include_in_schema=False)]
"""``?format=json|csv`` of a JSON operation with a CSV twin (undocumented: use the twin)."""


class CsvResponse(Response):
    """A CSV answer (``text/csv``): the media type the OpenAPI document declares."""

    media_type = "text/csv"


def csv_answer(body: str | Iterator[str], filename: str) -> Response:
    """A CSV attachment: ``body`` whole, or streamed from a generator of lines."""
    headers = {"Content-Disposition": f'attachment; filename="{filename}"'}
    if isinstance(body, str):
        return Response(body, media_type="text/csv", headers=headers)
    return StreamingResponse(body, media_type="text/csv", headers=headers)


def add_csv_twin(
    router: APIRouter,
    path: str,
    endpoint: Callable[..., Response],
    openapi_extra: dict[str, Any] | None = None,
) -> None:
    """Register ``GET <path>.csv``: ``endpoint`` (which takes ``format``) answering CSV.

    The twin takes the endpoint's other parameters (and the endpoint's ``openapi_extra``,
    for parameters documented by hand); its operation id is the endpoint's name with
    ``_csv``.
    """
    sig = inspect.signature(endpoint, eval_str=True)
    params = [p for name, p in sig.parameters.items() if name != "format"]

    @functools.wraps(endpoint)
    def twin(**kwargs: Any) -> Response:
        return endpoint(**kwargs, format="csv")

    twin.__signature__ = sig.replace(parameters=params)  # type: ignore[attr-defined]
    doc = inspect.getdoc(endpoint) or ""
    router.add_api_route(
        f"{path}.csv",
        twin,
        methods=["GET"],
        name=f"{endpoint.__name__}_csv",
        response_class=CsvResponse,
        summary=f"{endpoint.__name__.replace('_', ' ').capitalize()} (CSV)",
        description=f"The CSV form of `GET {router.prefix}{path}`.\n\n{doc}",
        responses={200: {"description": "CSV text (`text/csv`)"}},
        openapi_extra=openapi_extra,
    )
