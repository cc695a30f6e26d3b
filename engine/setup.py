"""A run's set-up and the one way into processing: :func:`prepare_run`.

What a run's processing needs besides its log is one value, :class:`RunSetup` (start chainage,
direction, vehicle, track, processing settings). :func:`prepare_run` checks a log against its
set-up once (plausibility of the log, speed, distance, sampling against the wavelength band)
and gives a :class:`PreparedRun`: the only input of :func:`engine.pipeline.process_run`. A
prepared run is the proof that the checks passed, so nothing downstream asks again.

Units: SI throughout (m, s, m/s, Hz).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .chainage import GRID_STEP_M, PRODUCT_BAND_M, AxlePositions, axle_grid, axle_positions
from .detect import DetectionConfig
from .errors import InversionError, ParameterError
from .methods import METHODS
from .plausibility import check_plausible
from .runlog import RunLog
from .track import TrackParams
from .vehicle import TABLE1, VehicleModel

Method = Literal["wiener", "spectral", "filtered-direct", "least-squares", "direct"]

DIRECTIONS = ("increasing", "decreasing")
"""Directions of travel, along increasing or decreasing chainage."""

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
    lambda_min_m: float = PRODUCT_BAND_M[0]
    lambda_max_m: float = PRODUCT_BAND_M[1]
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


@dataclass(frozen=True)
class RunSetup:
    """Everything a run's processing needs besides its log.

    Parameters
    ----------
    start_chainage_m : float, optional
        Chainage of the body centre at the first sample, m (needed without a chainage column;
        with one, the column is shifted to start there).
    direction : {"increasing", "decreasing"}
        Direction of travel.
    vehicle : VehicleModel
        Parameters of the logging vehicle (as loaded on this run).
    track : TrackParams
        Nominal track properties (for stiffness-loss estimates); default UIC60 on 80 kN/mm.
    config : ProcessConfig
        Method, band, grid and thresholds.
    """

    start_chainage_m: float | None = None
    direction: str = "increasing"
    vehicle: VehicleModel = TABLE1
    track: TrackParams = field(default_factory=TrackParams)
    config: ProcessConfig = field(default_factory=ProcessConfig)

    def __post_init__(self) -> None:
        if self.direction not in DIRECTIONS:
            raise ParameterError(
                f"direction must be one of {DIRECTIONS}, got {self.direction!r}",
                field="direction",
            )
        if self.start_chainage_m is not None and not np.isfinite(self.start_chainage_m):
            raise ParameterError(
                f"start_chainage_m must be a finite chainage in m, got {self.start_chainage_m}",
                field="start_chainage_m",
            )


@dataclass(frozen=True)
class PreparedRun:
    """A log checked against its set-up, ready to invert: made by :func:`prepare_run` only.

    Attributes
    ----------
    log : RunLog
        The log, canonical SI units; it passed :func:`~engine.plausibility.check_plausible`.
    setup : RunSetup
        What it is processed with.
    positions : AxlePositions
        Chainage of body and axles at each sample, m.
    speed : ndarray
        Speed at each sample, m/s.
    f_lo_hz, f_hi_hz : float
        Time-frequency band the inversion uses, Hz.
    travelled_m : float
        Distance covered by the run, m.
    grid : ndarray
        The chainage grid of the run's profile, m (:func:`~engine.chainage.axle_grid`).
    """

    log: RunLog = field(repr=False)
    setup: RunSetup
    positions: AxlePositions = field(repr=False)
    speed: NDArray[np.float64] = field(repr=False)
    f_lo_hz: float
    f_hi_hz: float
    travelled_m: float
    grid: NDArray[np.float64] = field(repr=False)

    def with_setup(self, setup: RunSetup) -> PreparedRun:
        """This run prepared with ``setup`` instead (itself when it is the same set-up); the
        log's plausibility is not checked again (it does not depend on the set-up)."""
        return self if setup == self.setup else prepare_run(self.log, setup, log_checked=True)

    def with_config(self, config: ProcessConfig) -> PreparedRun:
        """This run with another processing configuration (band, grid, method), itself when
        it is the same: the positions and speeds depend on the log and the vehicle only, so
        only the band's frequencies and the grid are derived again (no second preparation).

        Raises
        ------
        InversionError
            The run is too short or too coarsely sampled for ``config``'s band
            (:func:`prepare_run`).
        """
        if config == self.setup.config:
            return self
        f_lo, f_hi, grid = _band_and_grid(
            self.log, self.positions, self.speed, self.travelled_m, config
        )
        return PreparedRun(
            self.log, replace(self.setup, config=config), self.positions, self.speed,
            f_lo, f_hi, self.travelled_m, grid,
        )  # fmt: skip


