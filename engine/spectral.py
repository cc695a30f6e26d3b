"""Band-limited frequency-domain inversion of the vehicle's response (the default method).

The half-car is linear and time-invariant in time, whatever the speed: the rail levels under
the axles, ``y1(t)`` and ``y2(t)``, drive the body acceleration ``a(t)`` and pitch rate
``q(t)`` through a 2x2 matrix of transfer functions ``H(w)``. Inverting ``H`` frequency by
frequency is exact for band-limited signals; outside the band of interest the inverse would
amplify noise (``1/w²`` at low frequencies, the axle dynamics at high ones), so the inverse is
applied with a smooth band window and a Tikhonov term scaled to the estimated noise. Bias and
drift sit below the band and are removed with it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.fft as sfft
from numpy.typing import NDArray
from scipy.ndimage import map_coordinates, spline_filter1d

from .errors import InversionError
from .vehicle import VehicleModel

MODAL_COND_MAX = 1e8
"""Largest condition number of the state matrix's eigenvectors for which :func:`dof_response`
sums the modes; a vehicle beyond it (nearly defective) is solved bin by bin."""

BINS_PER_BLOCK = 16384
"""Frequency bins evaluated at once by :func:`dof_response` and the wheel force: a block's
temporaries (a few MB) stay in cache, where a whole hour's spectrum (~2 M bins) would cost
hundreds of MB of fresh memory per temporary."""

SPLINE_OVERSAMPLING = 8.0
"""Samples per period of the band's top frequency that a band-limited signal keeps when it is
evaluated from a decimated copy (:meth:`BandSpectrum.at_times`): a cubic spline through them
is exact to ~(2π/8)⁴/384 ≈ 1e-3 of the amplitude at the band's top edge (where the window
has fallen to zero) and to < 3e-4 inside the band."""

_SMOOTH = tuple(sorted(
    2**a * 3**b * 5**c for a in range(7) for b in range(4) for c in range(3)
    if 2**a * 3**b * 5**c <= 64
))  # fmt: skip
"""Decimation steps whose products with a fast FFT length stay fast (factors 2, 3, 5)."""


def decimation_step(dt: float, f_top: float) -> int:
    """Largest 5-smooth step (1..64 samples) keeping :data:`SPLINE_OVERSAMPLING` samples
    per period of ``f_top`` Hz in a signal sampled every ``dt`` s."""
    limit = 1.0 / (dt * SPLINE_OVERSAMPLING * f_top) if f_top > 0 else 1.0
    return max(d for d in _SMOOTH if d <= max(1.0, limit))


def _solve_by_bin(
    M: NDArray[np.float64],
    C: NDArray[np.float64],
    K: NDArray[np.float64],
    F: NDArray[np.float64],
    w: NDArray[np.float64],
) -> NDArray[np.complex128]:
    Z = -(w[:, None, None] ** 2) * M + 1j * w[:, None, None] * C + K  # (m, 4, 4)
    rhs = np.broadcast_to(F, Z.shape[:1] + F.shape).astype(np.complex128)
    return np.asarray(np.linalg.solve(Z, rhs), dtype=np.complex128)


def dof_response(
    vehicle: VehicleModel, omega: NDArray[np.float64], dofs: slice | None = None
) -> NDArray[np.complex128]:
    """Response of the vehicle's DOFs to the rail levels under its two measured points.

    Parameters
    ----------
    vehicle : VehicleModel
        Any vehicle kind (the half car; a bogie vehicle, whose measured points are its bogie
        centres and whose input is each bogie's mean level).
    omega : ndarray, shape (m,)
        Angular frequencies, rad/s.
    dofs : slice, optional
        The DOFs wanted (default all; the half car's ``slice(2, 4)``: the axles).

    Returns
    -------
    X : ndarray, shape (m, d, 2)
        ``X[k] @ [Y1, Y2]``: the DOFs (the half car's ``[u_s (m), theta_s (rad), u_u1 (m),
        u_u2 (m)]``; the rows of ``dofs``) per unit rail level (m) under measured point 1
        and 2, i.e. ``Z⁻¹ F`` with ``Z = K + i w C - w² M`` and ``F`` the kind's
        :meth:`~engine.vehicle.VehicleModel.axle_input`.

    Notes
    -----
    Evaluated as a sum over the 2n modes of the state-space form (one eigen-decomposition,
    then ``m x 2n`` divisions), not as ``m`` solves of ``Z``: the same function to rounding,
    several times faster and lighter on the long spectra of hour-long runs. A vehicle whose
    modes are nearly defective (eigenvectors conditioned beyond :data:`MODAL_COND_MAX`) is
    solved frequency by frequency instead.
    """
    M, C, K = vehicle.matrices()
    n = M.shape[0]
    dofs = slice(0, n) if dofs is None else dofs
    w = np.asarray(omega, dtype=float)
    F = vehicle.axle_input()
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ C]])
    B = np.vstack([np.zeros((n, 2)), Minv @ F])
    lam, V = np.linalg.eig(A)
    if np.linalg.cond(V) > MODAL_COND_MAX:
        return _solve_by_bin(M, C, K, F, w)[:, dofs, :]
    W = np.linalg.solve(V, B.astype(np.complex128))  # (2n, 2): each mode's share of the input
    Vq = V[dofs, :]  # (d, 8)
    # X[k, q, c] = sum_j R[k, j] Vq[q, j] W[j, c], R[k, j] = 1 / (i w_k - lam_j): one product
    P = (Vq.T[:, :, None] * W[:, None, :]).reshape(lam.size, -1)  # (2n, d * 2)
    out = np.empty((w.size, Vq.shape[0], 2), dtype=np.complex128)
    flat = out.reshape(w.size, -1)
    for k0 in range(0, w.size, BINS_PER_BLOCK):
        blk = slice(k0, k0 + BINS_PER_BLOCK)
        flat[blk] = (1.0 / (1j * w[blk, None] - lam[None, :])) @ P
    return out


def vehicle_response(vehicle: VehicleModel, omega: NDArray[np.float64]) -> NDArray[np.complex128]:
    """Frequency response from rail levels to the measured signals.

    Parameters
    ----------
    vehicle : VehicleModel
        Any vehicle kind.
    omega : ndarray, shape (m,)
        Angular frequencies, rad/s.

    Returns
    -------
    H : ndarray, shape (m, 2, 2)
        ``H[k] @ [Y1, Y2] = [A, Q]``: measured body acceleration (at the accelerometer,
        ``vehicle.sensor_x_m`` ahead of the CG; m/s² per m) and pitch rate (rad/s per m) for
        unit rail level under axle 1 and axle 2.
    """
    w = np.asarray(omega, dtype=float)
    X = dof_response(vehicle, w, slice(0, 2))  # the body's bounce and pitch
    H = np.empty((w.size, 2, 2), dtype=complex)
    # the accelerometer sits sensor_x_m ahead of the CG: it also feels the pitch acceleration
    H[:, 0, :] = -(w[:, None] ** 2) * (X[:, 0, :] + vehicle.sensor_x_m * X[:, 1, :])
    H[:, 1, :] = 1j * w[:, None] * X[:, 1, :]
    return H


def band_window(
    f: NDArray[np.float64], f_lo: float, f_hi: float, taper: float = 0.3
) -> NDArray[np.float64]:
    """Smooth band-pass weight: 1 inside ``[f_lo, f_hi]``, raised-cosine tapers outside.

    Each taper spans a fraction ``taper`` of an octave-like ratio: from ``f_lo / (1 + taper)``
    to ``f_lo`` and from ``f_hi`` to ``f_hi * (1 + taper)``. Frequencies in Hz (or cycles/m).
    """
    fa = np.abs(f)
    wgt = np.zeros_like(fa)
    lo0, hi1 = f_lo / (1 + taper), f_hi * (1 + taper)
    inside = (fa >= f_lo) & (fa <= f_hi)
    wgt[inside] = 1.0
    m = (fa > lo0) & (fa < f_lo)
    wgt[m] = 0.5 - 0.5 * np.cos(np.pi * (fa[m] - lo0) / (f_lo - lo0))
    m = (fa > f_hi) & (fa < hi1)
    wgt[m] = 0.5 + 0.5 * np.cos(np.pi * (fa[m] - f_hi) / (hi1 - f_hi))
    return wgt


@dataclass(frozen=True)
class BandSpectrum:
    """Spectrum of signals that are zero outside one contiguous band of bins.

    What the inverse computes before going back to time: the levels' (or any linear response
    of them, e.g. the wheel forces) unnormalised real FFT over the padded length ``nfft``,
    kept only at the bins ``bins`` where the band window is not zero.

    Attributes
    ----------
    values : ndarray, shape (k, m)
        Spectrum of ``k`` signals at the band's ``m`` bins (their units times samples).
    bins : slice
        The band's bins in the real FFT of length ``nfft``.
    omega : ndarray, shape (m,)
        Angular frequency of each band bin, rad/s.
    nfft, pad, n : int
        FFT length, samples padded before the signal, samples of the signal.
    dt : float
        Sample step, s.
    step : int
        Decimation step that divides ``nfft`` and keeps the band below the decimated
        Nyquist frequency with :data:`SPLINE_OVERSAMPLING` (1: none).
    """

    values: NDArray[np.complex128]
    bins: slice
    omega: NDArray[np.float64]
    nfft: int
    pad: int
    n: int
    dt: float
    step: int = 1

    def __post_init__(self) -> None:
        if self.nfft % self.step or self.bins.stop > self.nfft // self.step // 2 + 1:
            raise InversionError(
                f"decimation step {self.step} does not fit an FFT of {self.nfft} with the band "
                f"up to bin {self.bins.stop}"
            )

    def with_values(self, values: NDArray[np.complex128]) -> BandSpectrum:
        """Another set of signals on the same bins (e.g. a linear response of these)."""
        return BandSpectrum(values, self.bins, self.omega, self.nfft, self.pad, self.n,
                            self.dt, self.step)  # fmt: skip

    def decimated(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The signals exactly at every ``step``-th sample of the padded frame: times (s from
        the signal's first sample; the padding's are < 0 or beyond the end) and values (k, m).

        A spectrum that is zero above the decimated Nyquist frequency needs no low-pass: the
        short inverse transform of its first bins is the full one sampled every ``step``.
        """
        m = self.nfft // self.step
        spec = np.zeros(self.values.shape[:-1] + (m // 2 + 1,), dtype=np.complex128)
        spec[..., self.bins] = self.values
        out = sfft.irfft(spec, m, axis=-1, workers=FFT_WORKERS) / self.step
        t = (np.arange(m, dtype=np.float64) * self.step - self.pad) * self.dt
        return t, np.asarray(out, dtype=np.float64)

    def at_times(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Signal ``i`` at the times ``t[i]`` (s from the first sample, within the signal;
        NaN gives NaN), shape of ``t`` (k, q): the cubic spline through :meth:`decimated`.

        For values on a chainage grid at a fraction of the cost of :meth:`to_time`: the
        grid of a profile is far coarser than the samples of a 1 kHz log.
        """
        tk, yk = self.decimated()
        out = np.full(t.shape, np.nan)
        for i in range(yk.shape[0]):
            ok = np.isfinite(t[i])
            # cubic B-spline interpolation on the uniform decimated samples (ndimage's C
            # filter and evaluation: a tenth of CubicSpline's time on an hour)
            coef = spline_filter1d(yk[i], order=3, mode="mirror")
            at = (t[i, ok] - tk[0]) / (self.step * self.dt)
            out[i, ok] = map_coordinates(coef, at[None, :], order=3, mode="mirror",
                                         prefilter=False)  # fmt: skip
        return out

    def to_time(self, values: NDArray[np.complex128] | None = None) -> NDArray[np.float64]:
        """The signals in time, shape (k, n): these ``values`` (default: the stored ones) at
        the band's bins, zero elsewhere, inverse-transformed and cut to the signal."""
        vals = self.values if values is None else values
        spec = np.zeros(vals.shape[:-1] + (self.nfft // 2 + 1,), dtype=np.complex128)
        spec[..., self.bins] = vals
        out = sfft.irfft(spec, self.nfft, axis=-1, workers=FFT_WORKERS)
        return np.asarray(out[..., self.pad : self.pad + self.n])


@dataclass(frozen=True)
class SpectralInverse:
    """Rail levels under each axle, band-limited: their spectrum, and in time on demand.

    Attributes
    ----------
    y_front, y_rear : ndarray
        Levels at every sample, m, positive up, zero-mean in the band ``[f_lo, f_hi]`` Hz
        (computed from ``band`` when first asked for).
    f_lo, f_hi : float
        Time-frequency band used, Hz.
    noise_accel, noise_gyro : float
        Estimated white-noise standard deviations at the sample rate, m/s² and rad/s.
    band : BandSpectrum
        The levels' spectrum in the band (m times samples), ``y_front``/``y_rear`` being its
        :meth:`BandSpectrum.to_time`: the profile on a chainage grid and linear responses
        of the levels (the wheel forces) are taken from it without a full-length transform.
    """

    f_lo: float
    f_hi: float
    noise_accel: float
    noise_gyro: float
    band: BandSpectrum

    @cached_property
    def _levels(self) -> NDArray[np.float64]:
        return self.band.to_time()

    @property
    def y_front(self) -> NDArray[np.float64]:
        """Level under the front axle at every sample, m."""
        return self._levels[0]

    @property
    def y_rear(self) -> NDArray[np.float64]:
        """Level under the rear axle at every sample, m."""
        return self._levels[1]


def estimate_white_noise(x: NDArray[np.float64], dt: float, f_min: float = 150.0) -> float:
    """Standard deviation of the white noise in a signal, from its spectrum above ``f_min`` Hz.

    The vehicle filters the track's input strongly above the axle resonances, so the upper
    part of the spectrum is sensor noise; its median power density gives a robust level.
    Logs sampled below ~130 Hz cannot tell noise from signal: NaN.
    """
    fs = 1.0 / dt
    # slow loggers: use the top 40 % of their band, still above the vehicle's resonances
    f_min = min(f_min, 0.6 * fs / 2)
    if f_min < 40.0 or x.size < 256:
        return float("nan")
    seg = 1024 if x.size >= 4096 else 256
    n_seg = x.size // seg
    blocks = x[: n_seg * seg].reshape(n_seg, seg)
    blocks = blocks - blocks.mean(axis=1, keepdims=True)
    win = np.hanning(seg)
    spec = np.abs(np.fft.rfft(blocks * win, axis=1)) ** 2
    psd = spec.mean(axis=0) / (np.sum(win**2))  # per-bin variance contribution * 1/seg ...
    f = np.fft.rfftfreq(seg, dt)
    sel = f >= f_min
    # for white noise of variance s², E|X_k|²/sum(win²) = s² (one-sided bins double)
    return float(np.sqrt(np.median(psd[sel])))


def edge_padding(n: int, dt: float, f_lo: float, taper: float) -> int:
    """Samples padded at each end against wrap-around: one longest period of the band."""
    return int(min(n, 2.0 / (f_lo / (1 + taper)) / dt))


FFT_WORKERS = 2
"""Threads of a batched FFT (two channels, two axles): both cores of a small server."""


def padded_spectrum(x: NDArray[np.float64], pad: int, nfft: int) -> NDArray[np.complex128]:
    """Real FFT of ``x`` detrended (line through its ends) and mirror-padded by ``pad``.

    ``x`` is one signal (n,) or several along the last axis (k, n), transformed at once on
    :data:`FFT_WORKERS` threads (the same numbers as one by one).
    """
    n = x.shape[-1]
    buf = np.zeros(x.shape[:-1] + (nfft,))
    xx = buf[..., pad : pad + n]
    # remove the straight line through the ends, so the periodic extension is continuous
    # (built in place: np.linspace along the last axis of a batch is several times slower)
    first = x[..., :64].mean(axis=-1)[..., None]
    last = x[..., -64:].mean(axis=-1)[..., None]
    np.multiply(last - first, np.arange(n) / max(n - 1, 1), out=xx)
    np.subtract(x, xx, out=xx)
    xx -= first
    # mirror-pad with a taper to soften the edges
    ramp = 0.5 - 0.5 * np.cos(np.linspace(0, np.pi, pad)) if pad > 0 else np.zeros(0)
    buf[..., :pad] = xx[..., pad:0:-1][..., :pad] * ramp if pad < n else 0.0
    if pad < n - 1:
        buf[..., pad + n : pad + n + pad] = xx[..., -2 : -pad - 2 : -1] * ramp[::-1]
    return sfft.rfft(buf, axis=-1, workers=FFT_WORKERS)


TYPICAL_NOISE_ACCEL = 5e-3
"""Accelerometer white noise assumed when it cannot be estimated, m/s² (a MEMS sensor)."""
TYPICAL_NOISE_GYRO = 1e-4
"""Gyroscope white noise assumed when it cannot be estimated, rad/s (a MEMS sensor)."""
NOISE_RATIO_RANGE = 1e4
"""How far the gyro-to-accel noise ratio may stray from the typical one, either way."""


def noise_weights_sigma(noise_accel: float, noise_gyro: float) -> tuple[float, float]:
    """The noise levels the inverse weights the channels by, m/s² and rad/s (floored).

    Unknown levels (NaN, 0) take the typical MEMS values. A channel estimated as (nearly)
    noise-free — a simulated or heavily filtered gyro beside a noisy accelerometer — would
    get a weight so large that the per-bin normal matrix loses the other channel in rounding
    and is singular; so the ratio of the two levels is kept within :data:`NOISE_RATIO_RANGE`
    of the typical ratio (the quieter channel still dominates, by up to 10⁸ in weight).
    """
    sa = noise_accel if np.isfinite(noise_accel) and noise_accel > 0 else TYPICAL_NOISE_ACCEL
    sg = noise_gyro if np.isfinite(noise_gyro) and noise_gyro > 0 else TYPICAL_NOISE_GYRO
    typical = TYPICAL_NOISE_GYRO / TYPICAL_NOISE_ACCEL
    ratio = float(np.clip(sg / sa / typical, 1 / NOISE_RATIO_RANGE, NOISE_RATIO_RANGE))
    # keep the larger level, lift the smaller one to the allowed ratio
    if sg / sa / typical < ratio:
        sg = sa * typical * ratio
    elif sg / sa / typical > ratio:
        sa = sg / (typical * ratio)
    return float(sa), float(sg)


def weighted_adjoint(
    H: NDArray[np.complex128], noise_accel: float, noise_gyro: float
) -> NDArray[np.complex128]:
    """``Hᴴ W`` per bin, shape (m, 2, 2): the response's conjugate transpose weighted by
    ``W = diag(1/σ_a², 1/σ_g²)``, the channels' noise levels of :func:`noise_weights_sigma`
    (m/s² and rad/s; unknown: the typical MEMS ratio)."""
    sa, sg = noise_weights_sigma(noise_accel, noise_gyro)
    Wd = np.array([1.0 / sa**2, 1.0 / sg**2])
    return np.conj(np.transpose(H, (0, 2, 1))) * Wd[None, None, :]


def solve_bins(
    H: NDArray[np.complex128],
    A: NDArray[np.complex128],
    Q: NDArray[np.complex128],
    noise_accel: float,
    noise_gyro: float,
    mu_scale: float,
) -> NDArray[np.complex128]:
    """Noise-weighted Tikhonov inverse, bin by bin: ``(Hᴴ W H + μ I)⁻¹ Hᴴ W [A; Q]``.

    ``W`` as :func:`weighted_adjoint`; ``μ = mu_scale / (1 mm)²``, the prior of a ~1 mm² track
    level scale per bin (``mu_scale`` is ``regularisation / nfft`` for an unnormalised FFT).
    ``A``, ``Q`` may carry leading batch axes before the bin axis; returns
    ``Y[..., bin, axle]``.
    """
    HW = weighted_adjoint(H, noise_accel, noise_gyro)
    N = HW @ H + mu_scale / (1e-3) ** 2 * np.eye(2)[None]
    G = np.linalg.solve(N, HW)  # (m, 2, 2): the inverse operator per bin
    return np.einsum("mij,...mj->...mi", G, np.stack([A, Q], axis=-1))


WIENER_SMOOTHING = 0.15
"""Relative width of the running mean that gives the level's power spectrum from the bins
(a fraction of each bin's frequency): wide enough to average the noise of single bins, narrow
against the spectrum's slope over the band."""


@dataclass(frozen=True)
class AxleDelay:
    """How far in time the rear measured point trails the front one along the run.

    Under a changing speed the delay changes, so it is given per time and per axle: the front
    level at ``t`` is met again by the rear axle ``front_s`` later, the rear level at ``t``
    was under the front axle ``rear_s`` earlier (the two differ by the speed's change over the
    delay).

    Attributes
    ----------
    t_s : ndarray, shape (k,)
        Times, s from the first sample, increasing.
    front_s, rear_s : ndarray, shape (k,)
        The delays at those times, s (> 0).
    """

    t_s: NDArray[np.float64]
    front_s: NDArray[np.float64]
    rear_s: NDArray[np.float64]


TIE_PHASE = 1.0
"""Largest phase, rad at the band's top frequency, between neighbouring delays the tie is
evaluated at (:func:`delay_nodes`): a level between two of them blends two estimates whose
delays are off by at most that. Measured on ramp runs of every grade: 0.25-4 rad give the same
profile error (the top of the band is where the track is weakest against the noise), so 1 rad
leaves a margin at a quarter of the cost of 0.25."""

TIE_NODES_MAX = 48
"""Most delays the tie is evaluated at (a ±15 % speed ramp needs about 12); a wider range of
speeds spreads them further apart than :data:`TIE_PHASE`."""


def delay_nodes(delay: AxleDelay, omega_top: float) -> NDArray[np.float64]:
    """The delays (s) the tie is evaluated at: one where the run's delay hardly changes (by
    less than ``TIE_PHASE / omega_top``), else at most that far apart over the run's delays,
    placed where the run spends its time (quantiles), at most :data:`TIE_NODES_MAX`."""
    tau = np.concatenate([delay.front_s, delay.rear_s])
    spread = float(np.ptp(tau)) if tau.size else 0.0
    gap = TIE_PHASE / max(omega_top, 1e-9)
    if spread <= gap:
        return np.array([float(np.mean(tau))])
    k = int(min(TIE_NODES_MAX, np.ceil(spread / gap) + 1))
    nodes = np.quantile(tau, np.linspace(0.0, 1.0, k))
    # quantiles bunch where the speed dwells: keep them at least a tenth of the gap apart
    keep = np.concatenate([[True], np.diff(nodes) > 0.1 * gap])
    return np.asarray(nodes[keep], dtype=np.float64)


def node_weights(
    tau: NDArray[np.float64], nodes: NDArray[np.float64]
) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """Linear interpolation of delays ``tau`` between ``nodes`` (clamped at the ends): the
    node below each (``nodes.size - 2`` at most) and the weight of the one above it; the
    node below weighs the rest."""
    if nodes.size == 1:
        return np.full(tau.shape, -1, dtype=np.intp), np.zeros_like(tau)
    t = np.clip(tau, nodes[0], nodes[-1])
    below = np.clip(np.searchsorted(nodes, t, side="right") - 1, 0, nodes.size - 2)
    frac = (t - nodes[below]) / (nodes[below + 1] - nodes[below])
    return below, frac


def tie_coherence(
    delay: AxleDelay, nodes: NDArray[np.float64], omega: NDArray[np.float64], most: int = 64
) -> NDArray[np.complex128]:
    """``c`` of the tie (:func:`wiener_bins`) for each node, shape (nodes, bins).

    Several nodes: each its own delay exactly, ``c = exp(-i omega tau_j)`` (the blending of
    :func:`tied_band` follows the run's delay between them). One node: the mean of
    ``exp(-i omega tau)`` over up to ``most`` of the run's delays, whose magnitude falls
    where their small spread smears the phase.
    """
    if nodes.size > 1:
        return np.exp(-1j * nodes[:, None] * omega[None, :])
    tau = np.concatenate([delay.front_s, delay.rear_s])
    tau = tau[np.linspace(0, tau.size - 1, min(most, tau.size)).astype(np.intp)]
    return np.exp(-1j * omega[None, :] * tau[:, None]).mean(axis=0)[None, :]


def wiener_bins(
    H: NDArray[np.complex128],
    A: NDArray[np.complex128],
    Q: NDArray[np.complex128],
    noise_accel: float,
    noise_gyro: float,
    n_eff: float,
    omega: NDArray[np.float64],
    coherence: NDArray[np.complex128] | None = None,
    independent: float = 1e-5,
) -> NDArray[np.complex128]:
    """Noise-weighted inverse with the levels' own power spectrum as prior, bin by bin.

    ``(Hᴴ W H + I / P)⁻¹ Hᴴ W [A; Q]``: ``W`` as :func:`weighted_adjoint`; ``P`` per bin is the
    power of the levels the log itself shows there (the least-squares levels' power, smoothed
    over neighbouring bins, less the noise power ``n_eff diag((Hᴴ W H)⁻¹)`` the measured
    sensor noise puts into them). Where the noise outweighs the track the bin is shrunk towards
    zero, where the track dominates it is left as measured: the minimum-mean-square-error
    (Wiener) estimate of a Gaussian level of that spectrum. ``n_eff`` is the number of noise
    samples in the transformed frame (the signal plus its tapered padding).

    With ``coherence`` (shape (bins,) or (k, bins): ``c = mean(exp(-i omega tau))`` over the
    rear axle's delays ``tau`` behind the front one, :func:`tie_coherence`) the prior also
    knows that both axles ride the same track: the rear level is the front one delayed,
    ``E[Y1 Y2*] = P conj(c)``, plus an ``independent`` share of ``P`` per axle for what
    differs between them; ``k`` coherences give ``k`` estimates, shape (k, bins, 2). The tie
    is strong (1e-5: measured best of 1e-5-0.3 on the sensor grades, and as good with the
    wheelbase 3 % off) and loosens by itself where ``|c|`` falls below 1.
    """
    HW = weighted_adjoint(H, noise_accel, noise_gyro)
    N = HW @ H
    b = np.einsum("mij,mj->mi", HW, np.stack([A, Q], axis=-1))
    # least-squares levels (a whisker of ridge keeps the few ill-posed bins finite)
    ridge = 1e-9 * np.trace(N, axis1=1, axis2=2).real[:, None, None] * np.eye(2)[None]
    Ninv = _inv2(N + ridge)
    y_ls = np.einsum("mij,mj->mi", Ninv, b)
    power = np.mean(np.abs(y_ls) ** 2, axis=1)
    noise = n_eff * np.mean(np.real(np.diagonal(Ninv, axis1=1, axis2=2)), axis=1)
    # running means over a constant relative bandwidth (the spectra fall steeply with f)
    csum_p = np.concatenate([[0.0], np.cumsum(power)])
    csum_n = np.concatenate([[0.0], np.cumsum(noise)])
    k = np.arange(omega.size)
    df = omega[1] - omega[0] if omega.size > 1 else 1.0
    half = np.maximum(2, np.round(0.5 * WIENER_SMOOTHING * omega / df)).astype(np.intp)
    lo = np.clip(k - half, 0, omega.size)
    hi = np.clip(k + half + 1, 0, omega.size)
    cnt = hi - lo
    p_tot = (csum_p[hi] - csum_p[lo]) / cnt
    p_noise = (csum_n[hi] - csum_n[lo]) / cnt
    # the track's share, never below a hundredth of what is there (no bin is zeroed outright)
    prior = np.maximum(p_tot - p_noise, 1e-2 * p_tot)
    # (P N + C^-1)^-1 P b, the same estimate as (N + C^-1 / P)^-1 b, stays finite where a
    # silent log has no power at all (P = 0: the estimate is 0)
    Pb = prior[:, None] * b
    PN = prior[:, None, None] * N
    if coherence is None:
        return np.einsum("mij,mj->mi", _inv2(PN + np.eye(2)[None]), Pb)
    c = np.atleast_2d(coherence)
    d = 1.0 + independent
    det = d * d - np.abs(c) ** 2
    Cinv = np.empty(c.shape + (2, 2), dtype=np.complex128)
    Cinv[..., 0, 0] = Cinv[..., 1, 1] = d / det
    Cinv[..., 0, 1] = -np.conj(c) / det
    Cinv[..., 1, 0] = -c / det
    out = np.einsum("kmij,mj->kmi", _inv2(PN[None] + Cinv), Pb)
    return out if np.ndim(coherence) == 2 else out[0]


def tied_band(
    Y: NDArray[np.complex128], delay: AxleDelay, nodes: NDArray[np.float64], like: BandSpectrum
) -> BandSpectrum:
    """One band spectrum of the levels from the estimates tied at each delay node.

    ``Y`` (nodes, bins, 2) holds, per node, the levels as if the delay were that node's
    everywhere. Each is right where the run's delay is near its node, so the levels in time
    are the nodes' estimates blended by :func:`node_weights` of the delay at each instant
    (the front level by its delay ahead, the rear one by its delay behind), on the decimated
    samples of ``like`` (its bins, frame and step), and transformed back to the band's bins.
    """
    tk, acc = like.with_values(np.zeros((2, Y.shape[1]), dtype=np.complex128)).decimated()
    # per axle, the samples grouped by the node below their delay: each node then touches
    # only the samples it is blended into (its own group, and the group of the node below)
    groups = []
    for tau in (delay.front_s, delay.rear_s):
        below, frac = node_weights(np.interp(tk, delay.t_s, tau), nodes)
        order = np.argsort(below, kind="stable")
        edges = np.searchsorted(below[order], np.arange(nodes.size + 1))
        groups.append((order, edges, frac))
    for j in range(nodes.size):
        yk = like.with_values(Y[j].T).decimated()[1]
        for axle, (order, edges, frac) in enumerate(groups):
            own = order[edges[j] : edges[j + 1]]
            acc[axle, own] += (1.0 - frac[own]) * yk[axle, own]
            if j > 0:
                under = order[edges[j - 1] : edges[j]]
                acc[axle, under] += frac[under] * yk[axle, under]
    spec = sfft.rfft(acc * like.step, tk.size, axis=-1, workers=FFT_WORKERS)
    return like.with_values(np.asarray(spec[:, like.bins], dtype=np.complex128))


def _inv2(M: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Inverses of a stack of 2x2 matrices (..., 2, 2) in closed form (a few times faster
    than ``np.linalg.inv`` on small matrices)."""
    a, b, c, d = M[..., 0, 0], M[..., 0, 1], M[..., 1, 0], M[..., 1, 1]
    det = a * d - b * c
    out = np.empty_like(M)
    out[..., 0, 0] = d / det
    out[..., 0, 1] = -b / det
    out[..., 1, 0] = -c / det
    out[..., 1, 1] = a / det
    return out


def spectral_inverse(
    accel: NDArray[np.float64],
    pitch_rate: NDArray[np.float64],
    dt: float,
    vehicle: VehicleModel,
    f_lo: float,
    f_hi: float,
    *,
    taper: float = 0.3,
    regularisation: float = 1.0,
    wiener: bool = False,
    axle_delay: AxleDelay | None = None,
) -> SpectralInverse:
    """Band-limited inverse of the vehicle's response, from (a, q) to (y1, y2).

    Parameters
    ----------
    accel : ndarray
        Body acceleration, m/s² (any constant offset, i.e. bias or gravity, is ignored).
    pitch_rate : ndarray
        Body pitch rate, rad/s (any bias is ignored).
    dt : float
        Sample step, s.
    vehicle : VehicleModel
        Any vehicle kind.
    f_lo, f_hi : float
        Band kept, Hz.
    taper : float
        Relative width of the band's raised-cosine edges.
    regularisation : float
        Multiplier of the Tikhonov term (1 = noise-matched; 0 = plain inverse in the band).
    wiener : bool
        Use the levels' own power spectrum as the prior (:func:`wiener_bins`) instead of the
        flat Tikhonov term.
    axle_delay : AxleDelay, optional
        With ``wiener``: the rear axle's delay behind the front one along the run; the prior
        then ties the two levels (:func:`wiener_bins`), at each of the run's delays
        (:func:`delay_nodes`) where the speed changes (:func:`tied_band`).

    Returns
    -------
    SpectralInverse
    """
    n = accel.size
    if not (0 < f_lo < f_hi):
        raise InversionError(f"band must satisfy 0 < f_lo < f_hi, got {f_lo}, {f_hi} Hz")
    if f_hi * (1 + taper) >= 0.5 / dt:
        raise InversionError(
            f"the band's upper edge {f_hi * (1 + taper):.1f} Hz is above the Nyquist frequency "
            f"{0.5 / dt:.1f} Hz of a {1 / dt:.0f} Hz log: sample faster or lower the band"
        )
    sa = estimate_white_noise(accel, dt)
    sg = estimate_white_noise(pitch_rate, dt)
    pad = edge_padding(n, dt, f_lo, taper)
    step = decimation_step(dt, f_hi * (1 + taper))
    nfft = step * sfft.next_fast_len(-(-(n + 2 * pad) // step), real=True)
    A, Q = padded_spectrum(np.stack([accel, pitch_rate]), pad, nfft)
    f = sfft.rfftfreq(nfft, dt)
    wband = band_window(f, f_lo, f_hi, taper)
    inside = np.flatnonzero(wband > 0)  # one run of bins: the window is 0 outside its edges
    bins = slice(int(inside[0]), int(inside[-1]) + 1) if inside.size else slice(0, 0)
    omega = 2 * np.pi * f[bins]
    H = vehicle_response(vehicle, omega)
    nodes = None
    if wiener:
        # the mirrored padding carries the noise too, tapered (mean square of the ramp: 3/8)
        n_eff = n + 0.75 * pad
        coherence = None
        if axle_delay is not None and omega.size:
            nodes = delay_nodes(axle_delay, float(omega[-1]))
            coherence = tie_coherence(axle_delay, nodes, omega)
        Y = wiener_bins(H, A[bins], Q[bins], sa, sg, n_eff, omega, coherence)
    else:
        Y = solve_bins(H, A[bins], Q[bins], sa, sg, regularisation / nfft)
    Y = Y * wband[bins, None]
    if nodes is None or nodes.size == 1:
        band = BandSpectrum(np.reshape(Y, Y.shape[-2:]).T, bins, omega, nfft, pad, n, dt, step)
    else:
        like = BandSpectrum(Y[0].T, bins, omega, nfft, pad, n, dt, step)
        band = tied_band(Y, axle_delay, nodes, like)  # type: ignore[arg-type]
    return SpectralInverse(f_lo=f_lo, f_hi=f_hi, noise_accel=sa, noise_gyro=sg, band=band)
