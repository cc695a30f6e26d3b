"""From a prepared run (:mod:`engine.setup`) to the fused loaded profile on chainage, soft
spots and quality indicators."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from .budget import TimeBudget
from .chainage import to_grid
from .detect import Dip, dip_thresholds, find_dips, robust_baseline, robust_sigma
from .geometry_check import is_smooth_rail
from .intervals import merge_intervals
from .methods import METHODS, MethodInput
from .results import ProcessResult, Quality, SoftSpot
from .setup import MIN_SPEED_MPS, Method, PreparedRun, ProcessConfig, RunSetup, prepare_run
from .stiffness import fit_zone
from .track import TrackParams
from .vehicle_plausibility import check_result
from .visibility import detection_limit
from .wheel_force import dynamic_wheel_forces, force_spectrum

__all__ = [
    "METHODS", "MIN_SPEED_MPS", "Method", "PreparedRun", "ProcessConfig", "RunSetup",
    "fuse_axles", "prepare_run", "process_run",
]  # fmt: skip


def _soft_spots(
    grid: NDArray[np.float64],
    residual: NDArray[np.float64],
    dips: list[Dip],
    cfg: ProcessConfig,
    trk: TrackParams,
    load: float,
    wheel_offsets_m: tuple[float, ...] = (0.0,),
) -> list[SoftSpot]:
    """Fit each dip with the beam model (``load`` N on each wheel of a measured point, at
    ``wheel_offsets_m`` from it); dips whose fitted zones overlap become one zone."""
    if not cfg.fit_stiffness:
        return [SoftSpot(d.start_m, d.end_m, d.peak_m, d.depth_mm, float("nan")) for d in dips]
    half = 0.5 * trk.spacing

    def fit(a: float, b: float) -> tuple[float, float, float]:
        f = fit_zone(
            grid, residual, a, b, trk, load, cfg.lambda_min_m, cfg.lambda_max_m,
            wheel_offsets_m=wheel_offsets_m,
        )  # fmt: skip
        return f.start_m - half, f.end_m + half, f.loss

    merged = [(d, *fit(d.start_m, d.end_m)) for d in dips]
    # overlapping fitted zones are refitted as one; a refit may grow into a neighbour, so
    # merge again until every zone stands alone
    while True:
        groups = merge_intervals([m[1] for m in merged], [m[2] for m in merged])
        if all(g.size == 1 for g in groups):
            merged = [merged[g[0]] for g in groups]
            break
        regrouped: list[tuple[Dip, float, float, float]] = []
        for g in groups:
            members = [merged[i] for i in g]
            if len(members) == 1:
                regrouped.append(members[0])
                continue
            deeper = max((m[0] for m in members), key=lambda d: d.depth_mm)
            na, nb, nl = fit(min(m[1] for m in members) + half, max(m[2] for m in members) - half)
            regrouped.append((Dip(na, nb, deeper.peak_m, deeper.depth_mm), na, nb, nl))
        merged = regrouped
    return [
        SoftSpot(
            start_m=float(a),
            end_m=float(b),
            peak_m=d.peak_m,
            depth_mm=d.depth_mm,
            stiffness_loss_pct=float(100.0 * loss),
        )
        for d, a, b, loss in merged
    ]


def _agreement(
    front: NDArray[np.float64],
    rear: NDArray[np.float64],
    both: NDArray[np.bool_],
    cfg: ProcessConfig,
    step: float,
) -> float:
    """RMS difference of the front and rear profiles (mm) where both are away from their
    band-pass ends: each profile is band-passed over its own stretch, and the common stretch
    ends where one of them does, so its first and last ``lambda_max (1 + taper)`` metres hold
    one profile's edge effect (millimetres on rough rail) and say nothing of agreement. A
    common stretch too short for that is taken whole."""
    idx = np.flatnonzero(both)
    if idx.size == 0:
        return float("nan")
    edge = int(np.ceil(cfg.lambda_max_m * (1 + cfg.taper) / step))
    if idx.size > 2 * edge + int(np.ceil(20.0 / step)):
        idx = idx[edge:-edge]
    return float(np.sqrt(np.mean((front[idx] - rear[idx]) ** 2)))


def _no_budget(_stage: str) -> None:
    """The budget check of a computation without a budget."""


def fuse_axles(front: NDArray[np.float64], rear: NDArray[np.float64]) -> NDArray[np.float64]:
    """The fused value of the two axles' (same grid, NaN = axle did not pass): their mean
    where both passed, else the one that did. The fused level is this of the axles' levels
    (mm), the wheel force under it this of their forces (N)."""
    both = np.isfinite(front) & np.isfinite(rear)
    with np.errstate(invalid="ignore"):
        return np.where(both, 0.5 * (front + rear), np.where(np.isfinite(front), front, rear))


def process_run(run: PreparedRun, *, budget: TimeBudget | None = None) -> ProcessResult:
    """Invert a prepared run into a loaded profile along chainage and find its soft spots.

    Parameters
    ----------
    run : PreparedRun
        The log and its set-up, checked (:func:`~engine.setup.prepare_run`).
    budget : TimeBudget, optional
        Wall-time budget, checked between the stages (inversion, wheel forces, detection).

    Returns
    -------
    ProcessResult
        Profile in mm on a regular chainage grid (m), soft spots, quality indicators.

    Raises
    ------
    InversionError
        If an inversion method cannot treat the run;
        :class:`~engine.vehicle_plausibility.ImplausibleResult` if the level or a dip lies
        beyond what any track can show under the vehicle (its parameters are wrong).
    BudgetExceeded
        If ``budget`` is spent before the result is complete.
    """
    spent = budget.check if budget is not None else _no_budget
    log, setup = run.log, run.setup
    cfg, trk, vehicle = setup.config, setup.track, setup.vehicle
    dt = log.dt
    pos, speed, f_lo, f_hi = run.positions, run.speed, run.f_lo_hz, run.f_hi_hz
    step, grid = cfg.grid_step_m, run.grid
    given = MethodInput(
        log=log, positions=pos, grid=grid, step_m=step, vehicle=vehicle, f_lo_hz=f_lo,
        f_hi_hz=f_hi, lambda_min_m=cfg.lambda_min_m, lambda_max_m=cfg.lambda_max_m,
        taper=cfg.taper,
    )  # fmt: skip
    inv = METHODS[cfg.method](given)
    spent(f"the {cfg.method} inversion")
    front, rear = inv.front_mm, inv.rear_mm
    sa, sg = inv.noise_accel_mps2, inv.noise_pitch_rate_radps
    # wheel force per axle: static load + dynamic part from the vehicle equations, on the grid
    static = vehicle.static_axle_loads()
    if inv.band is not None:
        dyn = force_spectrum(inv.band, vehicle).at_times(given.axle_times)
    else:
        assert inv.y_front is not None and inv.y_rear is not None
        f1, f2 = dynamic_wheel_forces(inv.y_front, inv.y_rear, dt, vehicle)
        dyn = np.stack([to_grid(pos.front, f1, grid), to_grid(pos.rear, f2, grid)])
    front_force = static[0] + dyn[0]
    rear_force = static[1] + dyn[1]
    both = np.isfinite(front) & np.isfinite(rear)
    fused = fuse_axles(front, rear)
    spent("the wheel forces")
    baseline = robust_baseline(fused, step, cfg.detection.baseline_window_m)
    residual = fused - baseline
    thresholds = dip_thresholds(step, residual, cfg.detection)
    dips, thr = find_dips(grid, residual, cfg.detection, thresholds=thresholds)
    # the fused profile is the mean of the two measured points: each wheel carries the mean
    # wheel load, at its offset from its point (front and rear alike for every kind)
    load = float(np.mean(vehicle.static_wheel_loads()))
    wheels = vehicle.axle_wheel_offsets_m[0]
    spots = _soft_spots(grid, residual, dips, cfg, trk, load, wheels)
    limit = detection_limit(
        thr, params=trk, load=load, lambda_min_m=cfg.lambda_min_m,
        lambda_max_m=cfg.lambda_max_m, taper=cfg.taper, step_m=step,
        baseline_window_m=cfg.detection.baseline_window_m, wheel_offsets_m=wheels,
        matched=thresholds[1:],
    )  # fmt: skip
    spent("the soft-spot detection")
    # a wrong vehicle turns into dips no track can have: fail rather than report them
    if cfg.check_result:
        check_result(fused, baseline, [s.depth_mm for s in spots], vehicle, trk)
    geometry_check = is_smooth_rail(robust_sigma(residual))
    if not geometry_check.smooth:
        # a dip may be rail geometry: depth only, never a stiffness-loss figure
        spots = [replace(s, stiffness_loss_pct=float("nan")) for s in spots]
    agreement = _agreement(front, rear, both, cfg, step)
    quality = Quality(
        noise_accel_mps2=sa,
        noise_pitch_rate_radps=sg,
        axle_agreement_mm=agreement,
        coverage_m=float(np.isfinite(fused).sum() * step),
        speed_min_mps=float(speed.min()),
        speed_max_mps=float(speed.max()),
        sample_rate_hz=1.0 / dt,
    )
    return ProcessResult(
        chainage_m=grid,
        level_mm=fused,
        front_level_mm=front,
        rear_level_mm=rear,
        baseline_mm=baseline,
        soft_spots=spots,
        quality=quality,
        method=cfg.method,
        extras={"band_hz": (f_lo, f_hi), "residual_sigma_mm": robust_sigma(residual)},
        front_force_n=front_force,
        rear_force_n=rear_force,
        geometry_check=geometry_check,
        detection_limit=limit,
    )
