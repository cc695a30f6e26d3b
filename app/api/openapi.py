"""The OpenAPI document as served: what FastAPI generates, made to tell the truth.

* security as configured (none, or a key in ``X-API-Key`` or as a bearer token);
* error answers declared as JSON everywhere (FastAPI gives the HTML report's and the CSV
  downloads' errors the route's own media type);
* integers below 2^63 (ids, offsets and limits are 64-bit in the database);
* the JSON bodies of the routes that read them by hand (uploads) in the components.

Operation ids are the route functions' names (``create_run``, ``read_track``...), set by
:func:`operation_id` when the app is built.
"""

from __future__ import annotations

from typing import Any

from fastapi.routing import APIRoute
from pydantic import BaseModel
from pydantic.json_schema import models_json_schema

from app.api.access import keys_required
from app.core.config import Settings

INT64_MAX = 2**63 - 1
"""Largest integer the database holds (ids, offsets, limits)."""

ERROR_REF = {"$ref": "#/components/schemas/ErrorResponse"}


def operation_id(route: APIRoute) -> str:
    """A stable, readable operation id: the route function's name (unique in the app)."""
    return route.name


def add_body_models(schema: dict[str, Any], models: list[type[BaseModel]]) -> None:
    """Add the schemas of bodies documented by hand (``openapi_extra``) to the components."""
    _, defs = models_json_schema(
        [(m, "validation") for m in models], ref_template="#/components/schemas/{model}"
    )
    schema.setdefault("components", {}).setdefault("schemas", {}).update(defs["$defs"])


def security_as_configured(schema: dict[str, Any], settings: Settings) -> None:
    """State on each operation the key this configuration asks for (none, or a key in
    X-API-Key or as a bearer token), instead of FastAPI's "a key, always"."""
    for _path, method, op in _operations(schema):
        if "security" not in op:
            continue
        if keys_required(settings, method.upper()):
            op["security"] = [{"APIKeyHeader": []}, {"HTTPBearer": []}]
        else:
            del op["security"]
    if not (settings.require_api_key or settings.require_api_key_for_reads):
        schema.get("components", {}).pop("securitySchemes", None)


def errors_as_json(schema: dict[str, Any]) -> None:
    """Every 4xx/5xx answer is ``{"detail": {...}}`` JSON, whatever the route's success type."""
    for _path, _method, op in _operations(schema):
        for code, response in op.get("responses", {}).items():
            if str(code)[:1] in ("4", "5") and isinstance(response, dict):
                response["content"] = {"application/json": {"schema": ERROR_REF}}


def bounded_integers(node: Any) -> None:
    """Give every integer without a maximum the 64-bit one (in place, recursively)."""
    if isinstance(node, dict):
        if node.get("type") == "integer" and "maximum" not in node:
            node["maximum"] = INT64_MAX
        for value in node.values():
            bounded_integers(value)
    elif isinstance(node, list):
        for value in node:
            bounded_integers(value)


def _operations(schema: dict[str, Any]) -> list[tuple[str, str, dict[str, Any]]]:
    return [
        (path, method, op)
        for path, item in schema.get("paths", {}).items()
        for method, op in item.items()
        if isinstance(op, dict) and method != "parameters"
    ]
