"""Access before the body and a size cap on every body (issue 16, High 2 and Low).

The probe sent 300 MB JSON bodies without a key: the server read (and parsed) them before its
401, growing by ~800 MB per request. These tests talk raw HTTP/1.1 to a real uvicorn on
loopback so they can send a request's headers and *hold back its body*: a server that wants
the body before deciding never answers, one that decides on the headers answers at once.
"""

from __future__ import annotations

import json
import socket
import threading
import time
from collections.abc import Iterator

import httpx
import pytest

from api.api_support import row_counts
from api.live_server import LiveServer
from app.api.access import KeyRegister
from app.core.security import generate_key, hash_key, key_prefix
from app.db.models import ApiKey
from app.db.session import Database

BODY_ROUTES = [
    ("POST", "/api/v1/tracks"),
    ("POST", "/api/v1/vehicles"),
    ("POST", "/api/v1/simulate"),
    ("POST", "/api/v1/views/csv-preview"),
    ("PUT", "/api/v1/tracks/1/limits"),
    ("POST", "/api/v1/runs"),
]
"""Every route the probe found reading bodies before the key check."""


def _read_answer(sock: socket.socket, timeout: float) -> tuple[int, dict[str, str], bytes]:
    """Status, headers and body of the answer on ``sock`` (Content-Length framed)."""
    sock.settimeout(timeout)
    data = b""
    while b"\r\n\r\n" not in data:
        chunk = sock.recv(65536)
        if not chunk:
            break
        data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    lines = head.decode("latin-1").split("\r\n")
    status = int(lines[0].split()[1])
    headers = {k.strip().lower(): v.strip() for k, _, v in (ln.partition(":") for ln in lines[1:])}
    n = int(headers.get("content-length", "0"))
    while len(body) < n:
        chunk = sock.recv(65536)
        if not chunk:
            break
        body += chunk
    return status, headers, body


def _held_back(
    server: LiveServer, method: str, path: str, headers: dict[str, str], timeout: float = 10.0
) -> tuple[int, dict[str, str], bytes]:
    """Send the request line and headers only (the body declared, never sent); the answer."""
    assert server.port is not None
    with socket.create_connection(("127.0.0.1", server.port), timeout=timeout) as sock:
        head = f"{method} {path} HTTP/1.1\r\nHost: 127.0.0.1\r\n"
        head += "".join(f"{k}: {v}\r\n" for k, v in headers.items()) + "\r\n"
        sock.sendall(head.encode("latin-1"))
        return _read_answer(sock, timeout)


def _chunked(
    server: LiveServer,
    method: str,
    path: str,
    headers: dict[str, str],
    total: int,
    chunk: bytes,
    timeout: float = 30.0,
) -> tuple[int, dict[str, str], bytes, int]:
    """Stream up to ``total`` bytes as a chunked body until the server answers; the answer
    and how many body bytes were sent before it came."""
    assert server.port is not None
    with socket.create_connection(("127.0.0.1", server.port), timeout=timeout) as sock:
        head = f"{method} {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nTransfer-Encoding: chunked\r\n"
        head += "".join(f"{k}: {v}\r\n" for k, v in headers.items()) + "\r\n"
        sock.sendall(head.encode("latin-1"))
        sent = 0
        sock.setblocking(False)
        try:
            while sent < total:
                try:
                    if sock.recv(1, socket.MSG_PEEK):
                        break  # the server answered
                except BlockingIOError:
                    pass
                frame = f"{len(chunk):x}\r\n".encode() + chunk + b"\r\n"
                try:
                    sock.setblocking(True)
                    sock.settimeout(timeout)
                    sock.sendall(frame)
                    sent += len(chunk)
                finally:
                    sock.setblocking(False)
            else:
                sock.setblocking(True)
                sock.sendall(b"0\r\n\r\n")
        except (BrokenPipeError, ConnectionResetError):
            pass
        sock.setblocking(True)
        status, hdrs, body = _read_answer(sock, timeout)
        return status, hdrs, body, sent


