"""API key scopes (issue 16, low items): ``read``, ``write``, ``admin``. A key without the
scope a request needs gets 403 naming it, before the request's body is read; keys made
before scopes existed keep every scope (the migration's default)."""

from __future__ import annotations

import contextlib
import io

import pytest

from api.api_support import sql, upload
from app.cli import main as cli_main
from app.core.config import get_settings


def _key(monkeypatch, settings, name: str, *args: str) -> str:
    monkeypatch.setenv("DATABASE_URL", settings.sqlalchemy_url)
    get_settings.cache_clear()
    out = io.StringIO()
    try:
        with contextlib.redirect_stdout(out):
            assert cli_main(["create-key", name, *args]) == 0
    finally:
        get_settings.cache_clear()
    return out.getvalue().strip().splitlines()[-1]


def _missing(r, scope: str) -> None:
    assert r.status_code == 403, r.text
    detail = r.json()["detail"]
    assert detail["kind"] == "MissingScope" and detail["scope"] == scope
    assert repr(scope) in detail["message"]


def test_scoped_keys_do_what_their_scopes_allow(start_app, settings, monkeypatch, synthetic_run):
    c = start_app(require_api_key=True, require_api_key_for_reads=True)
    reader = {"X-API-Key": _key(monkeypatch, settings, "dashboard", "--scopes", "read")}
    writer = {"X-API-Key": _key(monkeypatch, settings, "pipeline", "--scopes", "read,write")}
    admin = {"X-API-Key": _key(monkeypatch, settings, "operator")}  # the default: all scopes
    assert sql(settings, "SELECT name, scopes FROM api_keys ORDER BY id") == [
        ("dashboard", "read"), ("pipeline", "read write"), ("operator", "read write admin"),
    ]  # fmt: skip

    assert c.get("/api/v1/runs", headers=reader).status_code == 200
    _missing(c.post("/api/v1/tracks", json={"name": "L"}, headers=reader), "write")
    r = upload(c, synthetic_run["csv"], track="L", start_chainage_m=12, headers=writer)
    assert r.status_code == 201, r.text
    run_id = r.json()["id"]
    _missing(c.delete(f"/api/v1/runs/{run_id}", headers=writer), "admin")
    _missing(c.patch("/api/v1/vehicles/table1", json={"params": {"ms": 1}}, headers=writer),
             "admin")  # fmt: skip
    _missing(c.post("/api/v1/vehicles/table1/calibrate", json={}, headers=writer), "admin")
    assert c.get(f"/api/v1/runs/{run_id}", headers=writer).status_code == 200
    assert c.delete(f"/api/v1/runs/{run_id}", headers=admin).status_code == 204


def test_a_write_only_key_cannot_read_when_reads_need_a_key(start_app, settings, monkeypatch):
    c = start_app(require_api_key=True, require_api_key_for_reads=True)
    writer = {"X-API-Key": _key(monkeypatch, settings, "drop box", "--scopes", "write")}
    _missing(c.get("/api/v1/tracks", headers=writer), "read")
    assert c.post("/api/v1/tracks", json={"name": "L"}, headers=writer).status_code == 201


def test_the_default_scopes_of_new_keys_are_a_setting(start_app, settings, monkeypatch):
    c = start_app(require_api_key=True)
    monkeypatch.setenv("TRACKPROFILE_DEFAULT_KEY_SCOPES", "read,write")
    key = {"X-API-Key": _key(monkeypatch, settings, "pipeline")}
    _missing(c.delete("/api/v1/runs/1", headers=key), "admin")
    monkeypatch.setenv("TRACKPROFILE_DEFAULT_KEY_SCOPES", "read,everything")
    get_settings.cache_clear()
    with pytest.raises(ValueError, match="unknown scope 'everything'"):
        get_settings()
    get_settings.cache_clear()
