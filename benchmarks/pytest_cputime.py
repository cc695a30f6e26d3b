"""A pytest plugin that writes the CPU time of every test (set-up, call and tear-down) as it
finishes, for measuring the suite on a shared machine, where wall time mostly says how busy the
machine was::

    PYTHONPATH=$PWD python -m pytest tests/api -p benchmarks.pytest_cputime

Each line of ``$CPUTIME_OUT`` (default ``cputime.tsv``), tab-separated: the test process's CPU
time, s (every thread: the app's worker too), that of its children it waited for, s (live
servers, subprocesses), the wall time, s, and the test's node id. Lines are written as tests
finish, so an interrupted run keeps what it measured.
"""

from __future__ import annotations

import os
import resource
import time

_started: dict[str, tuple[float, float, float]] = {}


def _now() -> tuple[float, float, float]:
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time(), children.ru_utime + children.ru_stime, time.perf_counter()


def pytest_runtest_logstart(nodeid: str, location: object) -> None:
    _started[nodeid] = _now()


def pytest_runtest_logfinish(nodeid: str, location: object) -> None:
    start = _started.pop(nodeid, None)
    if start is None:
        return
    end = _now()
    own, children, wall = (b - a for a, b in zip(start, end, strict=True))
    with open(os.environ.get("CPUTIME_OUT", "cputime.tsv"), "a") as out:
        out.write(f"{own:.2f}\t{children:.2f}\t{wall:.2f}\t{nodeid}\n")
