"""Geometry vs stiffness: a track's separated stiffness (``/tracks/{track}/stiffness``) and its
reference surveys (``/tracks/{track}/surveys``). ``{track}`` is the track's id or name."""

from __future__ import annotations

from typing import Any

import orjson
from fastapi import APIRouter, Request, Response
from fastapi.concurrency import run_in_threadpool

from app.api import uploads
from app.api.answers import Format, add_csv_twin, csv_answer
from app.api.convert import stiffness_public, survey_public
from app.api.deps import CtxDep, SessionDep, WindowDep
from app.api.uploads import JSON, MULTIPART
from app.schemas.stiffness import StiffnessPublic, SurveyCreateJson, SurveyFields, SurveyPublic
from app.services.lookup import get_track
from app.services.run_lifecycle.intake import clean_filename
from app.services.track import surveys
from app.services.track.separation_store import stiffness_with_vehicles
from app.services.vehicles.versions import read_settled
from app.services.views import exports

router = APIRouter(prefix="/tracks", tags=["geometry and stiffness"])


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
    ``message`` says why. The window and each soft spot are ``provisional`` (with
    ``provisional_reason``) while a vehicle behind them has neither a calibration applied nor
    its runs' loads declared. ``?from_m=&to_m=`` selects a window; the ``.csv`` twin answers
    ``chainage_m,k_rel,...,separable`` (with the message and the provisional reason as ``#``
    comment lines).
    """
    trk = get_track(session, track)
    from_m, to_m = window.from_m, window.to_m
    sep = read_settled(
        session, trk.id, "stiffness",
        lambda: stiffness_with_vehicles(session, trk.id, from_m, to_m),
    )  # fmt: skip
    if format == "csv":
        return csv_answer(exports.stiffness_csv(sep), f"track-{trk.id}-stiffness.csv")
    payload = stiffness_public(trk, window, sep)
    return Response(orjson.dumps(payload), media_type="application/json")


SEND = f"{MULTIPART} or {JSON}"
"""What a survey upload may be sent as (named when another content type comes)."""


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
    meta: SurveyFields
    data: bytes | bytearray
    if uploads.content_type(request, (MULTIPART, JSON), SEND) == MULTIPART:
        form = await uploads.read_file_form(request, what="the survey CSV", max_fields=16)
        data, filename = form.data, form.filename
        meta = uploads.validated(SurveyFields, form.fields)
    else:
        jmeta = uploads.validated_json(SurveyCreateJson, await uploads.read_body(request))
        data, filename, meta = jmeta.csv.encode(), jmeta.filename, jmeta
    survey_input = surveys.SurveyInput(
        wheel_load_n=meta.wheel_load_n, band_min_m=meta.band_min_m, band_max_m=meta.band_max_m,
        name=meta.name, recorded_at=meta.recorded_at, filename=clean_filename(filename),
    )  # fmt: skip
    survey, created = await run_in_threadpool(surveys.import_survey, ctx, track, data, survey_input)
    response.status_code = 201 if created else 200
    return survey_public(survey, duplicate=not created)


@router.get("/{track}/surveys", response_model=list[SurveyPublic])
def read_track_surveys(session: SessionDep, track: str) -> list[SurveyPublic]:
    """The track's reference surveys, oldest first."""
    trk = get_track(session, track)
    return [survey_public(s) for s in surveys.list_surveys(session, trk.id)]


@router.delete("/{track}/surveys/{survey_id}", status_code=204, response_class=Response)
def delete_track_survey(session: SessionDep, track: str, survey_id: int) -> Response:
    """Delete a survey; the track's stiffness is separated again without it."""
    trk = get_track(session, track)
    surveys.delete_survey(session, surveys.get_survey(session, trk.id, survey_id))
    session.commit()
    return Response(status_code=204)


add_csv_twin(router, "/{track}/stiffness", read_track_stiffness)
