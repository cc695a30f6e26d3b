"""Runs: upload (multipart CSV or JSON), list, read, delete; profile, soft spots, signals."""

from __future__ import annotations

import asyncio
import dataclasses
import time
from typing import Annotated, Any

import orjson
from fastapi import APIRouter, Header, Query, Request, Response
from fastapi.concurrency import run_in_threadpool
from pydantic import BaseModel, ValidationError

from app.api import uploads
from app.api.access import key_from_headers
from app.api.answers import Format, add_csv_twin, csv_answer
from app.api.convert import run_public
from app.api.deps import CallerDep, CtxDep, Limit, Offset, RunId, SessionDep, WindowDep
from app.api.uploads import JSON, MULTIPART
from app.schemas.common import Timestamp
from app.schemas.runs import (
    ProfilePublic,
    RunColumns,
    RunCreated,
    RunCreateJson,
    RunPublic,
    RunsPublic,
    RunStatus,
    RunUploadForm,
    SignalsPublic,
    SoftSpotPublic,
)
from app.services.context import AppContext
from app.services.errors import Malformed
from app.services.lookup import get_track
from app.services.run_lifecycle import intake
from app.services.run_lifecycle import stored_runs as runs
from app.services.run_lifecycle.accept import submit
from app.services.run_lifecycle.intake import Submission, ignored_options
from app.services.run_lifecycle.json_log import has_columns, split_json_columns
from app.services.views import exports

router = APIRouter(prefix="/runs", tags=["runs"])

SEND = f"{MULTIPART} (a file upload) or {JSON}"
"""What a run upload may be sent as (named when another content type comes)."""

IdempotencyKey = Annotated[
    str | None,
    Header(
        alias="Idempotency-Key",
        max_length=200,
        description="Resending a request with the same key returns the run stored the first time",
    ),
]


def _upload_form_schema() -> dict[str, Any]:
    schema = RunUploadForm.model_json_schema()
    schema["properties"] = {
        "file": {
            "type": "string",
            "format": "binary",
            "description": "The run log: CSV (plain or gzip), canonical or raw IMU columns",
        },
        **schema["properties"],
    }
    schema["required"] = ["file"]
    schema.pop("title", None)
    return schema


RUN_BODY_DOC: dict[str, Any] = {
    "requestBody": {
        "required": True,
        "description": "Either a multipart upload (``file`` plus form fields) or a JSON body "
        "carrying the CSV text (``csv``) or canonical SI arrays (``columns``).",
        "content": {
            "multipart/form-data": {"schema": _upload_form_schema()},
            "application/json": {"schema": {"$ref": "#/components/schemas/RunCreateJson"}},
        },
    }
}


def _from_multipart(
    fields: dict[str, Any], body: bytearray, filename: str | None, key: str | None,
    max_bytes: int,
) -> Submission:  # fmt: skip
    meta = uploads.validated(RunUploadForm, RunUploadForm.from_form(fields))
    return intake.from_upload(meta, body, filename, key, max_bytes)


def _from_json(
    body: bytes | bytearray, key: str | None, max_rest_bytes: int, max_bytes: int
) -> Submission:
    if not body or body.isspace():  # (not strip(): a copy of the whole body)
        raise Malformed("the request body is empty: send a JSON object or a multipart upload")
    arrays: dict[str, Any] = {}
    if has_columns(body):
        body, arrays = split_json_columns(body, RunColumns.model_fields, max_rest_bytes)
    try:
        meta = RunCreateJson.model_validate_json(body)
    except ValidationError as exc:
        if any(e.get("type") == "json_invalid" for e in exc.errors()):
            raise Malformed("the request body is not valid JSON", **_facts(exc)) from None
        raise uploads.validation_error(exc) from None
    columns = None if meta.columns is None else meta.columns.model_dump() | arrays
    return intake.from_json(meta, columns, key, max_bytes)


def _facts(exc: ValidationError) -> dict[str, Any]:
    err = exc.errors(include_url=False, include_input=False)[0]
    return {"errors": [{"loc": list(err["loc"]), "msg": err["msg"], "type": err["type"]}]}


def load_run_public(ctx: AppContext, run_id: int) -> RunPublic:
    """A run's public view, read fresh from the database."""
    with ctx.db.session() as s:
        return run_public(runs.get_run(s, run_id))


def _ignored(ctx: AppContext, run_id: int, sub: Submission) -> list[str]:
    with ctx.db.session() as s:
        return ignored_options(s, run_id, sub)


