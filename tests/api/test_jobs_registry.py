"""The worker's jobs come from the ``JOBS`` registry: a look tries them in its order, a job
added there is run with no change to the queue, and a kind left out is not done."""

from __future__ import annotations

from api.api_support import upload
from app.services.run_lifecycle import queue as queue_mod
from app.services.run_lifecycle.jobs import JOBS, CheckpointJob, Job
from app.services.run_lifecycle.queue import Worker


def test_an_added_idle_job_runs_in_its_place(start_app, monkeypatch) -> None:
    """An idle job put before the checkpoint is looked at when nothing is queued; while it
    finds work the look ends there (the checkpoint is not reached), and once it finds none
    the look goes on to the checkpoint and reports no work."""
    c = start_app(start_worker=False)
    found = [True, False]
    seen: list[str] = []

    class Probe(Job):
        def look(self) -> bool:
            seen.append("probe")
            return found.pop(0)

    def checkpoint(self: CheckpointJob) -> bool:
        seen.append("checkpoint")
        return False

    jobs = {k: v for k, v in JOBS.items() if k != "checkpoint"}
    monkeypatch.setattr(queue_mod, "JOBS", {**jobs, "probe": Probe, "checkpoint": CheckpointJob})
    monkeypatch.setattr(CheckpointJob, "look", checkpoint)
    w = Worker(c.app.state.ctx)
    assert isinstance(w.job(Probe), Probe)
    assert w.run_once() is True and seen == ["probe"]
    assert w.run_once() is False and seen == ["probe", "probe", "checkpoint"]


def test_a_kind_left_out_of_the_registry_is_not_done(start_app, synthetic_run, monkeypatch):
    """A worker made without the process job leaves a queued run queued (its claim is not
    even taken); a worker with the registry as it is processes it."""
    c = start_app(inline_max_samples=0, start_worker=False)
    r = upload(c, synthetic_run["csv"], track="J",
               start_chainage_m=synthetic_run["start_chainage_m"])  # fmt: skip
    assert r.status_code == 202, r.text
    run_id = r.json()["id"]
    ctx = c.app.state.ctx
    with monkeypatch.context() as m:
        m.setattr(queue_mod, "JOBS", {k: v for k, v in JOBS.items() if k != "process"})
        assert Worker(ctx).run_once() is False
    run = c.get(f"/api/v1/runs/{run_id}").json()
    assert (run["status"], run["stage"]) == ("processing", "queued")
    assert Worker(ctx).run_once() is True
    assert c.get(f"/api/v1/runs/{run_id}").json()["status"] == "done"
