"""Synthetic runs with known truth: for tests, accuracy studies and the simulate page."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .chainage import to_grid
from .detect import robust_baseline
from .irregularity import Profile, Spectrum, profile_from_samples, random_profile
from .pipeline import fuse_axles
from .results import ProcessResult
from .runlog import RunLog
from .sensor import SensorModel, apply_sensor
from .simulate import END_MARGIN_M, SimulationResult, room_to_run, simulate
from .track import SoftZone, Track, TrackParams
from .vehicle import TABLE1, VehicleModel

REALISTIC_SENSOR = SensorModel(
    accel_noise=0.005, gyro_noise=1e-4, accel_bias=0.02, gyro_bias=2e-4, digits=8
)
"""The sensor of the accuracy requirements: noise 0.005 m/s² and 1e-4 rad/s, biases 0.02 m/s²
and 2e-4 rad/s, 8 significant digits."""


@dataclass(frozen=True)
class SyntheticRun:
    """A simulated run: the log a sensor wrote and the truth behind it.

    Attributes
    ----------
    log : RunLog
        What the logger wrote.
    sim : SimulationResult
        The clean simulation (true levels under each axle, m).
    track : Track
        The simulated track (support stiffness per support).
    zones : tuple of SoftZone
        The soft zones put in.
    start_chainage_m : float
        True body-centre chainage at the first sample, m.
    direction : str
        Direction of travel.
    logged_start_chainage_m : float
        The start chainage a user would type (true one plus the odometer error), m.
    vehicle : VehicleModel
        The simulated vehicle.
    irregularity : Profile or None
        The unloaded rail geometry of the track (m), if any.
    """

    log: RunLog
    sim: SimulationResult
    track: Track
    zones: tuple[SoftZone, ...]
    start_chainage_m: float
    direction: str
    logged_start_chainage_m: float = float("nan")
    vehicle: VehicleModel = TABLE1
    irregularity: Profile | None = None

    def true_geometry(self, grid: NDArray[np.float64]) -> NDArray[np.float64]:
        """True unloaded rail level on ``grid`` (m), mm (zero without irregularity)."""
        return self.track.rail_irregularity(grid) * 1e3

    def true_profile(self, grid: NDArray[np.float64]) -> NDArray[np.float64]:
        """True loaded level fused like the engine's (mean of both axles), mm, on ``grid`` (m)."""
        return fuse_axles(
            to_grid(self.sim.x_front, self.sim.y_front * 1e3, grid),
            to_grid(self.sim.x_rear, self.sim.y_rear * 1e3, grid),
        )


IrregularityInput = str | Spectrum | Profile | tuple[NDArray[np.float64], NDArray[np.float64]]
"""A spectrum (name or :class:`Spectrum`), a given :class:`Profile`, or ``(x m, level m)``."""


def make_track(
    length: float = 500.0,
    *,
    zones: tuple[SoftZone, ...] | list[SoftZone] = (),
    jitter: float = 0.0,
    irregularity: IrregularityInput | None = None,
    irregularity_scale: float = 1.0,
    params: TrackParams | None = None,
    seed: int = 0,
) -> tuple[Track, Profile | None]:
    """A track with soft zones, support scatter and unloaded rail geometry.

    Parameters
    ----------
    length : float
        Track length, m.
    zones : sequence of SoftZone
        Soft zones.
    jitter : float
        Support-to-support stiffness scatter, standard deviation as a fraction (clipped to
        +-50 %).
    irregularity : str, Spectrum, Profile or (x, level) arrays, optional
        Unloaded rail level: a spectrum name of :data:`engine.irregularity.SPECTRA` (random
        profile of 1-120 m wavelengths), or a given profile (m, positive up).
    irregularity_scale : float
        Amplitude multiplier of a spectrum's random profile.
    params : TrackParams, optional
        Rail and nominal support properties.
    seed : int
        Seed of the stiffness scatter and of the random profile.

    Returns
    -------
    track, profile
        The track and its unloaded geometry (None without irregularity).
    """
    p = params or TrackParams()
    rng = np.random.default_rng(seed)
    track = Track(length, params=p, zones=tuple(zones))
    k = track.k
    if jitter > 0:
        k = track.k * np.clip(1.0 + jitter * rng.standard_normal(track.n_supports), 0.5, 1.5)
    prof: Profile | None
    if irregularity is None:
        prof = None
    elif isinstance(irregularity, Profile):
        prof = irregularity
    elif isinstance(irregularity, tuple):
        prof = profile_from_samples(*irregularity)
    else:
        prof = random_profile(irregularity, length, seed=seed + 7919, scale=irregularity_scale)
    track = Track(
        length, params=p, support_stiffness=k, zones=tuple(zones),
        irregularity=None if prof is None else prof.as_irregularity(),
    )  # fmt: skip
    return track, prof


