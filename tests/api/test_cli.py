"""Management commands: migrate, the demo run, API key listing."""

from __future__ import annotations

import contextlib
import io

import pytest

from api.api_support import assert_zones_match
from app.cli import main
from app.core.config import get_settings
from support.app_fixtures import database_url_for, uses_postgres


@pytest.fixture
def env_db(monkeypatch, tmp_path):
    """Point the commands at a fresh data directory (and at the test's database: the SQLite
    file there, or its PostgreSQL database with TEST_DATABASE_URL)."""
    if uses_postgres():
        monkeypatch.setenv("DATABASE_URL", database_url_for(tmp_path))
    else:
        monkeypatch.delenv("DATABASE_URL", raising=False)
    monkeypatch.setenv("TRACKPROFILE_DATA_DIR", str(tmp_path))
    get_settings.cache_clear()
    yield tmp_path
    get_settings.cache_clear()


def _run(*argv: str) -> tuple[int, str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(list(argv))
    return code, out.getvalue()


@pytest.mark.slow
def test_demo_run_is_loaded_once_and_finds_its_zones(env_db, start_app) -> None:
    """'demo' stores a simulated run with two soft zones (once); the service then serves it
    with both zones found."""
    code, out = _run("demo")
    assert code == 0 and "stored on track 'demo'" in out
    code, out = _run("demo")
    assert code == 0 and "already stored" in out
    c = start_app()
    runs = c.get("/api/v1/runs", params={"track": "demo"}).json()
    assert runs["count"] == 1
    run = runs["data"][0]
    assert run["recorded_at"] is not None  # dated like a real pass, not "Recorded: —"
    zones = run["options"]["simulation"]["zones"]
    assert len(zones) == 2
    assert_zones_match(c.get(f"/api/v1/runs/{run['id']}/soft-spots").json(), zones)


def test_migrate_and_key_listing(env_db) -> None:
    """'migrate' creates the database; keys are listed by prefix only, then revoked."""
    code, out = _run("migrate")
    assert code == 0 and "latest schema" in out
    assert uses_postgres() or (env_db / "trackprofile.db").is_file()
    _, created = _run("create-key", "fleet")
    key = created.strip().splitlines()[-1]
    _, listing = _run("list-keys")
    assert "fleet" in listing and key[:10] in listing and key not in listing
    assert "active" in listing
    _run("revoke-key", "1")
    assert "revoked" in _run("list-keys")[1]
    assert main(["revoke-key", "99"]) == 2
