"""From a run log to the fused loaded profile on chainage, soft spots and quality indicators."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .budget import TimeBudget
from .chainage import GRID_STEP_M, AxlePositions, axle_positions, to_grid
from .detect import DetectionConfig, Dip, find_dips, robust_baseline, robust_sigma
from .errors import InversionError, ParameterError
from .geometry_check import is_smooth_rail
from .intervals import merge_intervals
from .methods import METHODS, MethodInput
from .plausibility import check_plausible
from .results import ProcessResult, Quality, SoftSpot
from .runlog import RunLog
from .stiffness import fit_zone
from .track import TrackParams
from .vehicle import TABLE1, VehicleModel
from .vehicle_plausibility import check_result
from .visibility import detection_limit
from .wheel_force import dynamic_wheel_forces, force_spectrum

Method = Literal["wiener", "spectral", "filtered-direct", "least-squares", "direct"]

MIN_SPEED_MPS = 1.0
"""Slowest speed the inversion accepts, m/s (below it wavelengths map to sub-Hz frequencies)."""


@dataclass(frozen=True)
class ProcessConfig:
    """Settings of the processing pipeline.

    Parameters
    ----------
    method : {"wiener", "spectral", "filtered-direct", "least-squares", "direct"}
        ``wiener`` (default): the band-limited frequency-domain inversion with the log's own
        signal-to-noise ratio per bin as prior and both axles tied to one track (as good as
        ``spectral`` on exact logs, better on noisy MEMS logs; docs/accuracy.md).
        ``spectral``: the same inversion with a flat noise-matched prior per bin.
        ``filtered-direct``: band-passed inputs, then the direct integration with
        numerically dissipative Newmark parameters. ``least-squares``: the optimisation
        baseline (profile fitted so the simulated vehicle matches the log, window by
        window; slow). ``direct``: the paper's direct integration, then the same band-pass
        (the reference for exactness; wrong on noisy data).
    lambda_min_m, lambda_max_m : float
        Wavelength band of the profile, m. Default 3-40 m: all of EN 13848 D1 (3-25 m) and
        enough of D2 that a soft zone up to ~15 m long keeps its depth (a 25 m cut-off
        carves the middle out of a 10 m zone); see docs/method.md.
    grid_step_m : float
        Spacing of the chainage grid, m.
    taper : float
        Relative width of the band edges (raised cosine).
    detection : DetectionConfig
        Soft-spot thresholds.
    fit_stiffness : bool
        Fit each zone's extent and stiffness loss with the static beam model.
    check_result : bool
        Refuse a result beyond what a track can show
        (:func:`~engine.vehicle_plausibility.check_result`). Off only to score methods
        that are known to drift (benchmarks comparing candidates).
    """

    method: Method = "wiener"
    lambda_min_m: float = 3.0
    lambda_max_m: float = 40.0
    grid_step_m: float = GRID_STEP_M
    taper: float = 0.3
    detection: DetectionConfig = field(default_factory=DetectionConfig)
    fit_stiffness: bool = True
    check_result: bool = True

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ParameterError(
                f"method must be one of {tuple(METHODS)}, got {self.method!r}", field="method"
            )
        if not (0 < self.lambda_min_m < self.lambda_max_m):
            raise ParameterError(
                "wavelength band must satisfy 0 < lambda_min_m < lambda_max_m, got "
                f"{self.lambda_min_m} m, {self.lambda_max_m} m"
            )
        if not (0 < self.grid_step_m <= GRID_STEP_M):
            raise ParameterError(
                f"grid_step_m must be in (0, {GRID_STEP_M}] m, got {self.grid_step_m}"
            )
        if not (0 < self.taper <= 1):
            raise ParameterError(f"taper must be in (0, 1], got {self.taper}")


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


@dataclass(frozen=True)
class RunCheck:
    """What :func:`check_run` found: the run can be inverted with these values.

    Attributes
    ----------
    positions : AxlePositions
        Chainage of body and axles at each sample, m.
    speed : ndarray
        Speed at each sample, m/s.
    f_lo_hz, f_hi_hz : float
        Time-frequency band the inversion will use, Hz.
    travelled_m : float
        Distance covered by the run, m.
    log : RunLog
        The log checked (this object).
    inputs : tuple
        ``(start_chainage_m, direction, vehicle, config)`` it was checked with.
    """

    positions: AxlePositions
    speed: NDArray[np.float64]
    f_lo_hz: float
    f_hi_hz: float
    travelled_m: float
    log: RunLog = field(repr=False, compare=False)
    inputs: tuple[object, ...] = field(repr=False, compare=False)

    def is_for(
        self,
        log: RunLog,
        start_chainage_m: float | None,
        direction: str,
        vehicle: VehicleModel,
        config: ProcessConfig,
    ) -> bool:
        """Whether this check stands for ``log`` (the same object) with these parameters."""
        return log is self.log and self.inputs == (start_chainage_m, direction, vehicle, config)


def _no_budget(_stage: str) -> None:
    """The budget check of a computation without a budget."""


def check_run(
    log: RunLog,
    *,
    start_chainage_m: float | None = None,
    direction: str = "increasing",
    vehicle: VehicleModel = TABLE1,
    config: ProcessConfig | None = None,
) -> RunCheck:
    """Check up front that a log can be inverted, without inverting it (cheap, O(n)).

    Same parameters as :func:`process_run`. Raises :class:`InversionError` naming the
    problem: a speed below ``MIN_SPEED_MPS``, a run shorter than twice the longest
    wavelength, a sample rate too low for the shortest wavelength at the top speed, a
    missing start chainage, a chainage column that does not move steadily.
    """
    check_plausible(log)
    cfg = config or ProcessConfig()
    dt = log.dt
    pos = axle_positions(log, vehicle, start_chainage_m, direction)
    speed = log.speed_mps if log.speed_mps is not None else np.abs(np.gradient(pos.body)) / dt
    v_min, v_max = float(np.percentile(speed, 1)), float(np.percentile(speed, 99))
    if v_min < MIN_SPEED_MPS:
        raise InversionError(
            f"speed drops to {v_min:.2f} m/s; the inversion needs >= {MIN_SPEED_MPS} m/s "
            "throughout (split the log at stops)"
        )
    travelled = abs(pos.body[-1] - pos.body[0])
    if travelled < 2 * cfg.lambda_max_m:
        raise InversionError(
            f"the run covers {travelled:.1f} m; at least {2 * cfg.lambda_max_m:.0f} m "
            f"(twice the longest wavelength, {cfg.lambda_max_m} m) are needed"
        )
    tp = 1.0 + cfg.taper
    f_lo = v_min / (cfg.lambda_max_m * tp)
    f_hi = v_max * tp / cfg.lambda_min_m
    if f_hi * tp >= 0.5 / dt:
        raise InversionError(
            f"a {1 / dt:.0f} Hz log cannot resolve {cfg.lambda_min_m} m wavelengths at "
            f"{v_max:.1f} m/s (needs > {2 * f_hi * tp:.0f} Hz)"
        )
    return RunCheck(
        pos, speed, f_lo, f_hi, float(travelled), log, (start_chainage_m, direction, vehicle, cfg)
    )


def process_run(
    log: RunLog,
    *,
    start_chainage_m: float | None = None,
    direction: str = "increasing",
    vehicle: VehicleModel = TABLE1,
    track: TrackParams | None = None,
    config: ProcessConfig | None = None,
    budget: TimeBudget | None = None,
    checked: RunCheck | None = None,
) -> ProcessResult:
    """Invert a run log into a loaded profile along chainage and find its soft spots.

    Parameters
    ----------
    log : RunLog
        The run, canonical SI units.
    start_chainage_m : float, optional
        Chainage of the body centre at the first sample, m (needed without a chainage column).
    direction : {"increasing", "decreasing"}
        Direction of travel.
    vehicle : VehicleModel
        Parameters of the logging vehicle.
    track : TrackParams, optional
        Nominal track properties (for stiffness-loss estimates); default UIC60 on 80 kN/mm.
    config : ProcessConfig, optional
        Method, band, grid and thresholds.
    budget : TimeBudget, optional
        Wall-time budget, checked between the stages (checks, inversion, wheel forces,
        detection).
    checked : RunCheck, optional
        What :func:`check_run` found for this log and these parameters (a service's
        pre-flight): not checked again. Ignored (the log is checked) unless it
        :meth:`~RunCheck.is_for` this very log, start chainage, direction, vehicle and config.

    Returns
    -------
    ProcessResult
        Profile in mm on a regular chainage grid (m), soft spots, quality indicators.

    Raises
    ------
    InversionError
        If the log is too short for the band, too slow, or its sampling too coarse;
        :class:`~engine.vehicle_plausibility.ImplausibleResult` if the level or a dip lies
        beyond what any track can show under the vehicle (its parameters are wrong).
    BudgetExceeded
        If ``budget`` is spent before the result is complete.
    """
    spent = budget.check if budget is not None else _no_budget
    cfg = config or ProcessConfig()
    trk = track or TrackParams()
    dt = log.dt
    if checked is not None and checked.is_for(log, start_chainage_m, direction, vehicle, cfg):
        chk = checked
    else:
        chk = check_run(
            log, start_chainage_m=start_chainage_m, direction=direction, vehicle=vehicle,
            config=cfg,
        )  # fmt: skip
    pos, speed, f_lo, f_hi = chk.positions, chk.speed, chk.f_lo_hz, chk.f_hi_hz
    spent("the checks of the log")

    step = cfg.grid_step_m
    lo = min(pos.front.min(), pos.rear.min())
    hi = max(pos.front.max(), pos.rear.max())
    grid = np.arange(np.ceil(lo / step) * step, hi + 1e-9, step)
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
    with np.errstate(invalid="ignore"):
        fused = np.where(both, 0.5 * (front + rear), np.where(np.isfinite(front), front, rear))
    spent("the wheel forces")
    baseline = robust_baseline(fused, step, cfg.detection.baseline_window_m)
    residual = fused - baseline
    dips, thr = find_dips(grid, residual, cfg.detection)
    # the fused profile is the mean of the two measured points: each wheel carries the mean
    # wheel load, at its offset from its point (front and rear alike for every kind)
    load = float(np.mean(vehicle.static_wheel_loads()))
    spots = _soft_spots(grid, residual, dips, cfg, trk, load, vehicle.axle_wheel_offsets_m[0])
    limit = detection_limit(
        thr, params=trk, load=load, lambda_min_m=cfg.lambda_min_m,
        lambda_max_m=cfg.lambda_max_m, taper=cfg.taper, step_m=step,
        baseline_window_m=cfg.detection.baseline_window_m,
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
