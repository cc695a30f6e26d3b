"""Processing a run: a wall-time budget per run (issue 16, item 5) and a visible ``storing``
stage (issue 16, low items).

A run whose inversion takes longer than ``TRACKPROFILE_PROCESSING_BUDGET_S`` fails with a
clear error (``"kind": "BudgetExceeded"``) and frees its processing slot; the budget is
checked between the engine's stages, so a tiny budget stops every run after its first
stage. While the worker stores a result, the run shows ``stage: "storing"``.
"""

from __future__ import annotations

import threading

from api.api_support import row_counts, upload
from api.live_server import wait_status
from app.services.run_lifecycle import store as store_module
from engine.setup import ProcessConfig


def test_a_run_over_its_budget_fails_clearly_and_frees_the_slot(start_app, synthetic_run):
    c = start_app(inline_max_samples=0, processing_budget_s=1e-6, workers=1)
    ids = [
        upload(
            c, synthetic_run["csv"] + b"\n" * (start - 12), track="L", start_chainage_m=start
        ).json()["id"]  # fmt: skip
        for start in (12, 13)  # two runs (two logs): the second needs the slot the first held
    ]
    for run_id in ids:
        run = wait_status(c, run_id, {"done", "failed"}, timeout=60)
        assert run["status"] == "failed", run
        error = run["error"]
        assert error["kind"] == "BudgetExceeded" and error["limit_s"] == 1e-6
        assert "TRACKPROFILE_PROCESSING_BUDGET_S" in error["message"]
        # the first stage the budget is checked after: the default method's inversion
        assert f"stopped after the {ProcessConfig().method} inversion" in error["message"]
    assert c.app.state.ctx.slots.acquire(blocking=False)  # the slot is free again
    c.app.state.ctx.slots.release()


def test_an_inline_run_over_its_budget_is_422_and_stores_nothing(start_app, settings,
                                                                 synthetic_run):  # fmt: skip
    c = start_app(processing_budget_s=1e-6)
    before = row_counts(settings)
    r = upload(c, synthetic_run["csv"], track="L", start_chainage_m=12)
    assert r.status_code == 422, r.text
    assert r.json()["detail"]["kind"] == "BudgetExceeded"
    assert row_counts(settings) == before


def test_a_run_within_its_budget_is_done(start_app, synthetic_run) -> None:
    c = start_app(processing_budget_s=120)
    r = upload(c, synthetic_run["csv"], track="L", start_chainage_m=12, params={"wait": "true"})
    assert r.status_code == 201 and r.json()["status"] == "done", r.text


def test_the_storing_stage_is_visible(start_app, synthetic_run, monkeypatch) -> None:
    storing, release = threading.Event(), threading.Event()
    real_store = store_module.store_result

    def slow_store(*args, **kwargs):
        storing.set()
        assert release.wait(30)
        return real_store(*args, **kwargs)

    monkeypatch.setattr(store_module, "store_result", slow_store)
    c = start_app(inline_max_samples=0)
    run_id = upload(c, synthetic_run["csv"], track="L", start_chainage_m=12).json()["id"]
    try:
        assert storing.wait(60), "the worker never stored the run"
        run = c.get(f"/api/v1/runs/{run_id}").json()
        assert (run["status"], run["stage"], run["progress"]) == ("processing", "storing", 0.85)
    finally:
        release.set()
    assert wait_status(c, run_id, {"done", "failed"}, timeout=60)["status"] == "done"
