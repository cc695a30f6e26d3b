"""Every response model is what is sent.

FastAPI checks an answer against the route's ``response_model`` only when the route returns
data; routes that serialise themselves (``orjson`` for long arrays) return a ``Response`` and
skip the check. Here each such route is listed, asked for a real answer on a track with a run,
a survey and its separation, and the bytes sent are validated against the declared model in
strict mode (a number sent as a string, a float where the model says integer fail), with every
key the model declares and no other: what FastAPI itself would send. A new route that returns
a ``Response`` under a
``response_model`` fails :func:`test_every_self_serialising_route_is_checked` until it is added
to :data:`ANSWERS`.
"""

from __future__ import annotations

import inspect
import types
import typing
from collections.abc import Iterator
from typing import Any

import numpy as np
import orjson
import pytest
from fastapi import Response
from fastapi.routing import APIRoute
from pydantic import BaseModel, TypeAdapter, ValidationError
from starlette.testclient import TestClient

from app.db.models import ALIGNMENT_STATUSES, RUN_STAGES, RUN_STATUSES
from app.main import create_app
from app.schemas.common import AlignmentStatus
from app.schemas.runs import RunStage, RunStatus
from support.app_fixtures import make_settings

from .api_support import upload

TRACK = "answers"

ANSWERS: dict[tuple[str, str], tuple[str, ...]] = {
    ("GET", "/healthz"): ("/healthz",),
    ("GET", "/api/v1/runs/{run_id}/profile"): (
        "/api/v1/runs/{run}/profile",
        "/api/v1/runs/{run}/profile?include=all",
    ),
    ("GET", "/api/v1/runs/{run_id}/soft-spots"): ("/api/v1/runs/{run}/soft-spots",),
    ("GET", "/api/v1/tracks/{track}/profile"): (f"/api/v1/tracks/{TRACK}/profile",),
    ("GET", "/api/v1/tracks/{track}/stiffness"): (f"/api/v1/tracks/{TRACK}/stiffness",),
    ("GET", "/api/v1/tracks/{track}/quality"): (
        f"/api/v1/tracks/{TRACK}/quality",
        f"/api/v1/tracks/{TRACK}/quality?traces=true",
    ),
    ("GET", "/api/v1/tracks/{track}/defects"): (
        f"/api/v1/tracks/{TRACK}/defects",
        f"/api/v1/tracks/{TRACK}/defects?include=history",
    ),
    ("GET", "/api/v1/tracks/{track}/alerts"): (f"/api/v1/tracks/{TRACK}/alerts?since=2000-01-01",),
}
"""The routes whose declared model FastAPI does not check, and requests of each (with and
without the options that add fields)."""


def _may_skip_the_model(annotation: Any) -> bool:
    """Whether a route returning ``annotation`` may hand FastAPI a ``Response`` (or anything)."""
    if annotation is Any or annotation is inspect.Signature.empty:
        return True
    if isinstance(annotation, type):
        return issubclass(annotation, Response)
    if isinstance(annotation, types.UnionType) or typing.get_origin(annotation) is typing.Union:
        return any(_may_skip_the_model(a) for a in typing.get_args(annotation))
    return False


def api_routes(router: Any, prefix: str = "") -> Iterator[tuple[str, APIRoute]]:
    """``(path, route)`` of every operation under ``router``, through included routers (kept
    as routers by FastAPI: the include carries the prefixes above a router's own)."""
    for r in router.routes:
        if isinstance(r, APIRoute):
            yield prefix + r.path, r
        elif hasattr(r, "original_router"):
            yield from api_routes(r.original_router, prefix + r.include_context.prefix)


def self_serialising_routes(app: Any) -> set[tuple[str, str]]:
    """``(method, path)`` of each route with a ``response_model`` that may return a Response."""
    found = set()
    for path, route in api_routes(app.router):
        if route.response_model in (None, Any):  # Any: inferred, none declared
            continue
        returns = inspect.signature(route.endpoint, eval_str=True).return_annotation
        if _may_skip_the_model(returns):
            found |= {(m, path) for m in route.methods}
    return found


def declared_route(app: Any, method: str, path: str) -> APIRoute:
    """The operation ``method path``."""
    (route,) = [r for p, r in api_routes(app.router) if p == path and method in r.methods]
    return route


def key_differences(
    sent: Any, model: Any, where: str = "", *, exclude_none: bool = False
) -> list[str]:
    """Keys of ``sent`` (the JSON answer) that ``model`` (validated from it) does not declare
    (``+path``), and keys it declares that ``sent`` lacks (``-path``: validation fills a
    default in, FastAPI would have sent it), unless the route leaves out None values
    (``exclude_none``, its ``response_model_exclude_none``) and the value is None."""
    if isinstance(model, BaseModel) and isinstance(sent, dict):
        fields = type(model).model_fields
        out = [f"+{where}.{k}" for k in sent if k not in fields]
        out += [
            f"-{where}.{k}"
            for k in fields
            if k not in sent and not (exclude_none and getattr(model, k) is None)
        ]
        for k, v in sent.items():
            if k in fields:
                out += key_differences(
                    v, getattr(model, k), f"{where}.{k}", exclude_none=exclude_none
                )
        return out
    if isinstance(sent, list) and isinstance(model, list):
        return [
            e
            for i, (s, m) in enumerate(zip(sent, model, strict=True))
            for e in key_differences(s, m, f"{where}[{i}]", exclude_none=exclude_none)
        ]  # noqa: E501
    if isinstance(sent, dict) and isinstance(model, dict):
        return [
            e
            for k in sent
            for e in key_differences(
                sent[k], model.get(k), f"{where}.{k}", exclude_none=exclude_none
            )
        ]
    return []


