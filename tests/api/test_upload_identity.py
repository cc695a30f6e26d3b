"""What makes an upload a duplicate (issue 16, Low): the content *and* how it is placed.

The probe re-sent a file with a corrected start chainage and got ``200 duplicate``, the
correction dropped; 45 identical concurrent uploads were each inverted before deduplication.
"""

from __future__ import annotations

import threading

from api.api_support import upload
from app.services import submit as submit_module


def test_a_corrected_start_chainage_is_a_new_run(client, synthetic_run) -> None:
    first = upload(client, synthetic_run["csv"], track="L", start_chainage_m=12)
    assert first.status_code == 201
    again = upload(client, synthetic_run["csv"], track="L", start_chainage_m=12)
    assert again.status_code == 200 and again.json()["duplicate"] is True
    assert again.json()["id"] == first.json()["id"]
    for change in ({"start_chainage_m": 14}, {"start_chainage_m": 12, "direction": "decreasing"},
                   {"start_chainage_m": 12, "accel_unit": "m/s2"}):  # fmt: skip
        r = upload(client, synthetic_run["csv"], track="L", **change)
        assert r.status_code == 201, (change, r.text)
        assert r.json()["duplicate"] is False


def test_identical_concurrent_uploads_are_inverted_once(client, synthetic_run,
                                                         monkeypatch) -> None:  # fmt: skip
    """Eight identical uploads at once: one run stored, one inversion; the others answer the
    stored run as a duplicate."""
    calls = []
    real = submit_module.invert

    def counting(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(submit_module, "invert", counting)
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
