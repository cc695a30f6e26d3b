"""Health check, security headers, CORS default, and the locally served pages and assets."""

from __future__ import annotations

from starlette.testclient import TestClient


def test_healthz_reports_database_and_worker(client: TestClient) -> None:
    """/healthz answers 200 with the database reachable and the worker running."""
    r = client.get("/healthz")
    assert r.status_code == 200
    body = r.json()
    assert body["status"] == "ok"
    assert body["database"] == "ok"
    assert body["worker"] == "running"
    assert body["runs_processing"] == 0


def test_healthz_without_worker_is_reported(start_app) -> None:
    """With the worker disabled by configuration, health says so instead of failing."""
    c = start_app(start_worker=False)
    body = c.get("/healthz").json()
    assert body["worker"] == "disabled"
    assert body["status"] == "ok"


def test_security_headers_on_api_and_pages(client: TestClient) -> None:
    """Every answer carries nosniff, frame denial, no referrer and a strict CSP."""
    for path in ("/healthz", "/api/v1/tracks", "/api/v1/runs/999"):
        r = client.get(path)
        assert r.headers["x-content-type-options"] == "nosniff"
        assert r.headers["x-frame-options"] == "DENY"
        assert r.headers["referrer-policy"] == "no-referrer"
        csp = r.headers["content-security-policy"]
        assert "default-src 'self'" in csp
        assert "script-src 'self';" in csp  # no inline scripts outside the API docs
        assert "frame-ancestors 'none'" in csp


def test_cors_is_off_by_default(client: TestClient) -> None:
    """No CORS headers unless origins are configured, so other sites cannot call the API."""
    r = client.options(
        "/api/v1/tracks",
        headers={"Origin": "https://evil.example", "Access-Control-Request-Method": "POST"},
    )
    assert "access-control-allow-origin" not in r.headers
    r = client.get("/api/v1/tracks", headers={"Origin": "https://evil.example"})
    assert "access-control-allow-origin" not in r.headers


def test_cors_allows_configured_origin_only(start_app) -> None:
    """Configured origins get CORS headers; others still do not."""
    c = start_app(cors_origins=["https://ops.example"])
    ok = c.get("/api/v1/tracks", headers={"Origin": "https://ops.example"})
    assert ok.headers["access-control-allow-origin"] == "https://ops.example"
    other = c.get("/api/v1/tracks", headers={"Origin": "https://evil.example"})
    assert "access-control-allow-origin" not in other.headers


def test_cors_origins_from_environment_are_comma_separated(monkeypatch) -> None:
    """TRACKPROFILE_CORS_ORIGINS='a,b' gives two origins (not a JSON parse error)."""
    from app.core.config import Settings

    monkeypatch.setenv("TRACKPROFILE_CORS_ORIGINS", "https://a.example, https://b.example")
    assert Settings().cors_origins == ["https://a.example", "https://b.example"]


def test_dashboard_and_plotly_served_locally(client: TestClient) -> None:
    """/ serves the dashboard page and plotly.js comes from the installed plotly package."""
    page = client.get("/")
    assert page.status_code == 200
    assert page.headers["content-type"].startswith("text/html")
    js = client.get("/static/vendor/plotly.min.js")
    assert js.status_code == 200
    assert "javascript" in js.headers["content-type"]
    assert b"plotly.js" in js.content[:2000]
    assert len(js.content) > 1_000_000


def test_api_docs_need_no_cdn(client: TestClient) -> None:
    """/docs loads Swagger UI from this server (no CDN) and the OpenAPI document lists the API."""
    page = client.get("/docs")
    assert page.status_code == 200
    html = page.text
    assert "/docs/assets/swagger-ui-bundle.js" in html
    assert "cdn" not in html.lower()
    assert client.get("/docs/assets/swagger-ui-bundle.js").status_code == 200
    assert client.get("/docs/assets/swagger-ui.css").status_code == 200
    spec = client.get("/openapi.json").json()
    paths = spec["paths"]
    for p in (
        "/api/v1/runs",
        "/api/v1/runs/{run_id}",
        "/api/v1/runs/{run_id}/profile",
        "/api/v1/runs/{run_id}/soft-spots",
        "/api/v1/tracks",
        "/api/v1/vehicles",
        "/api/v1/simulate",
        "/healthz",
    ):
        assert p in paths, p
    body = paths["/api/v1/runs"]["post"]["requestBody"]["content"]
    assert "file" in body["multipart/form-data"]["schema"]["properties"]
    ref = body["application/json"]["schema"]["$ref"].split("/")[-1]
    assert ref in spec["components"]["schemas"]
    assert "RunColumns" in spec["components"]["schemas"]


def test_unknown_route_gives_json_error(client: TestClient) -> None:
    """A wrong URL answers 404 in the common error shape."""
    r = client.get("/api/v1/nothing-here")
    assert r.status_code == 404
    assert "message" in r.json()["detail"]