def test_the_key_check_finds_an_undeclared_or_missing_key() -> None:
    """The check itself: a key the model does not declare and a declared one left out (it has
    a default, so validation alone passes), also inside a list, are named."""

    class Item(BaseModel):
        a: int
        note: str | None = None

    class Page(BaseModel):
        data: list[Item]

    sent = {"data": [{"a": 1, "note": None}, {"a": 2, "b": 3}], "count": 2}
    model = TypeAdapter(Page).validate_json(orjson.dumps(sent), strict=True)
    assert key_differences(sent, model) == ["+.count", "+.data[1].b", "-.data[1].note"]
    # a route that leaves out None values (response_model_exclude_none) may omit a None
    assert key_differences(sent, model, exclude_none=True) == ["+.count", "+.data[1].b"]


def test_strict_validation_refuses_what_lax_validation_coerces() -> None:
    """Why the answer is validated strictly: a number sent as a string, or a float under an
    integer field, is a wrong type that lax validation would quietly accept."""

    class Counted(BaseModel):
        n: int
        level_mm: float

    for wrong in ({"n": 2.0, "level_mm": 1.5}, {"n": 2, "level_mm": "1.5"}):
        TypeAdapter(Counted).validate_json(orjson.dumps(wrong))  # lax: accepted
        with pytest.raises(ValidationError):
            TypeAdapter(Counted).validate_json(orjson.dumps(wrong), strict=True)


def test_declared_states_are_the_stored_ones() -> None:
    """The states an answer declares (its ``Literal`` types) are those the database keeps: a
    state added to one side only would be refused on the way out, or never reached."""
    assert typing.get_args(AlignmentStatus) == ALIGNMENT_STATUSES
    assert typing.get_args(RunStatus) == RUN_STATUSES
    assert typing.get_args(RunStage) == RUN_STAGES


@pytest.mark.slow  # the module's app, run and survey: ~8 s, paid by the first test
def test_every_self_serialising_route_is_checked(answered: tuple[TestClient, int]) -> None:
    """The routes that may bypass their model are exactly those this module asks (the asking
    finds the paths real: a wrong one is answered 404)."""
    assert self_serialising_routes(answered[0].app) == set(ANSWERS)


@pytest.fixture(scope="module")
def answered(
    tmp_path_factory: pytest.TempPathFactory, synthetic_run: dict[str, Any]
) -> Iterator[tuple[TestClient, int]]:  # noqa: E501
    """An app with one run on TRACK and a survey of it at another wheel load (separable)."""
    with TestClient(create_app(make_settings(tmp_path_factory.mktemp("answers")))) as c:
        r = upload(
            c, synthetic_run["csv"], track=TRACK, start_chainage_m=synthetic_run["start_chainage_m"]
        )  # noqa: E501
        assert r.status_code == 201, r.text
        run_id = r.json()["id"]
        prof = c.get(f"/api/v1/runs/{run_id}/profile").json()
        y = np.array([np.nan if v is None else v for v in prof["level_mm"]])
        ok = np.isfinite(y)
        rows = [
            f"{a:.3f},{b:.5f}"
            for a, b in zip(np.asarray(prof["chainage_m"])[ok], y[ok], strict=True)
        ]  # noqa: E501
        survey = "chainage_m,level_mm\n" + "\n".join(rows) + "\n"
        s = c.post(f"/api/v1/tracks/{TRACK}/surveys", json={"csv": survey, "wheel_load_n": 150_000})
        assert s.status_code == 201, s.text
        yield c, run_id


@pytest.mark.slow
@pytest.mark.dialect
@pytest.mark.parametrize("route", sorted(ANSWERS), ids=lambda r: f"{r[0]} {r[1]}")
def test_the_answer_is_the_declared_model(
    answered: tuple[TestClient, int], route: tuple[str, str]
) -> None:  # noqa: E501
    """The bytes of the real answer validate strictly against the route's response model, with
    exactly the keys the model declares."""
    client, run_id = answered
    declared = declared_route(client.app, *route)
    for url in ANSWERS[route]:
        r = client.get(url.format(run=run_id))
        assert r.status_code == 200, r.text
        sent = r.json()
        assert sent, f"an empty answer to {url} checks nothing"
        validated = TypeAdapter(declared.response_model).validate_json(r.content, strict=True)
        differences = key_differences(
            sent, validated, exclude_none=declared.response_model_exclude_none
        )
        assert differences == [], url
