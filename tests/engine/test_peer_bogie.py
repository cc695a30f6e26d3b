"""The independent judge: the peer's ROSE runs of a bogie coach (shared/data/peer-bogie).

Skipped when the shared data are absent (set SHARED_DIR). The vehicle is registered from the
truth JSON's whole-vehicle datasheet values; nothing else of the truth enters the processing.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from benchmarks.peer_truth import bogie_from_truth, bogie_mean_truth, butter_band
from engine.logio.parse import read_run_csv
from engine.pipeline import process_run
from engine.results import ProcessResult
from engine.setup import RunSetup, prepare_run
from support.samples import shared_data_dir


def _peer(name: str) -> tuple[Path, dict]:
    d = shared_data_dir()
    csv = None if d is None else d / "peer-bogie" / f"{name}.csv"
    if csv is None or not csv.exists():
        pytest.skip(f"peer run {name} not available (set SHARED_DIR)")
    return csv, json.loads(csv.with_suffix(".truth.json").read_text())


@pytest.fixture(scope="module")
def coach_smooth() -> tuple[ProcessResult, dict, dict]:
    csv, truth = _peer("pub_coach_smooth")
    res = process_run(
        prepare_run(
            read_run_csv(csv),
            RunSetup(
                start_chainage_m=truth["start_chainage_m"],
                direction=truth["direction"],
                vehicle=bogie_from_truth(truth),
            ),
        )
    )
    return res, truth, dict(np.load(csv.with_suffix(".truth.npz")))


def test_peer_coach_profile_is_the_bogie_mean_level(coach_smooth) -> None:
    """The loaded profile equals the peer's bogie-mean level in the 3-25 m band."""
    res, _, npz = coach_smooth
    x = res.chainage_m
    truth = bogie_mean_truth(npz, x) * 1e3
    ok = np.flatnonzero(np.isfinite(truth) & np.isfinite(res.level_mm))
    seg = slice(ok[0] + 100, ok[-1] - 100)  # 25 m dropped at each end
    step = float(x[1] - x[0])
    t, m = butter_band(truth[seg], step, 3.0, 25.0), butter_band(res.level_mm[seg], step, 3.0, 25.0)
    assert np.corrcoef(m, t)[0, 1] > 0.99
    assert np.sqrt(np.mean((m - t) ** 2)) < 0.2 * np.sqrt(np.mean(t**2))


def test_peer_coach_zones_and_losses(coach_smooth) -> None:
    """Every zone is found where it starts (±1.5 m) with the loss of the overall support
    within ±10 points; no false zone. (The ends: method.md §10.)"""
    res, truth, _ = coach_smooth
    zones = truth["zones"]
    assert len(res.soft_spots) == len(zones)
    for spot, z in zip(res.soft_spots, zones, strict=True):
        assert abs(spot.start_m - z["start_m"]) <= 1.5
        assert spot.start_m <= z["end_m"] and spot.end_m >= z["start_m"]
        assert abs(spot.stiffness_loss_pct - 100 * z["stiffness_loss"]) <= 10.0
