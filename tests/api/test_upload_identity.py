"""What makes an upload a duplicate: the log's content, whatever the options sent with it.

A log is one pass over the track. A browser upload and a pipeline's curl of the same file
(with other options) once stored two runs that then "confirmed" each other in the register;
now the stored run answers, naming the options that were not applied. 45 identical
concurrent uploads were each inverted before deduplication.
"""

from __future__ import annotations

import threading

from api.api_support import upload
from app.services.run_lifecycle import inversion as inversion_module


def test_the_same_log_with_other_options_is_the_stored_run(client, synthetic_run) -> None:
    """The same bytes again answer 200 duplicate with the first run, whatever the options;
    the answer names the options that differ (not applied) and how to read the log
    differently; the same options again name none."""
    first = upload(client, synthetic_run["csv"], track="L", start_chainage_m=12)
    assert first.status_code == 201
    again = upload(client, synthetic_run["csv"], track="L", start_chainage_m=12)
    assert again.status_code == 200 and again.json()["duplicate"] is True
    assert again.json()["id"] == first.json()["id"] and again.json()["ignored"] == []
    for change, named in (
        ({"start_chainage_m": 14}, ["start_chainage_m"]),
        ({"start_chainage_m": 12, "direction": "decreasing"}, ["direction"]),
        ({"start_chainage_m": 12, "accel_unit": "g"}, ["accel_unit"]),
        ({"start_chainage_m": 12, "vehicle": "heavy"}, ["vehicle"]),
    ):
        r = upload(client, synthetic_run["csv"], track="L", **change)
        assert r.status_code == 200, (change, r.text)
        body = r.json()
        assert body["duplicate"] is True and body["id"] == first.json()["id"], change
        assert body["ignored"] == named, (change, body["ignored"])
        assert f"delete run {body['id']}" in body["note"]
    runs = client.get("/api/v1/runs", params={"track": "L"}).json()["data"]
    assert len(runs) == 1


def test_a_log_uploaded_twice_with_other_options_is_one_pass_in_the_register(
    client, synthetic_run
) -> None:
    """The browser's upload (form fields) and a pipeline's (other vehicle field, a name) of
    the same file: one run, and every defect of the register is supported by one pass
    (status new, 1 pass) — not confirmed by its own copy."""
    a = upload(client, synthetic_run["csv"], "run.csv", track="R", start_chainage_m=12)
    b = upload(
        client, synthetic_run["csv"], "copy.csv", track="R", start_chainage_m=12.5,
        vehicle="table1", name="from the pipeline",
    )  # fmt: skip
    assert a.status_code == 201 and b.status_code == 200, b.text
    defects = client.get("/api/v1/tracks/R/defects").json()
    assert defects, "the synthetic run has a 50 % soft zone"
    assert all(d["runs_seen"] == 1 and d["status"] == "new" for d in defects), defects


def test_identical_concurrent_uploads_are_inverted_once(client, synthetic_run,
                                                         monkeypatch) -> None:  # fmt: skip
    """Eight identical uploads at once: one run stored, one inversion; the others answer the
    stored run as a duplicate."""
    calls = []
    real = inversion_module.invert

    def counting(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(inversion_module, "invert", counting)
    answers: list[tuple[int, int]] = []

    def one() -> None:
        r = upload(client, synthetic_run["csv"], track="C", start_chainage_m=12)
        answers.append((r.status_code, r.json()["id"]))

    threads = [threading.Thread(target=one) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    assert sorted(s for s, _ in answers) == [200] * 7 + [201], answers
    assert len({i for _, i in answers}) == 1
    assert len(calls) == 1