async def answer_submission(
    ctx: AppContext,
    response: Response,
    run_id: int,
    created: bool,
    wait: bool,
    ignored: list[str] | None = None,
) -> RunCreated:
    """Status code and body of an accepted run: 201 stored, 202 processing, 200 repeated
    (with the fields a repeat asked differently, not applied)."""
    public = await run_in_threadpool(load_run_public, ctx, run_id)
    if wait and public.status == "processing":
        deadline = time.monotonic() + ctx.settings.wait_timeout_s
        while public.status == "processing" and time.monotonic() < deadline:
            await asyncio.sleep(0.1)
            public = await run_in_threadpool(load_run_public, ctx, run_id)
    if not created:
        response.status_code = 200
    else:
        response.status_code = 202 if public.status == "processing" else 201
    note = None
    if ignored:
        note = (
            f"This log is already stored as run {run_id}; a log is one pass, so it was not "
            f"stored again and {', '.join(ignored)} of this upload "
            f"{'was' if len(ignored) == 1 else 'were'} not applied. To read it differently, "
            f"delete run {run_id} and upload the log again."
        )
    return RunCreated(
        **public.model_dump(), duplicate=not created, ignored=ignored or [], note=note
    )


def submission_responses(model: type[BaseModel], repeated: str) -> dict[int | str, Any]:
    """The answers of a route that submits a run (see :func:`answer_submission`), documented
    with their ``model``; ``repeated`` says when the same submission is answered 200."""
    return {
        200: {"model": model, "description": repeated},
        201: {"model": model, "description": "Processed and stored"},
        202: {"model": model, "description": "Accepted; the background worker processes it"},
    }


@router.post(
    "",
    response_model=RunCreated,
    status_code=202,
    openapi_extra=RUN_BODY_DOC,
    responses=submission_responses(RunCreated, "Already stored (same content or key)"),
)
async def create_run(
    request: Request,
    response: Response,
    ctx: CtxDep,
    caller: CallerDep,
    idempotency_key: IdempotencyKey = None,
    wait: Annotated[
        bool, Query(description="Wait (up to TRACKPROFILE_WAIT_TIMEOUT_S) for the result")
    ] = False,
) -> RunCreated:
    """Upload a run log; it is checked now and inverted now (short logs) or in the background.

    **multipart/form-data**: ``file`` (CSV, plain or gzip) and the fields of the upload form:
    ``track`` (name; created if new) or ``track_id``, ``vehicle`` (default ``table1``),
    ``start_chainage_m``, ``direction``, ``recorded_at``, ``name`` and the column/unit
    options (``time_column`` ... ``gravity``).

    **application/json**: the same fields, plus ``csv`` (the CSV text, read like an upload) or
    ``columns`` (canonical SI arrays ``time_s``, ``accel_z_mps2``, ``pitch_rate_radps``,
    ``speed_mps`` and/or ``chainage_m``).

    A log that cannot be read or inverted is answered 422 naming the field, column, row or
    unit, and nothing is stored.
    """
    owner = caller.key_id
    sent = key_from_headers(request.headers)
    if idempotency_key is not None and owner is None and sent:
        # Keys are not required here, but a client that names itself by a valid key has
        # Idempotency-Keys of its own, as it would where keys are required.
        known = await run_in_threadpool(request.app.state.keys.lookup, sent)
        owner = known.key_id if known is not None else None
    limits = ctx.settings
    if uploads.content_type(request, (MULTIPART, JSON), SEND) == MULTIPART:
        form = await uploads.read_file_form(request, what="the run log", max_fields=64)
        sub = await run_in_threadpool(
            _from_multipart, form.fields, form.data, form.filename, idempotency_key,
            limits.max_upload_bytes,
        )  # fmt: skip
        del form
    else:
        body = await uploads.read_body(request)
        sub = await run_in_threadpool(
            _from_json, body, idempotency_key, limits.max_body_bytes, limits.max_upload_bytes
        )
        del body
    sub.idempotency_owner = owner
    run_id, created = await run_in_threadpool(submit, ctx, sub)
    ignored = [] if created else await run_in_threadpool(_ignored, ctx, run_id, sub)
    del sub
    return await answer_submission(ctx, response, run_id, created, wait, ignored)


@router.get("", response_model=RunsPublic)
def list_runs(
    session: SessionDep,
    track: Annotated[str | None, Query(description="Track id or name")] = None,
    status: Annotated[RunStatus | None, Query()] = None,
    recorded_from: Annotated[Timestamp | None, Query(description="Recorded at or after")] = None,
    recorded_to: Annotated[Timestamp | None, Query(description="Recorded at or before")] = None,
    offset: Offset = 0,
    limit: Limit = 50,
) -> RunsPublic:
    """Runs, newest recording first; filter by track, status and recording time."""
    rows, count = runs.list_runs(
        session,
        track_id=None if track is None else get_track(session, track).id,
        status=status,
        recorded_from=recorded_from,
        recorded_to=recorded_to,
        offset=offset,
        limit=limit,
    )
    return RunsPublic(data=[run_public(r) for r in rows], count=count)


