"""The example log shipped in examples/ (README "Try it") reads as a raw logger file and gives
its truth: the two soft zones, and the recording time from its own timestamps."""

from __future__ import annotations

import json
from datetime import datetime
from typing import Any

from starlette.testclient import TestClient

from api.api_support import assert_zones_match, upload, wait_done
from support.samples import REPO

EXAMPLE = REPO / "examples" / "example_run.csv.gz"


def test_example_log_finds_its_true_zones(client: TestClient) -> None:
    truth: dict[str, Any] = json.loads(EXAMPLE.with_name("example_run.truth.json").read_text())
    assert EXAMPLE.stat().st_size < 1_000_000
    r = upload(client, EXAMPLE.read_bytes(), "example_run.csv.gz", track="Example line",
               start_chainage_m=truth["start_chainage_m"])  # fmt: skip
    assert r.status_code in (201, 202), r.text
    run = wait_done(client, r.json()["id"])
    assert run["status"] == "done", run
    assert datetime.fromisoformat(run["recorded_at"]) == datetime.fromisoformat(
        truth["recorded_at"]
    )
    spots = client.get(f"/api/v1/runs/{run['id']}/soft-spots").json()
    assert_zones_match(spots, truth["zones"])
