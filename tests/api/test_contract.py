"""The API tells the truth about itself (issue 16, item 11 and the low items): security as
configured in the OpenAPI document, 405 answers that list every method, strict numbers,
names without look-alike characters, idempotency keys per API key, a quiet /healthz, an
unknown-vehicle error that does not list the stored vehicles; and what a second probe and
the schema fuzzer found (issue 28's lows): 405 before 401/403, no undeclared redirects,
ids from 1, chainage in a stated range, windows outside a run, closed lists as enums,
``null`` form fields, the docs behind the read key, no ``server`` header, messages that
name what the caller knows."""

from __future__ import annotations

import dataclasses
import re

import pytest

from api.api_support import upload
from api.live_server import LiveServer
from app.core.config import REPO_ROOT
from app.core.security import generate_key, hash_key, key_prefix
from app.db.models import ApiKey
from app.services.run_lifecycle.stored_runs import EXTRA_PROFILE_COLUMNS
from engine.calibration import FITTABLE
from engine.errors import ParameterError
from engine.irregularity import SPECTRA
from engine.passes import Pass, on_grid
from engine.vehicle_kinds import KIND_PRESETS, VEHICLE_KINDS


def _ops(c) -> dict[tuple[str, str], dict]:
    paths = c.get("/openapi.json").json()["paths"]
    return {(m.upper(), p): op for p, item in paths.items() for m, op in item.items()}


def test_openapi_security_follows_the_settings(start_app) -> None:
    """Open service: no operation claims a key. Keys for writes: writes only. Keys for
    reads too: every API operation."""
    open_ = _ops(start_app())
    assert not any("security" in op for op in open_.values())
    writes = _ops(start_app(require_api_key=True))
    assert "security" in writes[("POST", "/api/v1/tracks")]
    assert "security" not in writes[("GET", "/api/v1/tracks")]
    closed = _ops(start_app(require_api_key=True, require_api_key_for_reads=True, public_docs=True))
    assert all("security" in op for (_m, p), op in closed.items() if p.startswith("/api/"))


def test_405_lists_every_method_of_the_path(client) -> None:
    r = client.put("/api/v1/runs/1")
    assert r.status_code == 405
    assert r.headers["allow"] == "DELETE, GET"
    assert r.json()["detail"]["allowed"] == ["DELETE", "GET"]
    assert r.headers["x-content-type-options"] == "nosniff"


def test_booleans_are_not_numbers(client) -> None:
    client.post("/api/v1/tracks", json={"name": "L"})
    r = client.put("/api/v1/tracks/L/limits", json={"alert_loss_pct": True})
    assert r.status_code == 422 and r.json()["detail"]["field"] == "alert_loss_pct", r.text
    assert client.put("/api/v1/tracks/L/limits", json={"alert_loss_pct": 25}).status_code == 200


def test_names_with_invisible_or_look_alike_characters_are_refused(client) -> None:
    for name in ("line\u202e1", "line\u00a01", "line\u200b1", "\ufeffline 1", "line\u30001"):
        r = client.post("/api/v1/tracks", json={"name": name})
        assert r.status_code == 422 and r.json()["detail"]["field"] == "name", name
        assert "U+" in r.json()["detail"]["message"]
    r = client.post("/api/v1/tracks", json={"name": "Linie Mu\u0308nchen"})
    assert r.json()["name"] == "Linie M\u00fcnchen"  # NFC


def test_idempotency_keys_belong_to_their_api_key(start_app, synthetic_run) -> None:
    """Two pipelines, each with its own API key, both use Idempotency-Key 'run-1' on
    different tracks: each gets its own run (globally scoped keys answered 409)."""
    c = start_app(require_api_key=True)
    db = c.app.state.ctx.db
    keys = []
    for name in ("a", "b"):
        key = generate_key()
        with db.session() as s:
            s.add(ApiKey(name=name, prefix=key_prefix(key), key_hash=hash_key(key)))
            s.commit()
        keys.append(key)
    ids = []
    for key, track in zip(keys, ("A", "B"), strict=True):
        hdrs = {"X-API-Key": key, "Idempotency-Key": "run-1"}
        r = upload(c, synthetic_run["csv"], track=track, start_chainage_m=12, headers=hdrs)
        assert r.status_code == 201, r.text
        ids.append(r.json()["id"])
        again = upload(c, synthetic_run["csv"], track=track, start_chainage_m=12, headers=hdrs)
        assert again.status_code == 200 and again.json()["id"] == ids[-1]
    assert ids[0] != ids[1]


