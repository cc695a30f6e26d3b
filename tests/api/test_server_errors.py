"""5xx answers (issue 16, Medium 7 and 8): a busy database is 503 with Retry-After, keyed reads
do not write, and an unexpected error's 500 carries the security headers."""

from __future__ import annotations

import sqlite3
import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from api.api_support import is_sqlite
from app.core.security import generate_key, hash_key, key_prefix
from app.db import session as db_session
from app.db.models import ApiKey
from app.main import create_app
from support.app_fixtures import make_settings

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    from starlette.testclient import TestClient


@contextmanager
def _write_locked(path: str) -> Iterator[None]:
    """Hold SQLite's write lock on ``path`` (as a long store does) while inside."""
    conn = sqlite3.connect(path, isolation_level=None)
    conn.execute("BEGIN IMMEDIATE")
    try:
        yield
    finally:
        conn.execute("ROLLBACK")
        conn.close()


def _add_key(app_client: TestClient) -> str:
    key = generate_key()
    db = app_client.app.state.ctx.db  # type: ignore[attr-defined]
    with db.session() as s:
        s.add(ApiKey(name="t", prefix=key_prefix(key), key_hash=hash_key(key)))
        s.commit()
    return key


@pytest.mark.sqlite_only
def test_keyed_reads_do_not_write_and_busy_writes_are_503(tmp_path, monkeypatch) -> None:
    """While another connection holds the write lock (a long store): keyed reads answer at
    once (the probe: 30 s, then 500 'database is locked', because each read stamped the key);
    a write that cannot get the lock within the busy timeout is 503 with Retry-After."""
    monkeypatch.setattr(db_session, "SQLITE_BUSY_TIMEOUT_MS", 300)
    settings = make_settings(
        tmp_path, require_api_key=True, require_api_key_for_reads=True, start_worker=False
    )
    assert is_sqlite(settings)
    with TestClient(create_app(settings)) as c:
        key = _add_key(c)
        hdrs = {"X-API-Key": key}
        assert c.get("/api/v1/runs", headers=hdrs).status_code == 200
        c.app.state.keys.flush()  # type: ignore[attr-defined]
        with _write_locked(str(tmp_path / "trackprofile.db")):
            t0 = time.monotonic()
            for _ in range(20):
                assert c.get("/api/v1/runs", headers=hdrs).status_code == 200
                assert c.get("/api/v1/tracks", headers=hdrs).status_code == 200
            assert time.monotonic() - t0 < 5
            r = c.post("/api/v1/tracks", json={"name": "L1"}, headers=hdrs)
            assert r.status_code == 503, r.text
            assert r.headers["retry-after"] == "2"
            assert r.json()["detail"]["kind"] == "DatabaseBusy"
            assert r.headers["x-content-type-options"] == "nosniff"
        assert c.post("/api/v1/tracks", json={"name": "L1"}, headers=hdrs).status_code == 201


def test_a_500_carries_the_security_headers(settings) -> None:
    """An unexpected error is a 500 JSON answer with the security headers and no details."""
    app = create_app(settings)

    def broken() -> None:
        raise RuntimeError("secret internals")

    app.add_api_route("/api/v1/broken", broken)
    with TestClient(app, raise_server_exceptions=False) as c:
        r = c.get("/api/v1/broken")
    assert r.status_code == 500
    assert r.json()["detail"]["kind"] == "InternalError"
    assert "secret" not in r.text
    assert r.headers["x-content-type-options"] == "nosniff"
    assert "frame-ancestors 'none'" in r.headers["content-security-policy"]
