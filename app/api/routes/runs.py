"""Runs: upload (multipart CSV or JSON), list, read, delete; profile, soft spots, signals."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Iterator
from datetime import datetime
from typing import Annotated, Any, Literal

import orjson
from fastapi import APIRouter, Header, Query, Request, Response
from fastapi.concurrency import run_in_threadpool
from fastapi.exceptions import RequestValidationError
from fastapi.responses import StreamingResponse
from pydantic import ValidationError
from sqlalchemy import func, select
from sqlalchemy.orm import Session
from starlette.datastructures import UploadFile

from app.api.convert import run_public
from app.api.deps import CtxDep, SessionDep
from app.core.errors import ApiError
from app.db.models import Run, RunSignals, SoftSpot
from app.schemas.runs import (
    ProfilePublic,
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
from app.services.integrate import remove_run_from_track
from app.services.logs import hash_columns, log_from_columns, parse_csv, sha256_hex
from app.services.profiles import PROFILE_COLUMNS, iter_profile_rows, read_profile
from app.services.submit import Submission, submit

from .lookup import get_track

router = APIRouter(prefix="/runs", tags=["runs"])

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


def _validate(model: type[RunUploadForm], data: Any) -> RunUploadForm:
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise RequestValidationError(exc.errors(include_url=False, include_input=False)) from None


def _submission(
    meta: RunUploadForm, *, source: str, content_hash: str, filename: str | None,
    key: str | None, log: Any, options: dict[str, Any],
) -> Submission:  # fmt: skip
    return Submission(
        log=log,
        source=source,
        content_hash=content_hash,
        track=meta.track,
        track_id=meta.track_id,
        vehicle=meta.vehicle,
        vehicle_id=meta.vehicle_id,
        name=meta.name,
        start_chainage_m=meta.start_chainage_m,
        direction=meta.direction,
        recorded_at=meta.recorded_at,
        filename=filename,
        idempotency_key=key,
        options=options,
    )


def _from_multipart(
    fields: dict[str, Any], data: bytes, filename: str | None, key: str | None, max_bytes: int
) -> Submission:
    meta = _validate(RunUploadForm, fields)
    options = meta.csv_options()
    log = parse_csv(data, options, max_bytes=max_bytes)
    return _submission(
        meta, source="upload", content_hash=sha256_hex(data), filename=filename, key=key,
        log=log, options={"csv": options},
    )  # fmt: skip


def _from_json(body: bytes, key: str | None) -> Submission:
    if not body.strip():
        raise ApiError(400, "the request body is empty: send a JSON object or a multipart upload")
    try:
        meta = RunCreateJson.model_validate_json(body)
    except ValidationError as exc:
        if any(e.get("type") == "json_invalid" for e in exc.errors()):
            raise ApiError(400, "the request body is not valid JSON", **_facts(exc)) from None
        raise RequestValidationError(exc.errors(include_url=False, include_input=False)) from None
    if meta.csv is not None:
        options = meta.csv_options()
        data = meta.csv.encode("utf-8")
        log = parse_csv(data, options, field="csv")
        return _submission(
            meta, source="json", content_hash=sha256_hex(data), filename=meta.filename, key=key,
            log=log, options={"csv": options},
        )  # fmt: skip
    assert meta.columns is not None
    log = log_from_columns(meta.columns.model_dump())
    return _submission(
        meta, source="json", content_hash=hash_columns(log), filename=meta.filename, key=key,
        log=log, options={"columns": True},
    )  # fmt: skip


def _facts(exc: ValidationError) -> dict[str, Any]:
    err = exc.errors(include_url=False, include_input=False)[0]
    return {"errors": [{"loc": list(err["loc"]), "msg": err["msg"], "type": err["type"]}]}


def load_run_public(ctx: AppContext, run_id: int) -> RunPublic:
    """A run's public view, read fresh from the database."""
    with ctx.db.session() as s:
        run = s.get(Run, run_id)
        if run is None:
            raise ApiError(404, f"run {run_id} not found", field="run_id")
        return run_public(run)


async def answer_submission(
    ctx: AppContext, response: Response, run_id: int, created: bool, wait: bool
) -> RunCreated:
    """Status code and body of an accepted run: 201 stored, 202 processing, 200 repeated."""
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
    return RunCreated(**public.model_dump(), duplicate=not created)