def test_healthz_hides_counts_when_reads_need_a_key(start_app) -> None:
    assert start_app().get("/healthz").json()["runs_processing"] == 0
    closed = start_app(require_api_key=True, require_api_key_for_reads=True)
    r = closed.get("/healthz")
    assert r.status_code == 200 and r.json()["runs_processing"] is None


def test_reads_key_alone_closes_writes_too(start_app) -> None:
    """TRACKPROFILE_REQUIRE_API_KEY_FOR_READS without REQUIRE_API_KEY used to leave
    everything open: it now requires keys for reads and writes."""
    c = start_app(require_api_key_for_reads=True)
    assert c.get("/api/v1/tracks").status_code == 401
    assert c.post("/api/v1/tracks", json={"name": "x"}).status_code == 401


def test_an_unknown_vehicle_does_not_list_the_stored_ones(client, synthetic_run) -> None:
    client.post("/api/v1/vehicles", json={"name": "secret fleet car"})
    r = upload(client, synthetic_run["csv"], track="L", start_chainage_m=12, vehicle="tgv")
    assert r.status_code == 422
    message = r.json()["detail"]["message"]
    assert "secret" not in message and "table1" in message


def _add_key(c, name: str, scopes: str = "read write admin") -> str:
    key = generate_key()
    with c.app.state.ctx.db.session() as s:
        s.add(ApiKey(name=name, prefix=key_prefix(key), key_hash=hash_key(key), scopes=scopes))
        s.commit()
    return key


def test_idempotency_keys_of_an_open_service_belong_to_the_key_sent(
    start_app, synthetic_run
) -> None:
    """Keys not required: a client that sends its valid API key has Idempotency-Keys of its
    own (another client's 'run-1' on another track is not a 409 naming that client's run);
    a reused key of one's own is a 409 quoting the key as sent, not as stored."""
    c = start_app()
    a, b = _add_key(c, "a"), _add_key(c, "b")
    r = upload(c, synthetic_run["csv"], track="A", start_chainage_m=12,
               headers={"X-API-Key": a, "Idempotency-Key": "run-1"})  # fmt: skip
    assert r.status_code == 201, r.text
    first = r.json()["id"]
    r = upload(c, synthetic_run["csv"], track="B", start_chainage_m=12,
               headers={"X-API-Key": b, "Idempotency-Key": "run-1"})  # fmt: skip
    assert r.status_code == 201 and r.json()["id"] != first, r.text
    r = upload(c, synthetic_run["csv"], track="C", start_chainage_m=12,
               headers={"X-API-Key": a, "Idempotency-Key": "run-1"})  # fmt: skip
    assert r.status_code == 409, r.text
    detail = r.json()["detail"]
    assert detail["run_id"] == first and "'run-1'" in detail["message"], detail
    assert not re.search(r"key\d+:", detail["message"]), detail  # not the stored form


def test_405_comes_before_read_only_and_key_refusals(start_app) -> None:
    """A method the path does not have is 405 with Allow in read-only mode, without a key
    and with a key lacking the scope: not the 403/401 its writes would get."""
    read_only = start_app(read_only=True)
    closed = start_app(require_api_key=True, require_api_key_for_reads=True)
    reader = _add_key(closed, "reader", "read")
    for c, headers in ((read_only, {}), (closed, {}), (closed, {"X-API-Key": reader})):
        for method, path, allow in (
            ("PUT", "/api/v1/runs/1", "DELETE, GET"),
            ("POST", "/api/v1/vehicles/presets", "GET"),
            ("PATCH", "/api/v1/tracks", "GET, POST"),
        ):
            r = c.request(method, path, headers=headers)
            assert r.status_code == 405, (method, path, headers, r.text)
            assert r.headers["allow"] == allow
    assert read_only.post("/api/v1/tracks", json={"name": "x"}).status_code == 403
    assert closed.post("/api/v1/tracks", json={"name": "x"}).status_code == 401
    r = closed.post("/api/v1/tracks", json={"name": "x"}, headers={"X-API-Key": reader})
    assert r.status_code == 403 and r.json()["detail"]["kind"] == "MissingScope"


def test_no_undeclared_redirects(client) -> None:
    """An encoded slash or a trailing one is 404 (declared), not a 307 to another resource."""
    for path in ("/api/v1/vehicles/%2F", "/api/v1/vehicles/", "/api/v1/tracks/"):
        r = client.get(path, follow_redirects=False)
        assert r.status_code == 404, (path, r.status_code)
        assert "location" not in r.headers