def _rss_mb(server: LiveServer) -> float:
    assert server.proc is not None
    with open(f"/proc/{server.proc.pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    raise AssertionError("no VmRSS")


@pytest.fixture
def keyed_server(settings) -> Iterator[LiveServer]:
    server = LiveServer(settings, "keyed", TRACKPROFILE_REQUIRE_API_KEY="true").start()
    try:
        yield server
    finally:
        server.stop()


def _create_key(settings) -> str:
    key = generate_key()
    db = Database(settings.sqlalchemy_url)
    with db.session() as s:
        s.add(ApiKey(name="t", prefix=key_prefix(key), key_hash=hash_key(key)))
        s.commit()
    db.dispose()
    return key


@pytest.mark.slow
def test_the_key_is_checked_before_any_body_byte(keyed_server, settings) -> None:
    """Keys required: every body route answers 401 to a request whose 300 MB body was declared
    but never sent (so the server did not wait for it, let alone read it); a wrong key too.
    With a valid key the same held-back request is answered 413 at once (over its cap)."""
    for method, path in BODY_ROUTES:
        hdrs = {"Content-Type": "application/json", "Content-Length": "300000000"}
        t0 = time.monotonic()
        status, headers, body = _held_back(keyed_server, method, path, hdrs)
        assert status == 401, (method, path, status, body[:200])
        assert time.monotonic() - t0 < 5
        assert json.loads(body)["detail"]["field"] == "X-API-Key"
        assert headers["x-content-type-options"] == "nosniff"
        status, _, _ = _held_back(keyed_server, method, path, hdrs | {"X-API-Key": "tp_wrong"})
        assert status == 401, (method, path)
    key = _create_key(settings)
    for method, path in BODY_ROUTES:
        hdrs = {"Content-Type": "application/json", "Content-Length": "900000000",
                "X-API-Key": key}  # fmt: skip
        status, _, body = _held_back(keyed_server, method, path, hdrs)
        assert status == 413, (method, path, status, body[:200])
        assert json.loads(body)["detail"]["limit_bytes"] > 0


@pytest.mark.slow
def test_read_only_refuses_before_any_body_byte(settings) -> None:
    """Read-only mode: 403 to a held-back 300 MB body on every body route."""
    server = LiveServer(settings, "ro", TRACKPROFILE_READ_ONLY="true").start()
    try:
        for method, path in BODY_ROUTES:
            hdrs = {"Content-Type": "application/json", "Content-Length": "300000000"}
            status, _, body = _held_back(server, method, path, hdrs)
            assert status == 403, (method, path, status, body[:200])
    finally:
        server.stop()


@pytest.mark.slow
def test_unauthorised_bodies_cost_no_memory(keyed_server, settings) -> None:
    """Four parallel 40 MB chunked JSON bodies without a key: each is refused after at most a
    few MB were sent, and the server's RSS grows by less than 30 MB (the probe: +800 MB per
    300 MB request). Nothing is stored."""
    before_rows = row_counts(settings)
    rss0 = _rss_mb(keyed_server)
    results: list[tuple[int, int]] = []

    def one() -> None:
        status, _, _, sent = _chunked(
            keyed_server, "POST", "/api/v1/tracks", {"Content-Type": "application/json"},
            total=40_000_000, chunk=b"[" + b"0," * 32_000 + b"0]",
        )  # fmt: skip
        results.append((status, sent))

    threads = [threading.Thread(target=one) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    rss1 = _rss_mb(keyed_server)
    assert [s for s, _ in results] == [401] * 4, results
    assert max(sent for _, sent in results) < 8_000_000, results
    assert rss1 - rss0 < 30, (rss0, rss1)
    assert row_counts(settings) == before_rows


@pytest.mark.slow
def test_every_body_has_a_cap_and_chunked_bodies_get_413(settings) -> None:
    """Without keys: small-body routes (JSON objects, the CSV preview) refuse a chunked body
    over TRACKPROFILE_MAX_BODY_KB with 413 (the probe saw 400 on csv-preview and limits), and
    a declared one at once; the run upload keeps its larger limit."""
    server = LiveServer(settings, "caps", TRACKPROFILE_MAX_BODY_KB="64").start()
    try:
        for method, path, ctype in [
            ("PUT", "/api/v1/tracks/1/limits", "application/json"),
            ("POST", "/api/v1/tracks", "application/json"),
            ("POST", "/api/v1/views/csv-preview", "multipart/form-data; boundary=xyz"),
        ]:
            status, _, body, sent = _chunked(
                server, method, path, {"Content-Type": ctype}, total=30_000_000,
                chunk=b" " * 16384,
            )  # fmt: skip
            assert status == 413, (method, path, status, body[:200])
            assert json.loads(body)["detail"]["limit_bytes"] == 64_000
            assert sent < 10_000_000  # answered long before the end (socket buffers: a few MB)
        hdrs = {"Content-Type": "application/json", "Content-Length": "100000"}
        status, _, _ = _held_back(server, "POST", "/api/v1/simulate", hdrs)
        assert status == 413
        # The run upload is capped by the upload limit (512 MB here), not the small cap: it
        # gets its 1 MB body and answers (422: not a run log), not 413.
        status, _, body, _ = _chunked(
            server, "POST", "/api/v1/runs", {"Content-Type": "application/json"},
            total=1_000_000, chunk=b" " * 16384,
        )  # fmt: skip
        assert status in (400, 422), (status, body[:200])
    finally:
        server.stop()


def test_key_use_is_stamped_outside_the_request(settings) -> None:
    """A key's last use is written by the stamping thread, at most once a minute per key and
    process: 50 keyed lookups make one write."""
    from app.db.migrate import upgrade

    db = Database(settings.sqlalchemy_url)
    upgrade(db)
    key = generate_key()
    with db.session() as s:
        s.add(ApiKey(name="t", prefix=key_prefix(key), key_hash=hash_key(key)))
        s.commit()
    keys = KeyRegister(db)
    writes = []
    from sqlalchemy import event

    @event.listens_for(db.engine, "before_cursor_execute")
    def _count(_conn, _cursor, statement, *_args) -> None:  # type: ignore[no-untyped-def]
        if statement.lstrip().upper().startswith("UPDATE API_KEYS"):
            writes.append(statement)

    for _ in range(50):
        assert keys.lookup(key) is not None
    keys.flush()
    assert len(writes) == 1
    with db.session() as s:
        assert s.query(ApiKey).one().last_used_at is not None
    assert keys.lookup("tp_unknown") is None
    keys.close()
    db.dispose()


@pytest.mark.slow
def test_oversized_headers_are_refused_before_any_route(keyed_server) -> None:
    """The server runs with the HTTP parser that bounds header size (h11, as ``serve.sh`` and
    the Dockerfile start it): a 1 MB header is refused (400, or the connection closed) and
    the server's memory does not grow by it; an ordinary request on a new connection works."""
    rss0 = _rss_mb(keyed_server)
    with socket.create_connection(("127.0.0.1", keyed_server.port), timeout=10) as sock:
        try:
            sock.sendall(
                b"GET /healthz HTTP/1.1\r\nHost: x\r\nX-Big: " + b"a" * 1_000_000 + b"\r\n\r\n"
            )
            answer = sock.recv(64)
        except ConnectionError:
            answer = b""
    assert answer == b"" or answer.startswith(b"HTTP/1.1 400"), answer
    assert _rss_mb(keyed_server) - rss0 < 20
    assert httpx.get(f"{keyed_server.url}/healthz", timeout=10).status_code == 200