@router.get("/{run_id}", response_model=RunPublic)
def read_run(session: SessionDep, run_id: RunId) -> RunPublic:
    """A run's status, metadata, quality indicators and error."""
    return run_public(runs.get_run(session, run_id))


@router.delete("/{run_id}", status_code=204, response_class=Response)
def delete_run(session: SessionDep, run_id: RunId) -> Response:
    """Delete a run with its profile, soft spots and signals (also while it processes).

    The track's aggregated profile is recomputed without it in the same transaction.
    """
    runs.delete_run(session, runs.get_run(session, run_id))
    session.commit()
    return Response(status_code=204)


INCLUDE_DOC: dict[str, Any] = {
    "parameters": [
        {
            "name": "include",
            "in": "query",
            "required": False,
            # comma-separated (?include=front_level_mm,rear_level_mm): form style, not exploded
            "style": "form",
            "explode": False,
            "description": "Extra arrays: each axle's level and wheel force (N), the baseline, "
            "or all",
            "schema": {
                "type": "array",
                "minItems": 1,
                "items": {"type": "string", "enum": ["all", *runs.EXTRA_PROFILE_COLUMNS]},
            },
        }
    ]
}
"""``include`` as the OpenAPI document states it: a comma-separated list of closed names
(FastAPI cannot state a list that is not exploded; the route reads the text)."""


@router.get(
    "/{run_id}/profile",
    response_model=ProfilePublic,
    response_model_exclude_none=True,
    openapi_extra=INCLUDE_DOC,
)
def read_run_profile(
    ctx: CtxDep,
    session: SessionDep,
    run_id: RunId,
    window: WindowDep,
    include: Annotated[str | None, Query(include_in_schema=False)] = None,
    format: Format = "json",
) -> Response:
    """The fused loaded profile on chainage: ``{"chainage_m": [...], "level_mm": [...]}``.

    Levels in mm, positive up (null where there is no data); chainage in m, aligned (the run's
    ``chainage_offset_m`` added). ``?from_m=&to_m=`` selects a window (inclusive) with one
    indexed query; ``?include=all`` adds each axle's level, the baseline the soft spots are
    measured from and each axle's wheel force (static + dynamic, N); the ``.csv`` twin
    answers ``chainage_m,level_mm[,...]`` as CSV.
    """
    names = [] if include is None else [n.strip() for n in include.split(",")]
    columns = ("chainage_m", "level_mm", *runs.included_columns(names))
    run = runs.detail_run(session, run_id, "profile")
    if format == "csv":
        csv = exports.run_profile_csv(ctx, run, window, columns)
        return csv_answer(csv, f"run-{run_id}-profile.csv")
    payload = runs.profile_window(session, run, window, columns)
    return Response(orjson.dumps(payload), media_type="application/json")


@router.get(
    "/{run_id}/soft-spots",
    response_model=list[SoftSpotPublic],
)
def read_run_soft_spots(
    session: SessionDep,
    run_id: RunId,
    format: Format = "json",
) -> Any:
    """Soft spots along chainage: extent and peak (m), depth (mm), stiffness loss (%)."""
    spots = runs.soft_spots(session, runs.done_run(session, run_id, "soft spots"))
    if format == "csv":
        return csv_answer(exports.soft_spots_csv(spots), f"run-{run_id}-soft-spots.csv")
    return [SoftSpotPublic(**dataclasses.asdict(p)) for p in spots]


@router.get("/{run_id}/signals", response_model=SignalsPublic)
def read_run_signals(session: SessionDep, run_id: RunId) -> SignalsPublic:
    """The raw signals against time (decimated to at most 5000 points, min/max envelope)."""
    run = runs.get_run(session, run_id)
    sig = runs.signals(session, run)
    d = runs.signal_data(sig)
    return SignalsPublic(
        run_id=run_id,
        n_samples=run.n_samples,
        decimated=sig.decimated,
        time_s=d["time_s"],
        accel_z_mps2=d["accel_z_mps2"],
        pitch_rate_radps=d["pitch_rate_radps"],
        speed_mps=d["speed_mps"],
    )


add_csv_twin(router, "/{run_id}/profile", read_run_profile, INCLUDE_DOC)
add_csv_twin(router, "/{run_id}/soft-spots", read_run_soft_spots)