def test_ids_start_at_one_in_the_schema_and_the_answers(client) -> None:
    """Every id parameter states minimum 1, and 0 is refused as malformed (422, the field)."""
    doc = client.get("/openapi.json").json()
    ids = [
        (path, p)
        for path, item in doc["paths"].items()
        for op in item.values()
        for p in op.get("parameters", [])
        if p["name"].endswith("_id") and p["in"] == "path"
    ]
    mine = [(path, p) for path, p in ids if p["name"] in ("run_id", "calibration_id")]
    assert len(mine) >= 8
    for path, p in mine:
        assert p["schema"].get("minimum") == 1, path
    form = doc["components"]["schemas"]["RunCreateJson"]["properties"]
    for name in ("track_id", "vehicle_id"):
        assert form[name]["anyOf"][0]["minimum"] == 1
    for url in ("/api/v1/runs/0", "/api/v1/views/runs/0/profile",
                "/api/v1/vehicles/table1/calibrations/0"):  # fmt: skip
        r = client.get(url)
        assert r.status_code == 422, (url, r.text)
        assert r.json()["detail"]["field"] in ("run_id", "calibration_id")


def test_chainage_has_a_stated_range_and_windows_must_meet_the_run(client) -> None:
    """A chainage of 1e25 is a 422 about that chainage and its range (not ids below 2^63);
    the range and the 10 km window limit are in the schema; a window outside a run's
    profile is a 422 naming the window (was a 200 with from_m above to_m)."""
    sim = client.post("/api/v1/simulate", json={"length_m": 200, "speed_mps": 45, "zones": []})
    assert sim.status_code == 201, sim.text
    rid = sim.json()["run"]["id"]
    for url in (f"/api/v1/runs/{rid}/profile?from_m=1e25",
                f"/api/v1/views/runs/{rid}/profile?to_m=-1e16",
                "/api/v1/tracks/simulated/stiffness?to_m=1e25"):  # fmt: skip
        r = client.get(url)
        assert r.status_code == 422, (url, r.text)
        detail = r.json()["detail"]
        assert detail["field"] in ("from_m", "to_m") and "10000000" in detail["message"]
        assert "2^63" not in detail["message"]
    r = upload(client, b"x", track="far", start_chainage_m=1e25)
    assert r.status_code == 422 and r.json()["detail"]["field"] == "start_chainage_m"
    for window in ("to_m=-5", "from_m=5000"):
        r = client.get(f"/api/v1/views/runs/{rid}/profile?{window}")
        assert r.status_code == 422, (window, r.text)
        assert r.json()["detail"]["field"] == window.split("=")[0]
        assert "outside run" in r.json()["detail"]["message"]
    assert client.get(f"/api/v1/views/runs/{rid}/profile?to_m=100").status_code == 200
    doc = client.get("/openapi.json").json()["paths"]
    params = {p["name"]: p for p in doc["/api/v1/views/tracks/{track}/window"]["get"]["parameters"]}
    assert params["to_m"]["schema"]["x-max-span-m"] == 10_000
    assert "10 km" in params["to_m"]["description"]
    assert params["from_m"]["schema"]["maximum"] == 1e7


def test_closed_lists_are_enums_from_the_engine_registries(client) -> None:
    """Vehicle preset (every kind), vehicle parameter names, calibration fit names, simulation
    spectrum and the profile's ``include`` are enums in the schema, made from the registries."""
    doc = client.get("/openapi.json").json()
    c = doc["components"]["schemas"]
    assert c["VehicleCreate"]["properties"]["preset"]["anyOf"][0]["enum"] == sorted(KIND_PRESETS)
    keys = c["VehicleEdit"]["properties"]["params"]["propertyNames"]["enum"]
    params_of_kinds = {f.name for kind in VEHICLE_KINDS.values() for f in dataclasses.fields(kind)}
    assert set(keys) == params_of_kinds | {"kind"}
    assert c["CalibrateRequest"]["properties"]["fit"]["anyOf"][0]["items"]["enum"] == list(FITTABLE)
    assert c["IrregularitySpec"]["properties"]["spectrum"]["enum"] == list(SPECTRA)
    for path in ("/api/v1/runs/{run_id}/profile", "/api/v1/runs/{run_id}/profile.csv"):
        [include] = [p for p in doc["paths"][path]["get"]["parameters"] if p["name"] == "include"]
        assert (include["style"], include["explode"]) == ("form", False)
        assert include["schema"]["items"]["enum"] == ["all", *EXTRA_PROFILE_COLUMNS]
    r = client.get("/api/v1/runs/1/profile?include=front_level_mm,")
    assert r.status_code in (404, 422)  # (no run 1: the name check comes with the run)


