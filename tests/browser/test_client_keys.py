"""The dashboard reads only what the API's OpenAPI schema promises.

``static/js/api.js`` records, when the page sets ``window.__tpKeyLog`` before it loads, every
key the client reads from an answer (method, URL, key path). This test walks the pages a user
walks (home, a run, a track with its register, the upload preview) in a real
browser, then looks every recorded key up in the served ``/openapi.json``: a key that no schema
has (a guess such as ``run_count ?? n_runs``, a field renamed on the server) fails it.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import pytest
from browser.harness import LiveServer, wait_for_plot

pytestmark = pytest.mark.browser

TRACK = "Keys line"


def _resolve(spec: dict[str, Any], schema: dict[str, Any]) -> dict[str, Any]:
    while "$ref" in schema:
        schema = spec["components"]["schemas"][schema["$ref"].rsplit("/", 1)[1]]
    return schema


def _variants(spec: dict[str, Any], schema: dict[str, Any]) -> list[dict[str, Any]]:
    """The object/array schemas a value may have (anyOf/oneOf unfolded, null left out)."""
    schema = _resolve(spec, schema)
    out: list[dict[str, Any]] = []
    for alt in schema.get("anyOf", []) + schema.get("oneOf", []) + schema.get("allOf", []):
        out.extend(_variants(spec, alt))
    if not out:
        out.append(schema)
    return [s for s in out if s.get("type") != "null"]


def _key_exists(spec: dict[str, Any], schema: dict[str, Any], path: list[str]) -> bool:
    if not path:
        return True
    head, rest = path[0], path[1:]
    for s in _variants(spec, schema):
        if head == "[]" and "items" in s:
            if _key_exists(spec, s["items"], rest):
                return True
        elif head in s.get("properties", {}):
            if _key_exists(spec, s["properties"][head], rest):
                return True
        elif isinstance(s.get("additionalProperties"), dict) and _key_exists(
            spec, s["additionalProperties"], rest
        ):
            return True
    return False


def _operation(spec: dict[str, Any], method: str, url: str) -> tuple[str, dict[str, Any]] | None:
    path = urlsplit(url).path
    for template, ops in spec["paths"].items():
        pattern = "^" + re.sub(r"\{[^}]+\}", "[^/]+", template) + "$"
        if re.match(pattern, path) and method.lower() in ops:
            return template, ops[method.lower()]
    return None


def _response_schema(op: dict[str, Any]) -> dict[str, Any] | None:
    for code in ("200", "201", "202"):
        content = op.get("responses", {}).get(code, {}).get("content", {})
        if "application/json" in content:
            return content["application/json"].get("schema")
    return None


@pytest.mark.slow
def test_every_key_the_dashboard_reads_is_in_the_openapi_schema(
    page: Any, live_server: LiveServer, sample_csv: Path
) -> None:
    """Keys read by the home, run, track and upload pages all exist in the schema of
    the answer they were read from (and the walk did read keys from those endpoints)."""
    with live_server.api() as api:
        for k in range(2):
            r = api.post(
                "/api/v1/simulate?wait=true",
                json={"track": TRACK, "length_m": 300, "seed": 70 + k,
                      "zones": [{"start_m": 120, "end_m": 125, "loss": 0.5}]},
            )  # fmt: skip
            assert r.status_code in (200, 201), r.text
        run_id = r.json()["run"]["id"]
        track_id = api.get(f"/api/v1/tracks/{TRACK}").json()["id"]
        spec = api.get("/openapi.json").json()

    page.add_init_script("window.__tpKeyLog = [];")
    page.goto(f"{live_server.url}/#/")
    page.wait_for_selector("#runs-table tbody tr")
    page.goto(f"{live_server.url}/#/runs/{run_id}")
    wait_for_plot(page, "#profile-plot")
    page.goto(f"{live_server.url}/#/tracks/{track_id}")
    wait_for_plot(page, "#chainage-map")
    page.wait_for_selector("#zone-table tbody tr")
    wait_for_plot(page, "#zone-plot")
    page.goto(f"{live_server.url}/#/upload")
    page.set_input_files("#file-input", str(sample_csv))
    page.wait_for_selector("#preview-table")
    note = "() => document.querySelector('#recognised-note').textContent"
    page.wait_for_function(f"{note}.includes('by the service')")
    reads = page.evaluate("() => window.__tpKeyLog")

    bad = []
    seen_ops = set()
    for rec in reads:
        found = _operation(spec, rec["method"], rec["url"])
        assert found is not None, f"the client called {rec['method']} {rec['url']}, not in the API"
        template, op = found
        seen_ops.add(f"{rec['method']} {template}")
        schema = _response_schema(op)
        assert schema is not None, f"{rec['method']} {template} documents no JSON answer"
        if not _key_exists(spec, schema, rec["path"]):
            bad.append(f"{rec['method']} {template}: {'.'.join(rec['path'])}")
    assert not bad, (
        "keys read by the dashboard that the OpenAPI schema does not have:\n"
        + "\n".join(sorted(set(bad)))
    )
    for expected in (
        "GET /api/v1/runs", "GET /api/v1/tracks", "GET /api/v1/runs/{run_id}",
        "GET /api/v1/views/runs/{run_id}/profile", "GET /api/v1/tracks/{track}/defects",
        "GET /api/v1/views/tracks/{track}/chainage-map", "POST /api/v1/views/csv-preview",
    ):  # fmt: skip
        assert expected in seen_ops, f"the walk read nothing from {expected}: {sorted(seen_ops)}"