def to_runlog(
    sim: SimulationResult,
    sensor: SensorModel | None = None,
    seed: int | None = None,
    *,
    chainage: bool = False,
) -> RunLog:
    """The log an IMU on the simulated vehicle would write (canonical SI units).

    Parameters
    ----------
    sim : SimulationResult
        A clean forward simulation.
    sensor : SensorModel, optional
        Noise, bias, sample rate and rounding; default an ideal sensor at the simulation rate.
    seed : int, optional
        Seed of the noise generator.
    chainage : bool
        Also log the body-centre chainage (odometer column), m.
    """
    return apply_sensor(
        sim.t, sim.accel, sim.pitch_rate, sim.speed, sensor or SensorModel(), seed=seed,
        chainage_m=sim.x_body if chainage else None,
    )  # fmt: skip


def make_run(
    *,
    length: float = 500.0,
    zones: tuple[SoftZone, ...] | list[SoftZone] = (),
    speed: float | tuple[float, float] = 22.0,
    start_chainage_m: float = 24.13,
    direction: str = "increasing",
    jitter: float = 0.0,
    sensor: SensorModel | None = None,
    sim_rate_hz: float = 1000.0,
    seed: int = 0,
    vehicle: VehicleModel = TABLE1,
    params: TrackParams | None = None,
    end_margin_m: float = END_MARGIN_M,
    track_seed: int | None = None,
    irregularity: IrregularityInput | None = None,
    track: tuple[Track, Profile | None] | None = None,
    start_error_m: float = 0.0,
) -> SyntheticRun:
    """Simulate a run over a track with soft zones and write it through a sensor.

    Parameters
    ----------
    length, zones : float, sequence of SoftZone
        Track length (m) and its soft zones, as for :func:`make_track`.
    speed : float or (float, float)
        Constant speed, or start and end speed of a linear ramp, m/s.
    start_chainage_m : float
        Body-centre chainage at the first sample, m.
    direction : {"increasing", "decreasing"}
        Direction of travel.
    jitter : float
        Support-to-support stiffness scatter, standard deviation as a fraction.
    sensor : SensorModel, optional
        Sensor imperfections and output rate (default: ideal, at the simulation rate).
    sim_rate_hz : float
        Simulation rate, Hz (e.g. 4000 with a 1000 Hz sensor: data that is not an exact
        Newmark 1 kHz output).
    seed : int
        Seed of the stiffness scatter and the sensor noise.
    vehicle, params : VehicleModel, TrackParams
        Vehicle and track.
    end_margin_m : float
        Distance kept between the leading axle and the end of the track, m.
    track_seed : int, optional
        Seed of the stiffness scatter alone (default ``seed``): the same physical track for
        runs with different sensor noise.
    irregularity : str, Spectrum, Profile or (x, level) arrays, optional
        Unloaded rail geometry (see :func:`make_track`); seeded by ``track_seed``/``seed``.
    track : (Track, Profile or None), optional
        A track made by :func:`make_track` (fleet studies: many runs over one track); then
        ``length``, ``zones``, ``jitter``, ``params`` and ``irregularity`` are taken from it.
    start_error_m : float
        Error of the logged start chainage, m: ``logged_start_chainage_m`` is the true start
        plus this (what a user would type; alignment has to correct it).
    """
    if track is None:
        track = make_track(
            length, zones=zones, jitter=jitter, irregularity=irregularity, params=params,
            seed=seed if track_seed is None else track_seed,
        )  # fmt: skip
    trk, prof = track
    length = trk.length
    zones = trk.zones
    room = room_to_run(length, start_chainage_m, direction, vehicle, end_margin_m)
    if isinstance(speed, tuple):
        v0, v1 = speed
        duration = 2.0 * room / (v0 + v1)

        def vfun(t: NDArray[np.float64]) -> NDArray[np.float64]:
            return v0 + (v1 - v0) * np.clip(t / duration, 0.0, 1.0)

        sim = simulate(
            trk, vehicle=vehicle, speed=vfun, duration=duration * 0.999,
            start_chainage_m=start_chainage_m, dt=1.0 / sim_rate_hz,
            direction=direction,  # type: ignore[arg-type]
        )  # fmt: skip
    else:
        sim = simulate(
            trk, vehicle=vehicle, speed=float(speed), duration=room / float(speed),
            start_chainage_m=start_chainage_m, dt=1.0 / sim_rate_hz,
            direction=direction,  # type: ignore[arg-type]
        )  # fmt: skip
    sens = sensor or SensorModel()
    log = to_runlog(sim, sens, seed=seed + 1)
    return SyntheticRun(
        log, sim, trk, tuple(zones), start_chainage_m, direction,
        start_chainage_m + start_error_m, vehicle, prof,
    )  # fmt: skip


