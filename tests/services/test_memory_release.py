"""Memory a long run's processing freed goes back to the operating system (app.core.memory),
checked on the allocator and the release timer directly."""

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
