"""Answers other than JSON models: CSV downloads (whole or streamed) and their OpenAPI entry."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from fastapi import Response
from fastapi.responses import StreamingResponse

CSV_RESPONSE: dict[int | str, dict[str, Any]] = {
    200: {"content": {"text/csv": {"schema": {"type": "string"}}}}
}
"""``responses=`` of an endpoint that can answer CSV (``?format=csv``)."""


def csv_answer(body: str | Iterator[str], filename: str) -> Response:
    """A CSV attachment: ``body`` whole, or streamed from a generator of lines."""
    headers = {"Content-Disposition": f'attachment; filename="{filename}"'}
    if isinstance(body, str):
        return Response(body, media_type="text/csv", headers=headers)
    return StreamingResponse(body, media_type="text/csv", headers=headers)
