"""The OpenAPI document states the rules the server enforces (issue 16, item 11): readable
and stable operation ids, CSV downloads as their own ``text/csv`` operations, errors declared
as JSON everywhere, 64-bit integers, name rules as patterns, enums for units and gravity, the
error facts the server sends; and what it says holds (``true`` is no number, ``Allow``)."""

from __future__ import annotations

import re

from api.api_support import upload

INT64_MAX = 2**63 - 1


def _ops(c) -> dict[tuple[str, str], dict]:
    paths = c.get("/openapi.json").json()["paths"]
    return {(m.upper(), p): op for p, item in paths.items() for m, op in item.items()}


def _walk(node):
    if isinstance(node, dict):
        yield node
        for v in node.values():
            yield from _walk(v)
    elif isinstance(node, list):
        for v in node:
            yield from _walk(v)


def test_operation_ids_are_the_route_names(client) -> None:
    ops = _ops(client)
    ids = [op["operationId"] for op in ops.values()]
    assert len(ids) == len(set(ids)), "operation ids must be unique"
    assert all(re.fullmatch(r"[a-z][a-z0-9_]*", i) and "api_v1" not in i for i in ids), ids
    assert ops[("POST", "/api/v1/runs")]["operationId"] == "create_run"
    assert ops[("GET", "/api/v1/tracks/{track}")]["operationId"] == "read_track"


def test_csv_downloads_are_their_own_operations(client, synthetic_run) -> None:
    ops = _ops(client)
    for path in ("/api/v1/runs/{run_id}/profile", "/api/v1/runs/{run_id}/soft-spots",
                 "/api/v1/tracks/{track}/profile", "/api/v1/tracks/{track}/defects",
                 "/api/v1/tracks/{track}/alerts", "/api/v1/tracks/{track}/stiffness"):  # fmt: skip
        json_op, csv_op = ops[("GET", path)], ops[("GET", path + ".csv")]
        assert list(json_op["responses"]["200"]["content"]) == ["application/json"], path
        assert list(csv_op["responses"]["200"]["content"]) == ["text/csv"], path
        assert "format" not in {p["name"] for p in json_op.get("parameters", [])}
    r = upload(client, synthetic_run["csv"], track="L", start_chainage_m=12)
    run_id = r.json()["id"]
    twin = client.get(f"/api/v1/runs/{run_id}/profile.csv?from_m=50&to_m=60")
    old = client.get(f"/api/v1/runs/{run_id}/profile?format=csv&from_m=50&to_m=60")
    assert twin.status_code == 200 and twin.headers["content-type"].startswith("text/csv")
    assert twin.text == old.text and twin.text.startswith("chainage_m,level_mm")
    bad = client.get(f"/api/v1/runs/{run_id}/profile.csv?from_m=60&to_m=50")
    assert bad.status_code == 422 and bad.headers["content-type"] == "application/json"
    assert client.get("/api/v1/tracks/L/defects.csv").headers["content-type"].startswith("text/csv")


def test_errors_are_declared_as_json_everywhere(client) -> None:
    for (_m, path), op in _ops(client).items():
        for code, response in op["responses"].items():
            if code[0] in "45":
                assert list(response["content"]) == ["application/json"], (path, code)
    r = client.get("/api/v1/tracks/nowhere/report")
    assert r.status_code == 404 and r.headers["content-type"] == "application/json"


def test_the_schema_states_the_rules(client) -> None:
    doc = client.get("/openapi.json").json()
    ints = [n for n in _walk(doc) if n.get("type") == "integer"]
    assert ints and all(n.get("maximum", INT64_MAX + 1) <= INT64_MAX for n in ints)
    schemas = doc["components"]["schemas"]
    name = schemas["TrackCreate"]["properties"]["name"]
    assert re.fullmatch(name["pattern"], "Line 12 up")
    for bad in ("12", "..", "   ", "a\nb"):
        assert not re.fullmatch(name["pattern"], bad), bad
    form = schemas["RunCreateJson"]["properties"]
    assert form["gravity"]["enum"] == ["auto", "included", "removed"]
    speed_unit = next(a for a in form["speed_unit"]["anyOf"] if a.get("type") == "string")
    assert "km/h" in speed_unit["enum"] and "m/s" in speed_unit["enum"]
    detail = schemas["ErrorDetail"]["properties"]
    assert {"kind", "limit_bytes", "scope", "field", "column", "row"} <= set(detail)
    params = {p["name"]: p for p in _ops(client)[("GET", "/api/v1/runs/{run_id}/profile")][
        "parameters"]}  # fmt: skip
    assert "not below from_m" in params["to_m"]["description"]
    assert "SurveyCreateJson" in schemas


def test_what_the_schema_says_holds(client) -> None:
    r = client.post("/api/v1/tracks", json={"name": "L", "c_support": False})
    assert r.status_code == 422 and r.json()["detail"]["field"] == "c_support"
    r = client.options("/api/v1/vehicles/presets")
    assert r.status_code == 405 and r.headers["allow"] == "GET"  # not PATCH: no vehicle
    r = client.options("/api/v1/runs/1")
    assert r.headers["allow"] == "DELETE, GET"
    r = client.post("/api/v1/tracks", json={"name": "L", "EI": 1e308})
    assert r.status_code == 422 and r.json()["detail"]["field"] == "EI"