@router.post(
    "",
    response_model=RunCreated,
    status_code=202,
    openapi_extra=RUN_BODY_DOC,
    responses={
        200: {"model": RunCreated, "description": "Already stored (same content or key)"},
        201: {"model": RunCreated, "description": "Processed and stored"},
        202: {"model": RunCreated, "description": "Accepted; the background worker processes it"},
    },
)
async def create_run(
    request: Request,
    response: Response,
    ctx: CtxDep,
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
    ctype = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if ctype == "multipart/form-data":
        async with request.form(max_files=1, max_fields=64) as form:
            upload = form.get("file")
            if upload is None:
                raise ApiError(422, "the upload has no 'file' part (the run log)", field="file")
            if not isinstance(upload, UploadFile):
                raise ApiError(422, "'file' must be a file, not a text field", field="file")
            data = await upload.read()
            filename = upload.filename
            fields = {k: v for k, v in form.multi_items() if k != "file"}
            extra_files = [k for k, v in fields.items() if not isinstance(v, str)]
            if extra_files:
                raise ApiError(
                    422, f"unexpected file part {extra_files[0]!r}", field=extra_files[0]
                )
        sub = await run_in_threadpool(
            _from_multipart, fields, data, filename, idempotency_key,
            ctx.settings.max_upload_bytes,
        )  # fmt: skip
        del data
    elif ctype == "application/json":
        body = await request.body()
        sub = await run_in_threadpool(_from_json, body, idempotency_key)
        del body
    else:
        raise ApiError(
            415,
            f"unsupported content type {ctype or '(none)'!r}: send multipart/form-data (a file "
            "upload) or application/json",
            field="Content-Type",
        )
    run_id, created = await run_in_threadpool(submit, ctx, sub)
    del sub
    return await answer_submission(ctx, response, run_id, created, wait)


@router.get("", response_model=RunsPublic)
def list_runs(
    session: SessionDep,
    track: Annotated[str | None, Query(description="Track id or name")] = None,
    status: Annotated[RunStatus | None, Query()] = None,
    recorded_from: Annotated[datetime | None, Query(description="Recorded at or after")] = None,
    recorded_to: Annotated[datetime | None, Query(description="Recorded at or before")] = None,
    offset: Annotated[int, Query(ge=0)] = 0,
    limit: Annotated[int, Query(ge=1, le=1000)] = 50,
) -> RunsPublic:
    """Runs, newest recording first; filter by track, status and recording time."""
    conds = []
    if track is not None:
        conds.append(Run.track_id == get_track(session, track).id)
    if status is not None:
        conds.append(Run.status == status)
    if recorded_from is not None:
        conds.append(Run.recorded_at >= recorded_from)
    if recorded_to is not None:
        conds.append(Run.recorded_at <= recorded_to)
    count = session.scalar(select(func.count()).select_from(Run).where(*conds)) or 0
    when = func.coalesce(Run.recorded_at, Run.created_at)
    rows = session.scalars(
        select(Run).where(*conds).order_by(when.desc(), Run.id.desc()).offset(offset).limit(limit)
    ).all()
    return RunsPublic(data=[run_public(r) for r in rows], count=count)


def _get_run(session: Session, run_id: int) -> Run:
    run = session.get(Run, run_id)
    if run is None:
        raise ApiError(404, f"run {run_id} not found", field="run_id")
    return run


def _require_done(run: Run, what: str) -> None:
    if run.status == "processing":
        raise ApiError(
            409, f"run {run.id} is still processing; its {what} is not available yet",
            status=run.status,
        )  # fmt: skip
    if run.status == "failed":
        msg = (run.error or {}).get("message", "unknown error")
        raise ApiError(409, f"run {run.id} failed ({msg}); it has no {what}", status=run.status)


@router.get("/{run_id}", response_model=RunPublic)
def read_run(session: SessionDep, run_id: int) -> RunPublic:
    """A run's status, metadata, quality indicators and error."""
    return run_public(_get_run(session, run_id))


@router.delete("/{run_id}", status_code=204, response_class=Response)
def delete_run(session: SessionDep, run_id: int) -> Response:
    """Delete a run with its profile, soft spots and signals (also while it processes).

    The track's aggregated profile is recomputed without it in the same transaction.
    """
    run = _get_run(session, run_id)
    remove_run_from_track(session, run)
    session.delete(run)
    session.commit()
    return Response(status_code=204)


def _window(
    run: Run, from_m: float | None, to_m: float | None
) -> tuple[float | None, float | None]:
    if from_m is not None and to_m is not None and to_m < from_m:
        raise ApiError(422, f"to_m ({to_m} m) is before from_m ({from_m} m)", field="to_m")
    off = run.chainage_offset_m or 0.0
    return (None if from_m is None else from_m - off), (None if to_m is None else to_m - off)


def _csv_value(v: float | None, fmt: str) -> str:
    return "" if v is None else format(v, fmt)


EXTRA_PROFILE_COLUMNS = PROFILE_COLUMNS[2:]
"""Arrays a profile answer carries on request (``?include=``), besides chainage and level."""


def _included(include: str | None) -> tuple[str, ...]:
    if not include:
        return ()
    names = [n.strip() for n in include.split(",") if n.strip()]
    if "all" in names:
        return EXTRA_PROFILE_COLUMNS
    unknown = [n for n in names if n not in EXTRA_PROFILE_COLUMNS]
    if unknown:
        raise ApiError(
            422,
            f"include: unknown column(s) {', '.join(unknown)}; choose from "
            f"{', '.join(EXTRA_PROFILE_COLUMNS)} or 'all'",
            field="include",
        )
    return tuple(c for c in EXTRA_PROFILE_COLUMNS if c in names)


@router.get(
    "/{run_id}/profile",
    response_model=ProfilePublic,
    response_model_exclude_none=True,
    responses={200: {"content": {"text/csv": {"schema": {"type": "string"}}}}},
)
def read_run_profile(
    ctx: CtxDep,
    session: SessionDep,
    run_id: int,
    from_m: Annotated[float | None, Query(allow_inf_nan=False, description="From, m")] = None,
    to_m: Annotated[float | None, Query(allow_inf_nan=False, description="To, m")] = None,
    include: Annotated[
        str | None,
        Query(
            description="Extra arrays, comma-separated: front_level_mm, rear_level_mm, "
            "baseline_mm, or all",
        ),
    ] = None,
    format: Annotated[Literal["json", "csv"], Query()] = "json",
) -> Response:
    """The fused loaded profile on chainage: ``{"chainage_m": [...], "level_mm": [...]}``.

    Levels in mm, positive up (null where there is no data); chainage in m, aligned (the run's
    ``chainage_offset_m`` added). ``?from_m=&to_m=`` selects a window (inclusive) with one
    indexed query; ``?include=all`` adds each axle's level and the baseline the soft spots are
    measured from; ``?format=csv`` answers ``chainage_m,level_mm[,...]`` as CSV.
    """
    extra = _included(include)
    run = _get_run(session, run_id)
    _require_done(run, "profile")
    lo, hi = _window(run, from_m, to_m)
    off = run.chainage_offset_m or 0.0
    columns = ("chainage_m", "level_mm", *extra)
    if format == "csv":
        return StreamingResponse(
            _profile_csv(ctx, run_id, lo, hi, off, columns),
            media_type="text/csv",
            headers={"Content-Disposition": f'attachment; filename="run-{run_id}-profile.csv"'},
        )
    cols = read_profile(session, run_id, lo, hi, columns)
    chainage = cols["chainage_m"] if off == 0 else [c + off for c in cols["chainage_m"]]
    payload = {
        "run_id": run_id,
        "chainage_offset_m": off,
        "n": len(chainage),
        "chainage_m": chainage,
        **{k: cols[k] for k in columns[1:]},
    }
    return Response(orjson.dumps(payload), media_type="application/json")


def _profile_csv(
    ctx: AppContext,
    run_id: int,
    lo: float | None,
    hi: float | None,
    off: float,
    columns: tuple[str, ...],
) -> Iterator[str]:
    yield ",".join(columns) + "\n"
    with ctx.db.session() as s:
        for rows in iter_profile_rows(s, run_id, lo, hi, columns):
            yield "".join(
                f"{r[0] + off:.4f}," + ",".join(_csv_value(v, ".6f") for v in r[1:]) + "\n"
                for r in rows
            )


SOFT_SPOT_FIELDS = ("start_m", "end_m", "peak_m", "depth_mm", "stiffness_loss_pct")


@router.get(
    "/{run_id}/soft-spots",
    response_model=list[SoftSpotPublic],
    responses={200: {"content": {"text/csv": {"schema": {"type": "string"}}}}},
)
def read_run_soft_spots(
    session: SessionDep,
    run_id: int,
    format: Annotated[Literal["json", "csv"], Query()] = "json",
) -> Any:
    """Soft spots along chainage: extent and peak (m), depth (mm), stiffness loss (%)."""
    run = _get_run(session, run_id)
    _require_done(run, "soft spots")
    off = run.chainage_offset_m or 0.0
    spots = session.scalars(
        select(SoftSpot).where(SoftSpot.run_id == run_id).order_by(SoftSpot.start_m)
    ).all()
    public = [
        SoftSpotPublic(
            start_m=s.start_m + off,
            end_m=s.end_m + off,
            peak_m=s.peak_m + off,
            depth_mm=s.depth_mm,
            stiffness_loss_pct=s.stiffness_loss_pct,
        )  # fmt: skip
        for s in spots
    ]
    if format == "csv":
        lines = [",".join(SOFT_SPOT_FIELDS)]
        for p in public:
            lines.append(
                f"{p.start_m:.3f},{p.end_m:.3f},{p.peak_m:.3f},{p.depth_mm:.6f},"
                f"{_csv_value(p.stiffness_loss_pct, '.2f')}"
            )
        return Response(
            "\n".join(lines) + "\n",
            media_type="text/csv",
            headers={"Content-Disposition": f'attachment; filename="run-{run_id}-soft-spots.csv"'},
        )
    return public


@router.get("/{run_id}/signals", response_model=SignalsPublic)
def read_run_signals(session: SessionDep, run_id: int) -> SignalsPublic:
    """The raw signals against time (decimated to at most 5000 points, min/max envelope)."""
    run = _get_run(session, run_id)
    sig = session.get(RunSignals, run_id)
    if sig is None:
        raise ApiError(404, f"run {run_id} has no stored signals")
    d = sig.data
    return SignalsPublic(
        run_id=run_id,
        n_samples=run.n_samples,
        decimated=sig.decimated,
        time_s=d["time_s"],
        accel_z_mps2=d["accel_z_mps2"],
        pitch_rate_radps=d["pitch_rate_radps"],
        speed_mps=d["speed_mps"],
    )
