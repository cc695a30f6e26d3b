"""Memory a long run's processing freed goes back to the operating system (app.core.memory):
glibc keeps freed heap blocks in the process otherwise, and a service that processed a few
hour-long logs stayed ~1.3 GB resident while idle."""

from __future__ import annotations

import numpy as np
import psutil
import pytest

from app.core import memory


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


def test_the_worker_releases_memory_after_each_run(start_app, synthetic_run, monkeypatch) -> None:
    """After a run is processed (not while looking for work) the worker hands memory back."""
    import app.services.worker as worker_mod
    from api.api_support import upload
    from app.services.worker import Worker

    calls: list[int] = []
    monkeypatch.setattr(worker_mod, "release_freed_memory", lambda: calls.append(1) or True)
    c = start_app(inline_max_samples=0, start_worker=False)
    r = upload(c, synthetic_run["csv"], track="T",
               start_chainage_m=synthetic_run["start_chainage_m"])  # fmt: skip
    assert r.status_code == 202, r.text
    w = Worker(c.app.state.ctx)
    assert w.run_once() is True and calls == [1]
    assert c.get(f"/api/v1/runs/{r.json()['id']}").json()["status"] == "done"
    assert w.run_once() is False and calls == [1]
