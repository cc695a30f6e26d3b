"""A run's detection limit: the smallest stiffness loss it can see, from its own noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from engine.errors import ParameterError
from engine.pipeline import process_run
from engine.sensor import sensor_for_grade
from engine.setup import RunSetup, prepare_run
from engine.synthetic import make_run, to_runlog
from engine.track import SoftZone, TrackParams
from engine.vehicle import TABLE1
from engine.visibility import DipModel, detection_limit, zone_dip_depths

LOADS = TABLE1.static_axle_loads()
BAND = {
    "load": 0.5 * (LOADS[0] + LOADS[1]), "lambda_min_m": 3.0, "lambda_max_m": 40.0,
    "taper": 0.3, "step_m": 0.25, "baseline_window_m": 40.0,
}  # fmt: skip


def test_limit_is_the_loss_whose_dip_reaches_the_threshold() -> None:
    """The loss reported makes a dip as deep as the threshold; the limit rises with the
    threshold; a threshold no modelled loss reaches gives NaN (not seen at all)."""
    lims = [detection_limit(t, **BAND).min_loss_pct for t in (0.06, 0.15, 0.4, 0.9)]
    for z in range(2):
        col = [x[z] for x in lims]
        assert all(a < b for a, b in zip(col, col[1:], strict=False)), col
    lim = detection_limit(0.15, **BAND)
    for length, loss in zip(lim.zone_length_m, lim.min_loss_pct, strict=True):
        depth = zone_dip_depths(length, np.array([loss / 100]), DipModel(TrackParams(), **BAND))
        assert depth[0] == pytest.approx(0.15, rel=0.03)
    assert math.isnan(detection_limit(50.0, **BAND).min_loss_pct[0])
    d = detection_limit(0.2, zone_lengths_m=(2.0, 4.0, 8.0), **BAND).to_dict()
    assert d["zone_length_m"] == [2.0, 4.0, 8.0] and len(d["min_loss_pct"]) == 3
    assert detection_limit(50.0, **BAND).to_dict()["min_loss_pct"] == [None, None]
    with pytest.raises(ParameterError) as e:
        detection_limit(0.0, **BAND)
    assert e.value.field == "threshold_mm"


def test_a_pass_reports_a_limit_that_falls_as_its_noise_falls() -> None:
    """One simulated pass logged by each grade: the limit falls from consumer to fibre-optic;
    a 3 m zone well above a grade's limit is found, one well below it is not."""
    run = make_run(
        length=320.0, zones=[SoftZone(120.0, 123.0, 0.30), SoftZone(220.0, 223.0, 0.60)],
        jitter=0.03, seed=5,
    )  # fmt: skip
    limits = {}
    for grade in ("consumer-mems", "industrial-mems", "tactical-mems", "fibre-optic"):
        log = to_runlog(run.sim, sensor_for_grade(grade, 1000.0, seed=2), seed=11)
        res = process_run(prepare_run(log, RunSetup(start_chainage_m=run.start_chainage_m)))
        assert res.detection_limit is not None
        limits[grade] = res.detection_limit.min_loss_pct[0]
        found = {
            z.loss: any(s.end_m >= z.start_m and s.start_m <= z.end_m for s in res.soft_spots)
            for z in run.zones
        }
        for loss, hit in found.items():
            if 100 * loss > limits[grade] + 10:
                assert hit, (grade, loss, limits[grade])
            if 100 * loss < limits[grade] - 10:
                assert not hit, (grade, loss, limits[grade])
    values = list(limits.values())
    assert all(a > b for a, b in zip(values, values[1:], strict=False)), limits
