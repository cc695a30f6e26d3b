"""API key scopes without HTTP: the scope each method and path needs, and scope names parsed
strictly."""

from __future__ import annotations

import pytest

from app.core.scopes import parse_scopes, required_scope


@pytest.mark.parametrize(
    ("method", "path", "scope"),
    [
        ("GET", "/api/v1/runs/1", "read"),
        ("POST", "/api/v1/runs", "write"),
        ("PUT", "/api/v1/tracks/L/limits", "write"),
        ("POST", "/api/v1/vehicles", "write"),
        ("DELETE", "/api/v1/runs/1", "admin"),
        ("DELETE", "/api/v1/tracks/L/surveys/3", "admin"),
        ("PATCH", "/api/v1/vehicles/car", "admin"),
        ("POST", "/api/v1/vehicles/car/calibrate", "admin"),
        ("PUT", "/api/v1/tracks/L/centerline", "admin"),  # one rule for storing and deleting
        ("DELETE", "/api/v1/tracks/L/centerline", "admin"),
    ],
)
def test_each_request_needs_its_scope(method, path, scope) -> None:
    assert required_scope(method, path) == scope


def test_unknown_scopes_are_refused() -> None:
    assert parse_scopes("write, read") == {"read", "write"}
    with pytest.raises(ValueError, match="unknown scope 'root'"):
        parse_scopes("read,root")
