"""Fixtures shared by the service tests (tests/services) and the HTTP tests (tests/api): the
real app on a real database per test, see :mod:`support.app_fixtures`."""

pytest_plugins = ["support.app_fixtures"]
