"""Fixtures shared by the service tests (tests/services) and the HTTP tests (tests/api): the
real app on a real database per test, see :mod:`support.app_fixtures`.

Also keeps the ``slow`` mark true: a test that took longer than :data:`SLOW_S` (set-up, call
and tear-down) without the mark is named at the end of the run, so that
``pytest -m "not slow"`` stays a quick run for development.
"""

from __future__ import annotations

import pytest

pytest_plugins = ["support.app_fixtures"]

SLOW_S = 5.0
"""A test taking longer than this, s, belongs under the ``slow`` mark."""

_took: dict[str, float] = {}
_unmarked: set[str] = set()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    _unmarked.update(item.nodeid for item in items if "slow" not in item.keywords)


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    _took[report.nodeid] = _took.get(report.nodeid, 0.0) + report.duration


def pytest_terminal_summary(terminalreporter) -> None:  # type: ignore[no-untyped-def]
    late = sorted(((t, n) for n, t in _took.items() if t > SLOW_S and n in _unmarked), reverse=True)
    if late:
        terminalreporter.section(f"over {SLOW_S:g} s without the slow mark")
        for t, n in late:
            terminalreporter.write_line(f"{t:7.1f} s  {n}")
