"""The calibration's objective: how much the front and rear axles' recovered levels disagree.

Both axles ride over the same rail, the rear ``d1 + d2`` later; inverted with the right vehicle
their levels agree on chainage up to the sensor noise. :func:`prepare` decimates every usable
run to the band, cuts it into segments and Fourier-transforms them once (grouped by sample step
and FFT length, so one frequency grid serves a group); :func:`evaluate` then only rebuilds the
vehicle's 2x2 inverse per frequency bin for a trial vehicle and compares the axles on the front
axle's chainage samples (the rear level there by four-point Lagrange interpolation).

Used by :func:`engine.calibration.calibrate`. Units: SI (s, m, rad/s); :func:`rms_mm` in mm.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import scipy.fft as sfft
from numpy.typing import NDArray
from scipy.signal import resample_poly

from .errors import EngineError, ParameterError
from .runlog import RunLog
from .setup import ProcessConfig, RunSetup, prepare_run
from .spectral import (
    band_window,
    edge_padding,
    estimate_white_noise,
    padded_spectrum,
    solve_bins,
    vehicle_response,
)
from .vehicle_kinds import Vehicle


class ComparedRun(Protocol):
    """What :func:`prepare` reads of a run (:class:`engine.calibration.CalibrationRun`)."""

    @property
    def log(self) -> RunLog: ...
    @property
    def start_chainage_m(self) -> float | None: ...
    @property
    def direction(self) -> str: ...
    @property
    def label(self) -> str: ...
    @property
    def body_mass_kg(self) -> float | None: ...


class Comparison(Protocol):
    """What :func:`prepare` reads of the settings (:class:`engine.calibration.CalibrationConfig`):
    the wavelength band (m), the segment length and the time used per run (s)."""

    @property
    def lambda_min_m(self) -> float: ...
    @property
    def lambda_max_m(self) -> float: ...
    @property
    def segment_s(self) -> float: ...
    @property
    def max_seconds_per_run(self) -> float | None: ...


@dataclass
class Segment:
    """A piece of one run, decimated; noise levels at the decimated step (same density)."""

    a: NDArray[np.float64]
    g: NDArray[np.float64]
    f_lo: float
    f_hi: float
    sa: float
    sg: float
    front_idx: NDArray[np.intp]
    rear_idx: NDArray[np.intp]
    rear_w: NDArray[np.float64]
    run: int


@dataclass
class Group:
    """Segments sharing one sample step and FFT length (one frequency grid) and one body mass
    (``body_mass_kg``, kg: a declared load; None: the vehicle's own)."""

    dt: float
    nfft: int
    pad: int
    n: int
    sel: NDArray[np.bool_]  # bins used (inside any segment's band)
    omega: NDArray[np.float64]  # rad/s of the used bins
    A: NDArray[np.complex128]  # (n_seg, n_used)
    Q: NDArray[np.complex128]
    wband: NDArray[np.float64]  # (n_seg, n_used)
    sa: NDArray[np.float64]  # (n_seg,) accelerometer noise at this step
    sg: NDArray[np.float64]
    # front samples compared (indices in the segment) and the rear level there (cubic weights)
    front_idx: list[NDArray[np.intp]]
    rear_idx: list[NDArray[np.intp]]  # (m, 4) indices
    rear_w: list[NDArray[np.float64]]  # (m, 4) weights
    run: list[int]  # run index of each segment
    body_mass_kg: float | None = None


def cubic_weights(
    x: NDArray[np.float64], xq: NDArray[np.float64]
) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """Four-point Lagrange interpolation of samples at increasing ``x`` onto ``xq``."""
    i = np.clip(np.searchsorted(x, xq) - 1, 1, x.size - 3)
    idx = i[:, None] + np.arange(-1, 3)[None, :]
    xs = x[idx]
    w = np.ones_like(xs)
    for j in range(4):
        for m in range(4):
            if m != j:
                w[:, j] *= (xq - xs[:, m]) / (xs[:, j] - xs[:, m])
    return idx, w


def prepare(
    runs: Sequence[ComparedRun], vehicle: Vehicle, cfg: Comparison
) -> tuple[list[Group], list[tuple[str, str]], list[tuple[str, float]]]:
    """Decimate, segment and transform every usable run once."""
    pcfg = ProcessConfig(lambda_min_m=cfg.lambda_min_m, lambda_max_m=cfg.lambda_max_m)
    taper = pcfg.taper
    skipped: list[tuple[str, str]] = []
    used: list[tuple[str, float]] = []
    pieces: dict[tuple[float, int, float | None], list[Segment]] = {}
    for r_i, run in enumerate(runs):
        label = run.label or f"run {r_i + 1}"
        if run.body_mass_kg is not None:
            try:
                vehicle.with_body_mass(run.body_mass_kg)
            except ParameterError as exc:
                skipped.append((label, f"its declared load: {exc}"))
                continue
        try:
            chk = prepare_run(
                run.log, RunSetup(run.start_chainage_m, run.direction, vehicle, config=pcfg)
            )
        except EngineError as exc:
            skipped.append((label, str(exc)))
            continue
        log = run.log
        dt = log.dt
        fs = 1.0 / dt
        # decimate to 2.5x the band's upper edge (Nyquist), zero-phase polyphase FIR
        q = max(1, int(fs / (5.0 * chk.f_hi_hz * (1 + taper))))
        sa = estimate_white_noise(log.accel_z_mps2, dt)
        sg = estimate_white_noise(log.pitch_rate_radps, dt)
        a = log.accel_z_mps2 - log.accel_z_mps2.mean()
        g = log.pitch_rate_radps - log.pitch_rate_radps.mean()
        if q > 1:
            a, g = resample_poly(a, 1, q), resample_poly(g, 1, q)
        xf = chk.positions.front[::q][: a.size] * chk.positions.sign
        xr = chk.positions.rear[::q][: a.size] * chk.positions.sign
        dtd = dt * q
        nseg = int(round(cfg.segment_s / dtd))
        total = a.size
        if total < nseg:  # short run: one segment of its own length
            nseg = total
        n_avail = max(1, total // nseg)
        n_take = n_avail
        if cfg.max_seconds_per_run is not None:
            n_take = max(1, min(n_avail, int(cfg.max_seconds_per_run / (nseg * dtd))))
        starts = np.linspace(0, total - nseg, n_take).round().astype(int) if n_take > 1 else [0]
        trim = int(math.ceil(1.0 / (chk.f_lo_hz / (1 + taper)) / dtd))  # one longest period
        lag = int(math.ceil(vehicle.wheelbase / max(chk.speed.min(), 1e-3) / dtd)) + 2
        n_used = 0
        for s0 in starts:
            sl = slice(int(s0), int(s0) + nseg)
            f_pos, r_pos = xf[sl], xr[sl]
            lo, hi = trim, nseg - trim
            if hi - lo < 4 * lag:
                continue
            # front samples whose chainage the rear axle also reaches inside the kept part
            k = np.arange(lo, hi)
            keep = (f_pos[k] >= r_pos[lo + 2]) & (f_pos[k] <= r_pos[hi - 3])
            k = k[keep]
            if k.size < 16:
                continue
            idx, w = cubic_weights(r_pos, f_pos[k])
            pieces.setdefault((dtd, nseg, run.body_mass_kg), []).append(
                Segment(a[sl], g[sl], chk.f_lo_hz, chk.f_hi_hz, sa / math.sqrt(q),
                         sg / math.sqrt(q), k, idx, w, r_i)
            )  # fmt: skip
            n_used += 1
        if n_used == 0:
            skipped.append((label, "too short to compare the two axles after edge trimming"))
            continue
        used.append((label, n_used * nseg * dtd))
    groups = []
    for (dtd, nseg, body_mass), segs in pieces.items():
        pad = edge_padding(nseg, dtd, min(sg.f_lo for sg in segs), taper)
        nfft = sfft.next_fast_len(nseg + 2 * pad, real=True)
        f = sfft.rfftfreq(nfft, dtd)
        wb = np.array([band_window(f, sg.f_lo, sg.f_hi, taper) for sg in segs])
        sel = wb.max(axis=0) > 0
        groups.append(
            Group(
                dt=dtd, nfft=nfft, pad=pad, n=nseg, sel=sel, omega=2 * np.pi * f[sel],
                A=np.array([padded_spectrum(sg.a, pad, nfft)[sel] for sg in segs]),
                Q=np.array([padded_spectrum(sg.g, pad, nfft)[sel] for sg in segs]),
                wband=wb[:, sel],
                sa=np.array([sg.sa for sg in segs]), sg=np.array([sg.sg for sg in segs]),
                front_idx=[sg.front_idx for sg in segs],
                rear_idx=[sg.rear_idx for sg in segs],
                rear_w=[sg.rear_w for sg in segs],
                run=[sg.run for sg in segs], body_mass_kg=body_mass,
            )
        )  # fmt: skip
    return groups, skipped, used


@dataclass
class Evaluation:
    """Residuals of one evaluation: per segment the difference and the level energy."""

    diff: list[NDArray[np.float64]]
    energy: NDArray[np.float64]
    run: NDArray[np.intp]


def evaluate(groups: list[Group], vehicle: Vehicle) -> Evaluation:
    """The axles' disagreement of every segment inverted with ``vehicle`` (at each group's
    declared body mass)."""
    diffs: list[NDArray[np.float64]] = []
    energy: list[float] = []
    runs: list[int] = []
    for g in groups:
        veh = vehicle if g.body_mass_kg is None else vehicle.with_body_mass(g.body_mass_kg)
        H = vehicle_response(veh, g.omega)
        full = np.zeros((g.A.shape[0], 2, g.sel.size), dtype=complex)
        for i in range(g.A.shape[0]):
            Y = solve_bins(H, g.A[i], g.Q[i], g.sa[i], g.sg[i], 1.0 / g.nfft)
            full[i, :, g.sel] = Y * g.wband[i][:, None]
        y = sfft.irfft(full, g.nfft, axis=-1)[..., g.pad : g.pad + g.n]
        for i in range(y.shape[0]):
            yf = y[i, 0, g.front_idx[i]]
            yr = np.sum(y[i, 1][g.rear_idx[i]] * g.rear_w[i], axis=1)
            diffs.append(yf - yr)
            energy.append(0.5 * float(np.sum(yf**2) + np.sum(yr**2)))
            runs.append(g.run[i])
    return Evaluation(diffs, np.array(energy), np.array(runs))


def run_objective(ev: Evaluation, run_index: int) -> float:
    sel = np.flatnonzero(ev.run == run_index)
    d = sum(float(np.sum(ev.diff[i] ** 2)) for i in sel)
    e = float(ev.energy[sel].sum())
    return math.sqrt(d / e) if e > 0 else float("nan")


def rms_mm(ev: Evaluation) -> float:
    d = np.concatenate(ev.diff)
    return float(np.sqrt(np.mean(d**2)) * 1e3)
