"""Security: API keys (stored hashed) for writes, optional for reads; read-only mode; the
management commands; file names as data; security headers; hostile values and bodies.

(CORS off by default and the request size limit are tested in test_health.py and
test_bad_input.py; a ``<script>`` track name shown as text in tests/browser.)
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys

import pytest

from api.api_support import db_file, is_sqlite, row_counts, sql, upload
from app.cli import main as cli_main
from app.core.config import REPO_ROOT, get_settings


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


# ------------------------------------------------------------------------------------------
# Management commands as an operator runs them: python -m app ...
# ------------------------------------------------------------------------------------------


def _manage(settings, *argv: str) -> subprocess.CompletedProcess[str]:
    """``python -m app ARGV`` in a separate process on the test's database."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("TRACKPROFILE_")}
    env |= {"DATABASE_URL": settings.sqlalchemy_url, "PYTHONPATH": str(REPO_ROOT)}
    return subprocess.run(
        [sys.executable, "-m", "app", *argv],
        cwd=REPO_ROOT, env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip


@pytest.mark.slow
def test_key_commands_create_list_and_revoke(start_app, settings) -> None:
    """`python -m app create-key` prints a key once that then opens writes; `list-keys`
    shows its prefix only; `revoke-key` closes it again (401 naming the reason); revoking
    an unknown id fails with exit code 2."""
    c = start_app(require_api_key=True)
    created = _manage(settings, "create-key", "fleet pipeline")
    assert created.returncode == 0, created.stderr
    key = created.stdout.strip().splitlines()[-1]
    assert key.startswith("tp_") and len(key) > 40
    headers = {"X-API-Key": key}
    assert c.post("/api/v1/tracks", json={"name": "K1"}, headers=headers).status_code == 201
    listing = _manage(settings, "list-keys")
    assert "fleet pipeline" in listing.stdout and key[:10] in listing.stdout
    assert key not in listing.stdout
    key_id = listing.stdout.split()[0]
    assert _manage(settings, "revoke-key", key_id).returncode == 0
    r = c.post("/api/v1/tracks", json={"name": "K2"}, headers=headers)
    assert r.status_code == 401 and "revoked" in r.json()["detail"]["message"]
    assert _manage(settings, "revoke-key", "999").returncode == 2
    assert row_counts(settings)["tracks"] == 1


def test_only_bearer_or_header_keys_count(start_app, settings, monkeypatch) -> None:
    """A valid key in another place (query string, Basic auth, a cookie) does not open
    writes: 401 and nothing stored."""
    c = start_app(require_api_key=True)
    key = _create_key(monkeypatch, settings)
    before = row_counts(settings)
    for kwargs in (
        {"params": {"api_key": key}},
        {"headers": {"Authorization": f"Basic {key}"}},
        {"headers": {"Cookie": f"X-API-Key={key}"}},
    ):
        r = c.post("/api/v1/tracks", json={"name": "x"}, **kwargs)
        assert r.status_code == 401, kwargs
    assert row_counts(settings) == before


def test_read_only_mode_wins_over_a_valid_key(start_app, settings, monkeypatch) -> None:
    """Read-only mode refuses writes even with a valid API key; reads still need the key when
    configured so."""
    key = _create_key(monkeypatch, settings)
    c = start_app(read_only=True, require_api_key=True, require_api_key_for_reads=True)
    r = c.post("/api/v1/tracks", json={"name": "x"}, headers={"X-API-Key": key})
    assert r.status_code == 403
    assert c.get("/api/v1/tracks").status_code == 401
    assert c.get("/api/v1/tracks", headers={"X-API-Key": key}).status_code == 200


# ------------------------------------------------------------------------------------------
# File names, headers, hostile values
# ------------------------------------------------------------------------------------------

HOSTILE_FILENAMES = {
    "../../etc/passwd": "passwd",
    "..\\..\\windows\\win.ini": "win.ini",
    "/tmp/evil.csv": "evil.csv",
    "run\x07\x1b.csv": "run.csv",
    "<img src=x onerror=alert(1)>.csv": "<img src=x onerror=alert(1)>.csv",
    "x" * 400: "x" * 255,
}


def test_file_names_are_data_never_paths(client, settings, synthetic_run, tmp_path) -> None:
    """Uploads named like paths are stored under their last component only (control
    characters dropped, 255 characters at most), and no file appears anywhere: the upload is
    never written to disk."""
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    stored = []
    for k, (name, expected) in enumerate(HOSTILE_FILENAMES.items()):
        # The multipart body is written by hand so that the name arrives byte for byte.
        body = (
            b"--b\r\nContent-Disposition: form-data; name=\"track\"\r\n\r\nfiles\r\n"
            b"--b\r\nContent-Disposition: form-data; name=\"start_chainage_m\"\r\n\r\n12\r\n"
            b"--b\r\nContent-Disposition: form-data; name=\"file\"; filename=\""
            + name.encode() + b"\"\r\nContent-Type: text/csv\r\n\r\n"
            + synthetic_run["csv"] + b"\n" * k + b"\r\n--b--\r\n"
        )  # fmt: skip
        r = client.post(
            "/api/v1/runs", content=body,
            headers={"content-type": "multipart/form-data; boundary=b"},
        )  # fmt: skip
        assert r.status_code == 201, (name, r.text)
        stored.append((r.json()["original_filename"], expected))
    assert all(got == want for got, want in stored), stored
    after = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    new = {str(p) for p in after} - {str(p) for p in before}
    assert all(p.startswith("trackprofile.db") for p in new), new  # the database (WAL) only
    for name in ("passwd", "win.ini", "evil.csv"):
        assert not list(tmp_path.rglob(name))


def test_security_headers_on_every_kind_of_answer(start_app, synthetic_run) -> None:
    """nosniff, frame denial, no referrer and the CSP are on JSON, CSV, HTML, static files
    and on errors: 401, 404, 405, 413 (answered before the body is read), 415, 422.
    (With keys required the key is checked first: 405 and 413 come from an open app.)"""
    c = start_app(max_upload_mb=0.01, require_api_key=True)
    open_app = start_app(max_upload_mb=0.01)
    answers = {
        "json": c.get("/api/v1/tracks"),
        "html": c.get("/"),
        "static": c.get("/static/index.html"),
        "docs": c.get("/docs"),
        "401": c.post("/api/v1/tracks", json={"name": "x"}),
        "404": c.get("/api/v1/runs/1"),
        "405": open_app.put("/api/v1/runs/1"),
        "413": upload(open_app, synthetic_run["csv"], track="t", start_chainage_m=1),
        "422": c.get("/api/v1/runs", params={"limit": 0}),
    }
    assert {k: r.status_code for k, r in answers.items()} == {
        "json": 200, "html": 200, "static": 200, "docs": 200, "401": 401, "404": 404,
        "405": 405, "413": 413, "422": 422,
    }  # fmt: skip
    for kind, r in answers.items():
        assert r.headers.get("x-content-type-options") == "nosniff", kind
        assert r.headers.get("x-frame-options") == "DENY", kind
        assert r.headers.get("referrer-policy") == "no-referrer", kind
        assert "frame-ancestors 'none'" in r.headers.get("content-security-policy", ""), kind
    assert "script-src 'self';" in answers["html"].headers["content-security-policy"]


def test_out_of_range_numbers_are_4xx_not_5xx(client, settings) -> None:
    """Ids and offsets beyond 64 bits, negative or huge pages are refused with 4xx naming the
    problem (a 5xx would also drop the connection)."""
    huge = "99999999999999999999999"
    for path in (
        f"/api/v1/runs/{huge}", f"/api/v1/runs/{huge}/profile", f"/api/v1/tracks/{huge}",
        f"/api/v1/vehicles/{huge}", f"/api/v1/runs?offset={huge}",
        f"/api/v1/tracks?offset={huge}", f"/api/v1/vehicles?offset={huge}",
    ):  # fmt: skip
        r = client.get(path)
        assert r.status_code == 422, (path, r.text)
        assert "out of range" in r.json()["detail"]["message"]
    assert client.delete(f"/api/v1/runs/{huge}").status_code == 422
    for query in ("limit=-1", "limit=0", "limit=100000", f"limit={huge}", "offset=-1"):
        r = client.get(f"/api/v1/runs?{query}")
        assert r.status_code == 422, query
        assert r.json()["detail"]["field"] in ("limit", "offset")
    for bad in ("-1", "0"):  # ids start at 1: a malformed id, not an unknown one
        r = client.get(f"/api/v1/runs/{bad}")
        assert r.status_code == 422 and r.json()["detail"]["field"] == "run_id", r.text


def test_nul_and_sql_like_text_is_plain_data(client, settings) -> None:
    """Names shaped like SQL are stored and found verbatim and every table survives; a NUL
    character in a looked-up name is a 4xx on any database."""
    names = ["x'; DROP TABLE runs;--", 'Robert"); DELETE FROM tracks; --', "%' OR '1'='1"]
    for name in names:
        r = client.post("/api/v1/tracks", json={"name": name})
        assert r.status_code == 201, r.text
        assert client.get(f"/api/v1/tracks/{r.json()['id']}").json()["name"] == name
        assert client.get("/api/v1/runs", params={"track": name}).json()["count"] == 0
    assert client.get("/api/v1/tracks").json()["count"] == 3
    assert client.get("/api/v1/runs", params={"track": "%"}).status_code == 404  # no LIKE
    r = client.get("/api/v1/tracks/%00")
    assert 400 <= r.status_code < 500
    r = client.post("/api/v1/tracks", json={"name": "nul", "description": "a\u0000b"})
    assert r.status_code in (201, 422), r.text  # SQLite keeps NUL; PostgreSQL refuses it
    assert set(row_counts(settings)) >= {"runs", "tracks", "vehicles"}


def test_hostile_bodies_are_4xx(client, settings) -> None:
    """Deeply nested JSON, a JSON string, form data where JSON is expected, 1000 form fields
    and a 2 MB form field are all refused with 4xx and store nothing."""
    before = row_counts(settings)
    js = {"content-type": "application/json"}
    cases = {
        "nested arrays": client.post("/api/v1/runs", content=b"[" * 100_000 + b"]" * 100_000,
                                     headers=js),
        "nested objects": client.post("/api/v1/runs", content=b'{"a":' * 50_000 + b"1"
                                      + b"}" * 50_000, headers=js),
        "JSON string": client.post("/api/v1/tracks", content=b'"hello"', headers=js),
        "form to a JSON endpoint": client.post("/api/v1/tracks", data={"name": "x"}),
        "1000 form fields": client.post(
            "/api/v1/runs", files={"file": ("a.csv", b"x")},
            data={f"f{i}": "x" for i in range(1000)},
        ),
        "2 MB form field": client.post(
            "/api/v1/runs", files={"file": ("a.csv", b"x")}, data={"track": "t" * 2_000_000}
        ),
        "multipart without boundary": client.post(
            "/api/v1/runs", content=b"abc", headers={"content-type": "multipart/form-data"}
        ),
    }  # fmt: skip
    for case, r in cases.items():
        assert 400 <= r.status_code < 500, (case, r.status_code, r.text[:200])
        assert r.json()["detail"]["message"], case
    assert row_counts(settings) == before


def test_track_names_and_urls(client, synthetic_run) -> None:
    """A new track named by digits only (it would read as an id) or '.'/'..' is refused with
    a 422 naming the field; a name with '/' is kept as data and its track is addressed by
    id (as the dashboard does)."""
    for name in ("4011", ".", ".."):
        r = client.post("/api/v1/tracks", json={"name": name})
        assert r.status_code == 422, name
        assert r.json()["detail"]["field"] == "name"
        r = upload(client, synthetic_run["csv"], track=name, start_chainage_m=12)
        assert r.status_code == 422 and r.json()["detail"]["field"] == "track", name
    r = client.post("/api/v1/tracks", json={"name": "up/down line 4011"})
    assert r.status_code == 201
    tid = r.json()["id"]
    assert client.get(f"/api/v1/tracks/{tid}").json()["name"] == "up/down line 4011"
    r = upload(client, synthetic_run["csv"], track="up/down line 4011", start_chainage_m=12)
    assert r.status_code == 201 and r.json()["track_id"] == tid
    assert client.get("/api/v1/runs", params={"track": str(tid)}).json()["count"] == 1


def _api_operations(c) -> list[tuple[str, str]]:
    """Every (method, path) of the OpenAPI document under /api/v1, path parameters set to 1."""
    import re

    ops = []
    for path, item in c.get("/openapi.json").json()["paths"].items():
        if path.startswith("/api/v1"):
            for method in item:
                ops.append((method.upper(), re.sub(r"\{[^}]+\}", "1", path)))
    return ops


def test_every_write_endpoint_is_guarded(start_app, settings) -> None:
    """Every POST/PUT/PATCH/DELETE of the API (read from the OpenAPI document, so endpoints
    added later are covered) is 401 without a key when keys are required and 403 in
    read-only mode; GETs need a key only when reads are closed too."""
    keyed = start_app(require_api_key=True, require_api_key_for_reads=True, public_docs=True)
    ops = _api_operations(keyed)
    writes = [(m, p) for m, p in ops if m in ("POST", "PUT", "PATCH", "DELETE")]
    reads = [(m, p) for m, p in ops if m == "GET"]
    assert len(writes) >= 6 and len(reads) >= 10
    before = row_counts(settings)
    for method, path in writes + reads:
        r = keyed.request(method, path, json={})
        assert r.status_code == 401, (method, path, r.status_code)
    read_only = start_app(read_only=True)
    for method, path in writes:
        r = read_only.request(method, path, json={})
        assert r.status_code == 403, (method, path, r.status_code)
    assert row_counts(settings) == before
