"""The API tells the truth about itself (issue 16, item 11 and the low items): security as
configured in the OpenAPI document, 405 answers that list every method, strict numbers,
names without look-alike characters, idempotency keys per API key, a quiet /healthz, an
unknown-vehicle error that does not list the stored vehicles."""

from __future__ import annotations

from api.api_support import upload
from app.core.security import generate_key, hash_key, key_prefix
from app.db.models import ApiKey


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
    closed = _ops(start_app(require_api_key=True, require_api_key_for_reads=True))
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
