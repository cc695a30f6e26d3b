"""Memory a long run's processing freed goes back to the operating system (app.core.memory):
glibc keeps freed heap blocks in the process otherwise, and a service that processed a few
hour-long logs stayed ~1.3 GB resident while idle."""

from __future__ import annotations

import time

from app.core import memory


def test_with_no_idle_time_memory_is_released_after_each_upload_and_run(
    start_app, synthetic_run, monkeypatch
) -> None:
    """memory_release_idle_s 0 (the tests' setting): handed back when an upload has been
    stored and when a run has been processed, not while the worker looks for work."""
    from api.api_support import upload
    from app.services.run_lifecycle.queue import Worker

    calls: list[int] = []
    monkeypatch.setattr(memory, "release_freed_memory", lambda: calls.append(1) or True)
    c = start_app(inline_max_samples=0, start_worker=False, memory_release_idle_s=0)
    r = upload(c, synthetic_run["csv"], track="T",
               start_chainage_m=synthetic_run["start_chainage_m"])  # fmt: skip
    assert r.status_code == 202, r.text
    assert calls == [1]
    w = Worker(c.app.state.ctx)
    assert w.run_once() is True and calls == [1, 1]
    assert c.get(f"/api/v1/runs/{r.json()['id']}").json()["status"] == "done"
    assert w.run_once() is False and calls == [1, 1]


def test_the_service_keeps_memory_while_busy_and_hands_it_back_when_idle(
    start_app, synthetic_run, monkeypatch
) -> None:
    """With an idle time the app keeps the allocator's freed memory (keep_freed_memory at
    start) and its timer hands it back once, after the last work plus the idle time."""
    from api.api_support import upload, wait_done

    kept: list[int] = []
    calls: list[float] = []
    monkeypatch.setattr(memory, "keep_freed_memory", lambda: kept.append(1) or True)
    monkeypatch.setattr(
        memory, "release_freed_memory", lambda: calls.append(time.monotonic()) or True
    )
    c = start_app(memory_release_idle_s=1.0)
    assert kept == [1]
    r = upload(
        c, synthetic_run["csv"], track="T", start_chainage_m=synthetic_run["start_chainage_m"]
    )
    assert wait_done(c, r.json()["id"])["status"] == "done"
    ended = time.monotonic()
    assert calls == [], "memory was handed back while the service was busy"
    deadline = ended + 5.0
    while not calls and time.monotonic() < deadline:
        time.sleep(0.1)
    assert len(calls) == 1, "the idle service did not hand its memory back"
    time.sleep(1.5)
    assert len(calls) == 1, "handed back again with no work in between"
