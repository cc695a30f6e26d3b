"""Geometry vs stiffness: a track's separated stiffness (``/tracks/{track}/stiffness``) and its
reference surveys (``/tracks/{track}/surveys``). ``{track}`` is the track's id or name."""

from __future__ import annotations

from typing import Any

import orjson
from fastapi import APIRouter, Request, Response
from fastapi.concurrency import run_in_threadpool
from pydantic import ValidationError
from starlette.datastructures import UploadFile

from app.api.answers import Format, add_csv_twin
from app.api.deps import CtxDep, SessionDep, WindowDep
from app.core.errors import ApiError, validation_detail
from app.db.models import Survey
from app.schemas.stiffness import (
    StiffnessPublic,
    SurveyCreateJson,
    SurveyFields,
    SurveyPublic,
)
from app.services.alignment import GRID_STEP_M
from app.services.context import AppContext
from app.services.lookup import get_track
from app.services.stiffness import UPDATING, stiffness_with_vehicles
from app.services.submit import clean_filename
from app.services.surveys import SurveyInput, create_survey, delete_survey, get_survey, list_surveys
from app.services.vehicles import read_settled

router = APIRouter(prefix="/tracks", tags=["geometry and stiffness"])

STIFFNESS_CSV_FIELDS = (
    "chainage_m", "k_rel", "k_rel_lo", "k_rel_hi", "geometry_mm", "geometry_sd_mm",
    "compliance_mm_per_kn", "n_passes", "load_ratio", "separable",
)  # fmt: skip


