"""Memory a long run's processing freed goes back to the operating system (app.core.memory):
glibc keeps freed heap blocks in the process otherwise, and a service that processed a few
hour-long logs stayed ~1.3 GB resident while idle."""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import psutil
import pytest

from app.core import memory
from app.core.config import REPO_ROOT


@pytest.mark.skipif(memory._TRIM is None, reason="the C library has no malloc_trim (not glibc)")
def test_freed_heap_memory_is_handed_back() -> None:
    proc = psutil.Process()
    before = proc.memory_info().rss
    blocks = [np.ones(8000) for _ in range(4000)]  # 64 kB each (from the heap): 256 MB
    keep = blocks[-1]  # the last block stays: what lies below it cannot simply be cut off
    del blocks
    retained = proc.memory_info().rss - before
    assert memory.release_freed_memory() is True
    after = proc.memory_info().rss - before
    assert retained > 150e6, f"the allocator kept only {retained / 1e6:.0f} MB"
    assert after < 50e6, f"{after / 1e6:.0f} MB still resident after the release"
    assert keep.sum() == 8000.0


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


def test_idle_release_waits_until_nothing_has_ended_for_idle_s() -> None:
    calls: list[int] = []
    keeper = memory.IdleRelease(0.3, release=lambda: calls.append(1) or True)
    assert keeper.release_if_idle() is False, "nothing was kept yet"
    keeper.busy()
    assert keeper.release_if_idle() is False and calls == []
    time.sleep(0.2)
    keeper.busy()  # more work: the idle time starts again
    time.sleep(0.2)
    assert keeper.release_if_idle() is False and calls == []
    time.sleep(0.15)
    assert keeper.release_if_idle() is True and calls == [1]
    assert keeper.release_if_idle() is False and calls == [1], "released twice"


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


def test_kept_memory_stays_in_the_process_until_released() -> None:
    """keep_freed_memory changes the allocator of the whole process: checked in a child."""
    code = """
import numpy as np, psutil
from app.core import memory
from app.core.config import REPO_ROOT
proc = psutil.Process()
assert memory.keep_freed_memory()
import pyarrow as pa
assert pa.default_memory_pool().backend_name == "system", pa.default_memory_pool().backend_name
base = proc.memory_info().rss
a = np.ones(5_000_000)  # 40 MB: kept now; its own mapping under glibc's defaults
del a
kept = proc.memory_info().rss - base
memory.release_freed_memory()
print(kept, proc.memory_info().rss - base)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=REPO_ROOT).stdout.split()  # fmt: skip
    kept, after = (int(v) for v in out)
    assert kept > 30e6, f"only {kept / 1e6:.0f} MB stayed after the free"
    assert after < 20e6, f"{after / 1e6:.0f} MB still resident after the release"