@pytest.mark.parametrize("field", ["track_id", "vehicle_id", "start_chainage_m", "direction"])
def test_null_form_fields_are_unset(client, synthetic_run, field) -> None:
    """A multipart field sent as ``null`` (how HTTP clients write None in a form) on a field
    that is not free text is unset, as an empty one is; on a name it stays a name."""
    fields = {"track": "L", "start_chainage_m": 12, field: "null"}
    r = upload(client, synthetic_run["csv"], **fields)
    if field == "start_chainage_m":  # unset, and the log has no chainage column: required
        assert r.status_code == 422 and "start_chainage_m" in r.json()["detail"]["message"]
        return
    assert r.status_code == 201, r.text


def test_null_on_a_name_is_a_name(client, synthetic_run) -> None:
    r = upload(client, synthetic_run["csv"], track="null", start_chainage_m=12, name="null")
    assert r.status_code == 201, r.text
    assert (r.json()["track"], r.json()["name"]) == ("null", "null")


@pytest.mark.slow
def test_docs_follow_the_read_key_unless_public(start_app, settings) -> None:
    """With reads closed, /docs and /openapi.json need a key (Swagger's assets do not);
    TRACKPROFILE_PUBLIC_DOCS opens them; an open service always shows them."""
    closed = start_app(require_api_key=True, require_api_key_for_reads=True)
    key = _add_key(closed, "reader", "read")
    for path in ("/openapi.json", "/docs"):
        assert closed.get(path).status_code == 401, path
        assert closed.get(path, headers={"X-API-Key": key}).status_code == 200, path
    assert closed.get("/docs/assets/swagger-ui.css").status_code == 200
    public = start_app(require_api_key=True, require_api_key_for_reads=True, public_docs=True)
    assert public.get("/openapi.json").status_code == 200
    assert public.get("/api/v1/tracks").status_code == 401
    assert start_app().get("/openapi.json").status_code == 200


@pytest.mark.slow
def test_no_server_header_from_the_served_process(settings) -> None:
    """uvicorn as the service is started (serve.sh, Dockerfile, the tests' live servers)
    sends no ``server`` header, which would name the server to a prober."""
    for launcher in ("scripts/serve.sh", "Dockerfile"):
        text = (REPO_ROOT / launcher).read_text()
        assert "--no-server-header" in text, launcher
    server = LiveServer(settings, "headers").start()
    try:
        import httpx

        r = httpx.get(server.url + "/healthz", timeout=10)
        assert r.status_code == 200 and "server" not in r.headers
    finally:
        server.stop()


def test_a_pass_is_named_as_the_caller_knows_it() -> None:
    """A separation error names the pass by its label (``run 13``: the run's id in the API),
    not by its place in an internal list (``pass 0``)."""
    import numpy as np

    x = np.arange(0.0, 10.0, 0.25)
    bad = Pass(chainage_m=x, level_mm=np.zeros_like(x), force_n=-1.0, kind="run", label="run 13")
    with pytest.raises(ParameterError) as err:
        on_grid([bad], 0.25)
    assert str(err.value).startswith("run 13:") and "pass 0" not in str(err.value)


def test_csv_preview_takes_a_file_part_and_its_options_only(client) -> None:
    """The preview's ``file`` must be a file part (a text field of that name was read as
    the file), and a form field the preview does not know is refused, naming it."""
    r = client.post("/api/v1/views/csv-preview", data={"file": "-309"})
    assert r.status_code == 422 and r.json()["detail"]["field"] == "file", r.text
    csv = b"time_s,accel_z_mps2\n0,0.1\n"
    r = client.post("/api/v1/views/csv-preview", files={"file": ("a.csv", csv)},
                    data={"MO2": "{}"})  # fmt: skip
    assert r.status_code == 422 and r.json()["detail"]["field"] == "MO2", r.text
    r = client.post("/api/v1/views/csv-preview", files={"file": ("a.csv", csv)},
                    data={"time_column": "time_s"})  # fmt: skip
    assert r.status_code == 200, r.text
