"""``POST /api/v1/simulate``: a synthetic run from the forward model, processed like an upload."""

from __future__ import annotations

import dataclasses
from typing import Annotated

from fastapi import APIRouter, Query, Response
from fastapi.concurrency import run_in_threadpool

from app.api.convert import simulation_spec
from app.api.deps import CtxDep
from app.schemas.runs import RunCreated
from app.schemas.simulate import SimulatePublic, SimulateRequest
from app.services.run_lifecycle.simulation import simulate_and_submit
from app.services.views.charts import truth_view
from engine.irregularity import SPECTRA
from engine.sensor import SENSOR_GRADES

from .runs import answer_submission, submission_responses

router = APIRouter(tags=["simulate"])


@router.get("/simulate/spectra", response_model=dict[str, str])
def list_spectra() -> dict[str, str]:
    """The rail-irregularity spectra a simulation can use, by name, with their source."""
    return {name: sp.source for name, sp in SPECTRA.items()}


@router.get("/simulate/sensor-grades", response_model=dict[str, dict[str, float | str]])
def list_sensor_grades() -> dict[str, dict[str, float | str]]:
    """The IMU grades a simulation can use (``sensor_grade``), by name, with their figures."""
    return {name: dataclasses.asdict(g) for name, g in SENSOR_GRADES.items()}


@router.post(
    "/simulate",
    response_model=SimulatePublic,
    status_code=201,
    responses=submission_responses(SimulatePublic, "The same simulation was stored before"),
)
async def simulate_run(
    ctx: CtxDep,
    body: SimulateRequest,
    response: Response,
    wait: Annotated[bool, Query(description="Wait for the result of a long run")] = False,
) -> SimulatePublic:
    """Simulate the vehicle over a track with soft zones, then process and store the run.

    Lets a new user try the product without a logger: the answer carries the run (its
    profile and soft spots are at the usual run endpoints) and the truth to compare with.
    """
    run_id, created, truth = await run_in_threadpool(
        simulate_and_submit, ctx, simulation_spec(body)
    )
    run: RunCreated = await answer_submission(ctx, response, run_id, created, wait)
    return SimulatePublic(run=run, truth=truth_view(truth))