def prepare_run(log: RunLog, setup: RunSetup, *, log_checked: bool = False) -> PreparedRun:
    """Check up front that a log can be processed with its set-up, without inverting it.

    Cheap (O(n)); the only way to a :class:`PreparedRun`, hence into processing.

    Parameters
    ----------
    log : RunLog
        The run, canonical SI units.
    setup : RunSetup
        What it is processed with.
    log_checked : bool
        The log's reader made every check of :func:`~engine.plausibility.check_plausible`
        itself, with its own column names and lines (:func:`engine.logio.read_run_csv`):
        they are not repeated. False for every other log.

    Raises
    ------
    LogFormatError
        The log is implausible (:func:`~engine.plausibility.check_plausible`).
    InversionError
        Naming the problem: a speed below :data:`MIN_SPEED_MPS`, a run shorter than twice the
        longest wavelength, a sample rate too low for the shortest wavelength at the top
        speed, a missing start chainage, a chainage column that does not move steadily.
    """
    if not log_checked:
        check_plausible(log)
    pos = axle_positions(log, setup.vehicle, setup.start_chainage_m, setup.direction)
    speed = log.speed_mps if log.speed_mps is not None else np.abs(np.gradient(pos.body)) / log.dt
    v_min = float(np.percentile(speed, 1))
    if v_min < MIN_SPEED_MPS:
        raise InversionError(
            f"speed drops to {v_min:.2f} m/s; the inversion needs >= {MIN_SPEED_MPS} m/s "
            "throughout (split the log at stops)"
        )
    travelled = float(abs(pos.body[-1] - pos.body[0]))
    f_lo, f_hi, grid = _band_and_grid(log, pos, speed, travelled, setup.config)
    return PreparedRun(log, setup, pos, speed, f_lo, f_hi, travelled, grid)


def _band_and_grid(
    log: RunLog,
    pos: AxlePositions,
    speed: NDArray[np.float64],
    travelled: float,
    cfg: ProcessConfig,
) -> tuple[float, float, NDArray[np.float64]]:
    """The inversion's time-frequency band (Hz) and the profile's chainage grid (m) of a run
    covering ``travelled`` m at ``speed`` (m/s), for ``cfg``; raises :class:`InversionError`
    when the run is too short or too coarsely sampled for the band."""
    v_min, v_max = float(np.percentile(speed, 1)), float(np.percentile(speed, 99))
    if travelled < 2 * cfg.lambda_max_m:
        raise InversionError(
            f"the run covers {travelled:.1f} m; at least {2 * cfg.lambda_max_m:.0f} m "
            f"(twice the longest wavelength, {cfg.lambda_max_m} m) are needed"
        )
    tp = 1.0 + cfg.taper
    f_lo = v_min / (cfg.lambda_max_m * tp)
    f_hi = v_max * tp / cfg.lambda_min_m
    if f_hi * tp >= 0.5 / log.dt:
        raise InversionError(
            f"a {1 / log.dt:.0f} Hz log cannot resolve {cfg.lambda_min_m} m wavelengths at "
            f"{v_max:.1f} m/s (needs > {2 * f_hi * tp:.0f} Hz)"
        )
    grid = axle_grid(pos.front, pos.rear, cfg.grid_step_m)
    return f_lo, f_hi, grid
