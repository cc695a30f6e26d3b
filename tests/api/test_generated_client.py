"""A Python client generated from the served OpenAPI document works (issue 16, item 12):
openapi-python-client builds it from ``/openapi.json``; the test creates a track, uploads a
short run as JSON columns, reads the run, its soft spots (the synthetic run's 50 % soft zone
at 70-75 m among them) and the profile's CSV twin through it."""

from __future__ import annotations

import importlib
import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest


def _generate(client, tmp_path: Path) -> None:
    schema = tmp_path / "openapi.json"
    schema.write_text(json.dumps(client.get("/openapi.json").json()))
    exe = Path(sys.executable).parent / "openapi-python-client"
    result = subprocess.run(
        [str(exe), "generate", "--path", str(schema), "--output-path",
         str(tmp_path / "tp_client"), "--meta", "none"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr
    for op in ("create_run", "read_run", "read_run_soft_spots", "read_run_profile_csv"):
        assert (tmp_path / "tp_client" / "api" / "runs" / f"{op}.py").exists(), result.stdout


@pytest.mark.slow
def test_a_generated_client_uploads_and_reads_a_run(client, synthetic_run, tmp_path) -> None:
    _generate(client, tmp_path)
    sys.path.insert(0, str(tmp_path))
    try:
        tp = importlib.import_module("tp_client")
        runs = importlib.import_module("tp_client.api.runs")
        tracks = importlib.import_module("tp_client.api.tracks")
        models = importlib.import_module("tp_client.models")
        for name in ("create_run", "read_run", "read_run_soft_spots", "read_run_profile_csv"):
            importlib.import_module(f"tp_client.api.runs.{name}")
        importlib.import_module("tp_client.api.tracks.create_track")

        api = tp.Client(base_url=str(client.base_url)).set_httpx_client(client)
        track = tracks.create_track.sync(client=api, body=models.TrackCreate(name="Line 1"))
        assert isinstance(track, models.TrackPublic) and track.name == "Line 1"

        a = np.loadtxt(io.BytesIO(synthetic_run["csv"]), delimiter=",", skiprows=1)
        header = synthetic_run["csv"].split(b"\n", 1)[0].decode().strip().split(",")
        cols = {name: a[:, i].tolist() for i, name in enumerate(header)}
        body = models.RunCreateJson(
            track_id=track.id,
            start_chainage_m=synthetic_run["start_chainage_m"],
            columns=models.RunColumns(**cols),
        )
        created = runs.create_run.sync(client=api, body=body, wait=True)
        assert isinstance(created, models.RunCreated), created
        assert created.status == "done" and created.n_samples == synthetic_run["n_samples"]

        run = runs.read_run.sync(client=api, run_id=created.id)
        assert isinstance(run, models.RunPublic) and run.track == "Line 1"
        spots = runs.read_run_soft_spots.sync(client=api, run_id=created.id)
        assert isinstance(spots, list) and spots
        assert any(s.start_m < 75 and s.end_m > 70 for s in spots), spots
        csv = runs.read_run_profile_csv.sync_detailed(client=api, run_id=created.id)
        assert csv.status_code == 200 and csv.content.startswith(b"chainage_m,level_mm")
        missing = runs.read_run.sync(client=api, run_id=created.id + 1)
        assert isinstance(missing, models.ErrorResponse) and "not found" in (missing.detail.message)
    finally:
        sys.path.remove(str(tmp_path))
        for mod in [m for m in sys.modules if m == "tp_client" or m.startswith("tp_client.")]:
            del sys.modules[mod]
