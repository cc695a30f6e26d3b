"""Access control: API keys (stored hashed) for writes, optional for reads; read-only mode."""

from __future__ import annotations

import hashlib

from api.api_support import db_file, is_sqlite, row_counts, sql
from app.cli import main as cli_main
from app.core.config import get_settings


def _create_key(monkeypatch, settings, name: str = "pipeline") -> str:
    monkeypatch.setenv("DATABASE_URL", settings.sqlalchemy_url)
    get_settings.cache_clear()
    try:
        import contextlib
        import io

        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            assert cli_main(["create-key", name]) == 0
    finally:
        get_settings.cache_clear()
    return out.getvalue().strip().splitlines()[-1]


def test_writes_need_a_valid_key_when_keys_are_required(start_app, settings, monkeypatch):
    """With keys required: no key or a wrong key is 401 and stores nothing; a created key
    works (X-API-Key or Bearer); reads stay open for the dashboard."""
    c = start_app(require_api_key=True)
    body = {"name": "L1"}
    before = row_counts(settings)
    r = c.post("/api/v1/tracks", json=body)
    assert r.status_code == 401
    assert r.json()["detail"]["field"] == "X-API-Key"
    assert c.post("/api/v1/tracks", json=body, headers={"X-API-Key": "tp_guess"}).status_code == 401
    assert row_counts(settings) == before
    key = _create_key(monkeypatch, settings)
    assert c.post("/api/v1/tracks", json=body, headers={"X-API-Key": key}).status_code == 201
    bearer = {"Authorization": f"Bearer {key}"}
    assert c.post("/api/v1/tracks", json={"name": "L2"}, headers=bearer).status_code == 201
    assert c.get("/api/v1/tracks").status_code == 200
    assert c.delete("/api/v1/runs/1").status_code == 401


def test_keys_are_stored_hashed_and_can_be_revoked(start_app, settings, monkeypatch) -> None:
    """Only the SHA-256 of a key is in the database; a revoked key stops working."""
    c = start_app(require_api_key=True)
    key = _create_key(monkeypatch, settings)
    stored = sql(settings, "SELECT key_hash, prefix FROM api_keys")
    assert stored == [(hashlib.sha256(key.encode()).hexdigest(), key[:10])]
    if is_sqlite(settings):
        assert key.encode() not in db_file(settings).read_bytes()
    assert (
        c.post("/api/v1/tracks", json={"name": "a"}, headers={"X-API-Key": key}).status_code == 201
    )
    monkeypatch.setenv("DATABASE_URL", settings.sqlalchemy_url)
    get_settings.cache_clear()
    assert cli_main(["revoke-key", "1"]) == 0
    get_settings.cache_clear()
    r = c.post("/api/v1/tracks", json={"name": "b"}, headers={"X-API-Key": key})
    assert r.status_code == 401
    assert "revoked" in r.json()["detail"]["message"]


def test_reads_can_require_a_key_too(start_app) -> None:
    """require_api_key_for_reads closes the read endpoints as well (health stays open)."""
    c = start_app(require_api_key=True, require_api_key_for_reads=True)
    assert c.get("/api/v1/tracks").status_code == 401
    assert c.get("/healthz").status_code == 200


def test_read_only_mode_refuses_every_write(start_app, settings) -> None:
    """In read-only mode uploads, creations and deletions are 403; reads work."""
    c = start_app(read_only=True)
    before = row_counts(settings)
    assert c.post("/api/v1/tracks", json={"name": "x"}).status_code == 403
    assert c.post("/api/v1/simulate", json={}).status_code == 403
    r = c.post("/api/v1/runs", files={"file": ("a.csv", b"x")}, data={"track": "t"})
    assert r.status_code == 403
    assert "read-only" in r.json()["detail"]["message"]
    assert c.delete("/api/v1/runs/1").status_code == 403
    assert c.get("/api/v1/vehicles").status_code == 200
    assert row_counts(settings) == before
