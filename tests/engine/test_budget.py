"""Wall-time budgets of the engine (engine.budget): checked between the pipeline's stages."""

from __future__ import annotations

import time

import pytest

from engine.budget import TimeBudget
from engine.errors import BudgetExceeded, EngineError
from engine.pipeline import process_run
from engine.setup import ProcessConfig, RunSetup, prepare_run
from engine.synthetic import make_run


def test_a_spent_budget_raises_naming_the_stage_and_source() -> None:
    budget = TimeBudget(0.01, "processing", "SOME_SETTING")
    budget.check("a quick stage")
    time.sleep(0.02)
    with pytest.raises(BudgetExceeded, match=r"budget of 0.01 s \(SOME_SETTING\): stopped after "
                       "the slow stage") as info:  # fmt: skip
        budget.check("the slow stage")
    assert isinstance(info.value, EngineError) and info.value.elapsed_s >= 0.02
    with pytest.raises(ValueError, match="> 0"):
        TimeBudget(0)


def test_the_pipeline_stops_at_the_first_check_past_its_budget() -> None:
    run = make_run(length=150.0, speed=20.0, seed=1)
    start = run.start_chainage_m
    with pytest.raises(BudgetExceeded) as info:
        process_run(prepare_run(run.log, RunSetup(start_chainage_m=start)), budget=TimeBudget(1e-9))
    assert info.value.stage == f"the {ProcessConfig().method} inversion"  # the first stage
    assert process_run(
        prepare_run(run.log, RunSetup(start_chainage_m=start)), budget=TimeBudget(300)
    ).level_mm.size