@dataclass(frozen=True)
class Score:
    """How a processed run compares with its truth.

    Attributes
    ----------
    profile_rms_mm : float
        RMS of (estimated - true) fused loaded level after removing a slowly varying
        baseline (40 m running median) from both, mm.
    zones_found : int
        True zones matched by a detected zone (overlapping it).
    zones_true : int
        True zones inside the covered stretch.
    false_alarms : int
        Detected zones that overlap no true zone.
    max_edge_error_m : float
        Largest start or end error among matched zones, m.
    max_loss_error_pct : float
        Largest stiffness-loss error among matched zones, percentage points.
    """

    profile_rms_mm: float
    zones_found: int
    zones_true: int
    false_alarms: int
    max_edge_error_m: float
    max_loss_error_pct: float


def score(result: ProcessResult, run: SyntheticRun, baseline_window_m: float = 40.0) -> Score:
    """Compare a processed run with the truth of a synthetic run."""
    g = result.chainage_m
    step = float(g[1] - g[0])
    truth = run.true_profile(g)
    t_res = truth - robust_baseline(truth, step, baseline_window_m)
    e_res = result.level_mm - robust_baseline(result.level_mm, step, baseline_window_m)
    ok = np.isfinite(t_res) & np.isfinite(e_res)
    rms = float(np.sqrt(np.mean((e_res[ok] - t_res[ok]) ** 2)))
    lo, hi = float(g[ok][0]), float(g[ok][-1])
    inside = [z for z in run.zones if z.start_m >= lo + 5 and z.end_m <= hi - 5]
    found = 0
    edge_err = 0.0
    loss_err = 0.0
    matched: set[int] = set()
    for z in inside:
        hits = [
            (i, s)
            for i, s in enumerate(result.soft_spots)
            if s.end_m >= z.start_m and s.start_m <= z.end_m
        ]
        if not hits:
            continue
        found += 1
        i, s = min(hits, key=lambda h: abs(h[1].peak_m - 0.5 * (z.start_m + z.end_m)))
        matched.update(j for j, _ in hits)
        edge_err = max(edge_err, abs(s.start_m - z.start_m), abs(s.end_m - z.end_m))
        loss_err = max(loss_err, abs(s.stiffness_loss_pct - 100 * z.loss))
    false = sum(
        1
        for i, s in enumerate(result.soft_spots)
        if i not in matched
        and not any(s.end_m >= z.start_m and s.start_m <= z.end_m for z in run.zones)
    )
    return Score(rms, found, len(inside), false, edge_err, loss_err)
