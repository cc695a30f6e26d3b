"""The ring at a pass's ends (engine.end_rings): shapes per vehicle and speed, fitted across
passes, and the separation that uses them (docs/accuracy.md "The ends' ring as a few shapes")."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from benchmarks.peer_truth import FOUND_TOL_M, FOUND_TOL_PP, bogie_from_truth, zones_as_built
from engine.bogie import FREIGHT_WAGON, PASSENGER_COACH
from engine.end_rings import (
    EndRingConfig,
    EndRingShapes,
    end_ring_shapes,
    fit_end_rings,
    run_speed_mps,
)
from engine.errors import ParameterError
from engine.logio.parse import read_run_csv
from engine.passes import Pass, align_passes, pass_from_result
from engine.pipeline import process_run
from engine.separation import separate
from engine.setup import RunSetup, prepare_run
from support.samples import shared_data_dir

STEP = 0.25


@pytest.fixture(scope="module")
def shapes() -> tuple[EndRingShapes, EndRingShapes]:
    return end_ring_shapes(PASSENGER_COACH, 27.0), end_ring_shapes(FREIGHT_WAGON, 18.0)


def _rail(x: np.ndarray, seed: int) -> np.ndarray:
    """A rough rail in 3-40 m, about 1 mm RMS."""
    rng = np.random.default_rng(seed)
    lam = rng.uniform(3.0, 40.0, 60)
    amp = 0.25 * (lam / 40.0) ** 1.5 * rng.uniform(0.5, 1.5, lam.size)
    ph = rng.uniform(0, 2 * np.pi, lam.size)
    return np.sum(amp[:, None] * np.sin(2 * np.pi * x[None, :] / lam[:, None] + ph[:, None]), 0)


def _ring(s: EndRingShapes, n: int, first: int, last: int, rng: np.random.Generator) -> np.ndarray:
    """A ring made of ``s``'s shapes at both ends, each weight drawn with its RMS over the cuts
    that made it (as a pass's own ring would be)."""
    k, m = s.start.shape
    out = np.zeros(n)
    out[first : first + m] += rng.normal(0, s.start_rms) @ s.start
    out[last - m + 1 : last + 1] += rng.normal(0, s.end_rms) @ s.end
    return out


@pytest.mark.slow
def test_shapes_are_made_per_speed_bin_and_checked(shapes) -> None:
    coach, _ = shapes
    assert coach.start.shape == coach.end.shape == (6, round(120.0 / STEP))
    assert coach.step_m == pytest.approx(STEP)
    # tapered to zero at their far end: a shape must not leave a step in the level
    assert np.all(coach.start[:, -1] == 0) and np.all(coach.end[:, 0] == 0)
    assert np.linalg.matrix_rank(coach.start) == 6
    # the weights' RMS over the cuts, largest first: the fit's prior
    assert coach.start_rms.shape == (6,) and np.all(np.diff(coach.start_rms) <= 0)
    assert 0 < coach.start_rms[-1] < coach.start_rms[0]
    # speeds round to 2 m/s bins: 27.0 and 27.9 m/s share the 28 m/s shapes, 26.9 does not
    assert end_ring_shapes(PASSENGER_COACH, 27.9) is coach
    assert end_ring_shapes(PASSENGER_COACH, 26.9) is not coach
    with pytest.raises(ValueError, match="speed_mps"):
        end_ring_shapes(PASSENGER_COACH, 0.0)
    with pytest.raises(ParameterError, match="fade_m"):
        EndRingConfig(fade_m=200.0)


def test_fit_takes_both_passes_rings_off_and_keeps_a_zone_dip(shapes) -> None:
    coach_s, wagon_s = shapes
    x = np.arange(0.0, 400.0, STEP)
    rail = _rail(x, 3)
    rng = np.random.default_rng(7)
    # the wagon starts 6 m later and stops 6 m earlier: each ring sits at its own pass's ends
    a = np.where((x >= 0.0), rail, np.nan)
    b = np.where((x >= 6.0) & (x < 394.0), rail, np.nan)
    ia, ib = np.flatnonzero(np.isfinite(a)), np.flatnonzero(np.isfinite(b))
    dip = -0.5 * np.exp(-0.5 * ((x - 66.0) / 1.5) ** 2)  # the heavier wagon sinks at a zone
    a_meas = a + _ring(coach_s, x.size, ia[0], ia[-1], rng)
    b_meas = b + dip + _ring(wagon_s, x.size, ib[0], ib[-1], rng)
    passes = [
        Pass(x, a_meas, 40e3, end_rings=coach_s),
        Pass(x, b_meas, 100e3, end_rings=wagon_s),
    ]
    fitted = fit_end_rings(passes)
    both = np.isfinite(a) & np.isfinite(b)
    truth = (a - b - dip)[both]
    before = (a_meas - b_meas)[both] - truth
    after = (fitted[0].level_mm - fitted[1].level_mm)[both] - truth
    # what is left is the dip, mostly; the rings are gone (to a tenth)
    near = np.abs(x[both] - 66.0) < 6.0
    away = ~near
    assert np.sqrt(np.mean(after[away] ** 2)) < 0.1 * np.sqrt(np.mean(before[away] ** 2))
    kept = -np.min((fitted[1].level_mm - fitted[0].level_mm)[both][near] - (b - a)[both][near])
    assert kept > 0.8 * 0.5
    # passes without shapes come back as they are
    bare = [replace(p, end_rings=None) for p in passes]
    assert all(q is p for q, p in zip(fit_end_rings(bare), bare, strict=True))


def test_a_pass_without_shapes_takes_part_as_it_is(shapes) -> None:
    coach_s, _ = shapes
    x = np.arange(0.0, 300.0, STEP)
    rail = _rail(x, 11)
    ring = _ring(coach_s, x.size, 0, x.size - 1, np.random.default_rng(2))
    survey = Pass(x, rail.copy(), 50e3, kind="survey")
    run = Pass(x, rail + ring, 60e3, end_rings=coach_s)
    out_survey, out_run = fit_end_rings([survey, run])
    assert out_survey is survey
    assert np.sqrt(np.mean((out_run.level_mm - rail) ** 2)) < 0.05 * np.sqrt(np.mean(ring**2))


@pytest.mark.slow
def test_public_rough_pair_gives_every_zone_with_the_rings_fitted() -> None:
    """The coach and the freight wagon of the peer (ROSE) over rough rail: every zone as built
    within 1.5 m and 10 pp, no false zone, with the rings fitted; without them the first zone
    (56 m into the covered stretch) is not reported."""
    d = shared_data_dir()
    names = ("pub_coach_irr", "pub_freight_irr")
    if d is None or not all((d / "peer-bogie" / f"{n}.csv").exists() for n in names):
        pytest.skip("peer runs not available (set SHARED_DIR)")
    passes, truths = [], []
    for n in names:
        csv = d / "peer-bogie" / f"{n}.csv"
        truth = json.loads(csv.with_suffix(".truth.json").read_text())
        vehicle = bogie_from_truth(truth)
        setup = RunSetup(truth["start_chainage_m"], truth["direction"], vehicle)
        res = process_run(prepare_run(read_run_csv(csv), setup))
        passes.append(
            pass_from_result(
                res,
                label=n,
                wheel_offsets_m=vehicle.axle_wheel_offsets_m[0],
                end_rings=end_ring_shapes(vehicle, run_speed_mps(res)),
            )
        )
        truths.append(truth)
    passes, _ = align_passes(passes)
    npz = dict(np.load(d / "peer-bogie" / f"{names[0]}.truth.npz"))
    zones = zones_as_built(truths[0], npz)

    def reported(sep):  # type: ignore[no-untyped-def]
        found, false = 0, 0
        for s in sep.soft_spots:
            hit = [z for z in zones if s.start_m <= z["end_m"] and s.end_m >= z["start_m"]]
            if not hit:
                false += 1
                continue
            z = hit[0]
            found += (
                abs(s.start_m - z["start_m"]) <= FOUND_TOL_M
                and abs(s.end_m - z["end_m"]) <= FOUND_TOL_M
                and abs(s.loss_pct - 100 * z["stiffness_loss"]) <= FOUND_TOL_PP
            )
        return found, false, sep

    found, false, with_rings = reported(separate(passes))
    assert (found, false) == (len(zones), 0), [
        (s.start_m, s.end_m, s.loss_pct) for s in with_rings.soft_spots
    ]
    _, _, without = reported(separate([replace(p, end_rings=None) for p in passes]))
    first = zones[0]
    assert not any(
        s.start_m <= first["end_m"] and s.end_m >= first["start_m"] for s in without.soft_spots
    )
    cov = with_rings.n_passes > 0
    assert with_rings.separable[cov].mean() > without.separable[without.n_passes > 0].mean()
