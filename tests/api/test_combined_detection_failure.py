"""A run is stored whatever the combined-pass detection says: when it fails (an engine
error), the upload still answers 201, the chunks keep no spots (NULL) and the register
detects on them when read."""

from __future__ import annotations

import app.services.track.aggregate as aggregate_mod
from api.api_support import sql, upload
from engine.errors import InversionError


def test_a_failing_combined_detection_does_not_fail_the_upload(
    client, settings, synthetic_run, monkeypatch
) -> None:
    def broken(*args, **kwargs):
        raise InversionError("no usable passes")

    monkeypatch.setattr(aggregate_mod, "detect_combined", broken)
    r = upload(client, synthetic_run["csv"], track="T",
               start_chainage_m=str(synthetic_run["start_chainage_m"]))  # fmt: skip
    assert r.status_code == 201, r.text
    assert r.json()["status"] == "done"
    spots = sql(settings, "SELECT spots FROM track_profile_chunks")
    assert spots and all(s in (None, "null") for (s,) in spots)  # JSON null: none kept
    monkeypatch.undo()  # detection works again: the register detects on the stale chunks
    track_id = r.json()["track_id"]
    assert client.get(f"/api/v1/tracks/{track_id}/defects").status_code == 200