def _fmt(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "1" if v else "0"
    if isinstance(v, int):
        return str(v)
    return f"{v:.6g}"


@router.get("/{track}/stiffness", response_model=StiffnessPublic)
def read_track_stiffness(
    session: SessionDep,
    track: str,
    window: WindowDep,
    format: Format = "json",
) -> Response:
    """Support stiffness and unloaded geometry separated across the track's passes.

    Per 0.25 m of aligned chainage: ``k_rel`` (stiffness / nominal) with its band, the
    unloaded geometry (mm) and its uncertainty, the compliance, how many passes cover the
    point and the ratio of their wheel forces; the soft spots found and which runs and
    surveys (with their mean wheel force) contributed. Where the passes do not span enough
    wheel load the point is not separable: its stiffness and geometry are null and
    ``message`` says why. ``?from_m=&to_m=`` selects a window; the ``.csv`` twin answers
    ``chainage_m,k_rel,...,separable`` (with the message as a ``#`` comment line).
    """
    trk = get_track(session, track)
    from_m, to_m = window.from_m, window.to_m
    sep = read_settled(
        session, trk.id, "stiffness",
        lambda: stiffness_with_vehicles(session, trk.id, from_m, to_m),
    )  # fmt: skip
    cols = sep.columns
    if format == "csv":
        lines = []
        if sep.updating:
            lines.append(f"# {UPDATING}")
        if sep.message:
            lines.append(f"# {sep.message}")
        lines.append(",".join(STIFFNESS_CSV_FIELDS))
        for i in range(sep.n):
            lines.append(",".join(_fmt(cols[k][i]) for k in STIFFNESS_CSV_FIELDS))
        return Response(
            "\n".join(lines) + "\n",
            media_type="text/csv",
            headers={"Content-Disposition": f'attachment; filename="track-{trk.id}-stiffness.csv"'},
        )
    payload = {
        "track_id": trk.id,
        "track": trk.name,
        "from_m": from_m,
        "to_m": to_m,
        "grid_step_m": GRID_STEP_M,
        "k_nominal_n_per_m": trk.k_nominal,
        "n": sep.n,
        "separable": sep.separable,
        "separable_fraction": sep.separable_fraction,
        "message": sep.message,
        "not_separable": [st.to_dict() for st in sep.not_separable],
        "updating": sep.updating,
        "chainage_m": cols["chainage_m"],
        "k_rel": cols["k_rel"],
        "k_rel_lo": cols["k_rel_lo"],
        "k_rel_hi": cols["k_rel_hi"],
        "geometry_mm": cols["geometry_mm"],
        "geometry_sd_mm": cols["geometry_sd_mm"],
        "compliance_mm_per_kn": cols["compliance_mm_per_kn"],
        "n_passes": cols["n_passes"],
        "load_ratio": cols["load_ratio"],
        "separable_at": cols["separable"],
        "soft_spots": [
            {
                "start_m": s.start_m,
                "end_m": s.end_m,
                "peak_m": s.peak_m,
                "stiffness_loss_pct": s.loss_pct,
                "loss_lo_pct": s.loss_lo_pct,
                "loss_hi_pct": s.loss_hi_pct,
                "confidence": s.confidence,
                "basis": "separated",
            }  # fmt: skip
            for s in sep.spots
        ],
        "contributors": sep.contributors,
    }
    return Response(orjson.dumps(payload), media_type="application/json")


def survey_public(s: Survey, duplicate: bool = False) -> SurveyPublic:
    """A survey's public view (chainage aligned)."""
    off = s.chainage_offset_m or 0.0
    return SurveyPublic(
        id=s.id, track_id=s.track_id, name=s.name, original_filename=s.original_filename,
        recorded_at=s.recorded_at, created_at=s.created_at, wheel_load_n=s.wheel_load_n,
        band_min_m=s.band_min_m, band_max_m=s.band_max_m, n_points=s.n_points,
        chainage_min_m=s.chainage_min_m + off, chainage_max_m=s.chainage_max_m + off,
        chainage_offset_m=off, alignment_status=s.alignment_status,  # type: ignore[arg-type]
        alignment_correlation=s.alignment_correlation, alignment_reason=s.alignment_reason,
        duplicate=duplicate,
    )  # fmt: skip


def _fields(model: type[SurveyFields], data: Any) -> SurveyFields:
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        detail = validation_detail(exc.errors(include_url=False, include_input=False))
        raise ApiError(422, detail.pop("message"), **detail) from None


def _store_survey(
    ctx: AppContext, track: str, data: bytes, meta: SurveyFields, filename: str | None
) -> tuple[SurveyPublic, bool]:
    with ctx.db.session() as s:
        trk = get_track(s, track)
        survey, created = create_survey(
            s, trk, data,
            SurveyInput(
                wheel_load_n=meta.wheel_load_n, band_min_m=meta.band_min_m,
                band_max_m=meta.band_max_m, name=meta.name, recorded_at=meta.recorded_at,
                filename=clean_filename(filename),
            ),
        )  # fmt: skip
        s.commit()
        return survey_public(survey, duplicate=not created), created


SURVEY_BODY_DOC: dict[str, Any] = {
    "requestBody": {
        "required": True,
        "description": "A multipart upload (``file``: CSV chainage_m,level_mm; fields "
        "wheel_load_n, band_min_m, band_max_m, name, recorded_at) or a JSON body with the CSV "
        "text in ``csv``.",
        "content": {
            "multipart/form-data": {
                "schema": {
                    "type": "object",
                    "additionalProperties": False,
                    "required": ["file", "wheel_load_n"],
                    "properties": {
                        "file": {"type": "string", "format": "binary"},
                        **SurveyFields.model_json_schema()["properties"],
                    },
                }
            },
            "application/json": {"schema": {"$ref": "#/components/schemas/SurveyCreateJson"}},
        },
    }
}


@router.post(
    "/{track}/surveys",
    response_model=SurveyPublic,
    status_code=201,
    openapi_extra=SURVEY_BODY_DOC,
    responses={200: {"model": SurveyPublic, "description": "The same survey was stored before"}},
)
async def create_track_survey(
    request: Request, response: Response, ctx: CtxDep, track: str
) -> SurveyPublic:
    """Import a reference survey: a track recording car's longitudinal level (CSV
    ``chainage_m,level_mm``, level in mm positive up) at its wheel load ``wheel_load_n`` (N)
    in the wavelength band ``band_min_m``-``band_max_m`` (default 3-25 m, EN 13848 D1).

    It is aligned to the track like a run and counts as one more pass at a known load when
    geometry and stiffness are separated. A bad survey (missing column, chainage not
    monotonic, a value not finite, a level beyond +-100 mm, no wheel load) is answered 422
    naming the column and row or the field, and nothing is stored.
    """
    ctype = request.headers.get("content-type", "").split(";")[0].strip().lower()
    limit = ctx.settings.max_upload_bytes
    if ctype == "multipart/form-data":
        async with request.form(max_files=1, max_fields=16) as form:
            upload = form.get("file")
            if not isinstance(upload, UploadFile):
                raise ApiError(422, "the upload has no 'file' part (the survey CSV)", field="file")
            data = await upload.read(limit + 1)
            filename = upload.filename
            fields = {k: v for k, v in form.multi_items() if k != "file"}
        meta = _fields(SurveyFields, fields)
    elif ctype == "application/json":
        body = await request.body()
        try:
            jmeta = SurveyCreateJson.model_validate_json(body)
        except ValidationError as exc:
            detail = validation_detail(exc.errors(include_url=False, include_input=False))
            raise ApiError(422, detail.pop("message"), **detail) from None
        data, filename, meta = jmeta.csv.encode(), jmeta.filename, jmeta
    else:
        raise ApiError(
            415, f"unsupported content type {ctype or '(none)'!r}: send multipart/form-data or "
            "application/json", field="Content-Type",
        )  # fmt: skip
    if len(data) > limit:
        raise ApiError(413, f"the survey is larger than the upload limit ({limit} bytes)")
    public, created = await run_in_threadpool(_store_survey, ctx, track, data, meta, filename)
    response.status_code = 201 if created else 200
    return public


@router.get("/{track}/surveys", response_model=list[SurveyPublic])
def read_track_surveys(session: SessionDep, track: str) -> list[SurveyPublic]:
    """The track's reference surveys, oldest first."""
    trk = get_track(session, track)
    return [survey_public(s) for s in list_surveys(session, trk.id)]


@router.delete("/{track}/surveys/{survey_id}", status_code=204, response_class=Response)
def delete_track_survey(session: SessionDep, track: str, survey_id: int) -> Response:
    """Delete a survey; the track's stiffness is separated again without it."""
    trk = get_track(session, track)
    delete_survey(session, get_survey(session, trk.id, survey_id))
    session.commit()
    return Response(status_code=204)


add_csv_twin(router, "/{track}/stiffness", read_track_stiffness)
