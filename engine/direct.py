"""The paper's direct-integration inverse (Fig. 2, eqs. 7-21).

From the body's vertical acceleration and pitch rate, recover the rail level under each axle by
integrating the body motion with Newmark relations, eliminating the suspension forces from the
two body equations, integrating each axle's own equation and reading the contact spring. Run at
the forward model's step with the same ``gamma, beta`` from a static start, this is an exact
algebraic inverse of the forward discretisation.

It is only marginally stable (a Newmark differentiation mode at the Nyquist frequency and a
double integration): on noisy, biased, rounded or resampled data its raw output is useless; see
:mod:`engine.robust` for the inversion used on real logs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter

from .errors import InversionError, ParameterError
from .newmark import Newmark
from .vehicle import TABLE1, VehicleParams


@dataclass(frozen=True)
class DirectResult:
    """Output of the direct inverse; arrays have one entry per sample.

    Attributes
    ----------
    y_front, y_rear : ndarray
        Rail level under the front and rear axle relative to the first sample, m, positive up.
    u_s, theta_s : ndarray
        Body bounce (m) and pitch (rad) relative to the first sample.
    u_front, u_rear : ndarray
        Axle displacements relative to the first sample, m.
    """

    y_front: NDArray[np.float64]
    y_rear: NDArray[np.float64]
    u_s: NDArray[np.float64]
    theta_s: NDArray[np.float64]
    u_front: NDArray[np.float64]
    u_rear: NDArray[np.float64]


def _check(accel: ArrayLike, pitch_rate: ArrayLike) -> tuple[NDArray[np.float64], ...]:
    a = np.ascontiguousarray(accel, dtype=float)
    q = np.ascontiguousarray(pitch_rate, dtype=float)
    if a.ndim != 1 or a.shape != q.shape:
        raise InversionError(
            f"acceleration and pitch rate must be 1-D arrays of equal length, got shapes "
            f"{a.shape} and {q.shape}"
        )
    if a.size < 3:
        raise InversionError("the direct inverse needs at least 3 samples")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(q))):
        raise InversionError("acceleration and pitch rate must be finite")
    return a, q


def _newmark_displacement(
    v: NDArray[np.float64], a: NDArray[np.float64], nm: Newmark
) -> NDArray[np.float64]:
    """Displacement (zero start) from velocity and acceleration by the Newmark relation
    ``u[n+1] = u[n] + dt v[n] + dt²((0.5-b) a[n] + b a[n+1])``."""
    dt, b = nm.dt, nm.beta
    inc = np.empty_like(a)
    inc[0] = 0.0
    inc[1:] = dt * v[:-1] + dt * dt * ((0.5 - b) * a[:-1] + b * a[1:])
    return np.cumsum(inc)


def _newmark_integrate(
    a: NDArray[np.float64], nm: Newmark
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Velocity and displacement from acceleration by the Newmark relations (zero start)."""
    dt, g = nm.dt, nm.gamma
    # v[n+1] = v[n] + dt((1-g) a[n] + g a[n+1])
    v = lfilter([g * dt, (1 - g) * dt], [1.0, -1.0], a)
    v -= v[0]  # v[0] = 0 (lfilter's first output is g dt a[0])
    v[0] = 0.0
    return v, _newmark_displacement(v, a, nm)


def _newmark_differentiate(
    v: NDArray[np.float64], nm: Newmark
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Acceleration and displacement from velocity by the Newmark relations (zero start)."""
    dt, g = nm.dt, nm.gamma
    # a[n+1] = (v[n+1] - v[n] - dt (1-g) a[n]) / (g dt), a[0] = 0
    dv = np.empty_like(v)
    dv[0] = 0.0
    dv[1:] = np.diff(v) / (g * dt)
    acc = lfilter([1.0], [1.0, (1 - g) / g], dv)
    return acc, _newmark_displacement(v, acc, nm)


def _axle_from_force(
    P: NDArray[np.float64], k: float, c: float, nm: Newmark
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Axle displacement, velocity, acceleration from its suspension force ``P = c u' + k u``.

    Newmark recursion with state ``(u, u', u'')`` from rest, as a linear filter on ``P``.
    """
    dt, g, b = nm.dt, nm.gamma, nm.beta
    # velocity relation: u'[n+1] = g/(b dt)(u[n+1]-u[n]) + (1-g/b) u'[n] + dt(1-g/(2b)) u''[n]
    a_uu = g / (b * dt)
    denom = k + c * a_uu
    # state x = [u, u', u''], x[n+1] = A x[n] + B P[n+1]
    # u[n+1] = (P[n+1] + c(a_uu u[n] - (1-g/b) u'[n] - dt(1-g/(2b)) u''[n])) / denom
    ru = np.array([c * a_uu, -c * (1 - g / b), -c * dt * (1 - g / (2 * b))]) / denom
    bu = 1.0 / denom
    # u''[n+1] = (u[n+1]-u[n])/(b dt²) - u'[n]/(b dt) - (1/(2b)-1) u''[n]
    # u'[n+1]  = u'[n] + dt((1-g) u''[n] + g u''[n+1])
    A = np.zeros((3, 3))
    B = np.zeros(3)
    A[0] = ru
    B[0] = bu
    A[2] = (ru - np.array([1.0, 0.0, 0.0])) / (b * dt * dt) - np.array(
        [0.0, 1.0 / (b * dt), 1.0 / (2 * b) - 1.0]
    )
    B[2] = bu / (b * dt * dt)
    A[1] = np.array([0.0, 1.0, (1 - g) * dt]) + g * dt * A[2]
    B[1] = g * dt * B[2]
    u, ud, udd = _state_filter(A, B, P)
    return u, ud, udd


def _state_filter(
    A: NDArray[np.float64], B: NDArray[np.float64], p: NDArray[np.float64]
) -> list[NDArray[np.float64]]:
    """Run ``x[n+1] = A x[n] + B p[n+1]`` from ``x[0] = 0``; one array per state component.

    Each component is an IIR filter of ``p`` with the characteristic polynomial of ``A``
    as denominator; numerators come from ``adj(zI - A) B``.
    """
    from scipy.signal import ss2tf

    n = A.shape[0]
    # x[n] = A x[n-1] + B p[n]  <=> x = (I - A z^-1)^-1 B p
    Cm = np.eye(n)
    num, den = ss2tf(A, B.reshape(n, 1), Cm, np.zeros((n, 1)))
    # ss2tf gives H(z) = C (zI - A)^-1 B; we need z (zI-A)^-1 B = (I - A z^-1)^-1 B:
    # multiply by z: shift numerators one place left (their leading coefficient is zero).
    p0 = p.copy()
    p0[0] = 0.0  # state starts at rest: x[0] = 0 whatever p[0]
    return [lfilter(np.append(num[j][1:], 0.0), den, p0) for j in range(n)]


def _direct_filtered(
    a_m: NDArray[np.float64], qd: NDArray[np.float64], nm: Newmark, v: VehicleParams
) -> DirectResult:
    """The whole run at once: each Newmark recursion as an IIR filter."""
    qd = qd - qd[0]
    qdd, th = _newmark_differentiate(qd, nm)
    # the accelerometer sits sensor_x_m ahead of the CG: remove the pitch acceleration it feels
    a_s = a_m - v.sensor_x_m * qdd if v.sensor_x_m else a_m
    vd_s, u_s = _newmark_integrate(a_s, nm)
    d1, d2 = v.d1, v.d2
    RA = (
        v.ms * a_s
        + (v.cs1 + v.cs2) * vd_s
        + (v.ks1 + v.ks2) * u_s
        + (v.cs1 * d1 - v.cs2 * d2) * qd
        + (v.ks1 * d1 - v.ks2 * d2) * th
    )
    RB = (
        v.Is * qdd
        + d1 * (v.cs1 * (vd_s + d1 * qd) + v.ks1 * (u_s + d1 * th))
        - d2 * (v.cs2 * (vd_s - d2 * qd) + v.ks2 * (u_s - d2 * th))
    )
    P1 = (d2 * RA + RB) / (d1 + d2)
    P2 = (d1 * RA - RB) / (d1 + d2)
    u1, ud1, udd1 = _axle_from_force(P1, v.ks1, v.cs1, nm)
    u2, ud2, udd2 = _axle_from_force(P2, v.ks2, v.cs2, nm)
    S1 = v.cs1 * (vd_s + d1 * qd - ud1) + v.ks1 * (u_s + d1 * th - u1)
    S2 = v.cs2 * (vd_s - d2 * qd - ud2) + v.ks2 * (u_s - d2 * th - u2)
    y1 = u1 + (v.mu1 * udd1 - S1) / v.kt1
    y2 = u2 + (v.mu2 * udd2 - S2) / v.kt2
    return DirectResult(y_front=y1, y_rear=y2, u_s=u_s, theta_s=th, u_front=u1, u_rear=u2)


def _direct_loop(
    a_s: NDArray[np.float64], qd_in: NDArray[np.float64], nm: Newmark, v: VehicleParams
) -> DirectResult:
    """Per sample in Python: the straightforward transcription of the paper's flow chart."""
    dt, g, b = nm.dt, nm.gamma, nm.beta
    n = a_s.size
    d1, d2 = v.d1, v.d2
    out = np.zeros((6, n))
    us = vs = th = thd = thdd = 0.0
    u = [0.0, 0.0]
    ud = [0.0, 0.0]
    udd = [0.0, 0.0]
    ks = (v.ks1, v.ks2)
    cs = (v.cs1, v.cs2)
    mu = (v.mu1, v.mu2)
    kt = (v.kt1, v.kt2)
    qd0 = float(qd_in[0])
    a_prev = float(a_s[0])
    for i in range(1, n):
        thd_new = float(qd_in[i]) - qd0
        thdd_new = (thd_new - thd - dt * (1 - g) * thdd) / (g * dt)
        a_new = float(a_s[i]) - v.sensor_x_m * thdd_new  # CG acceleration
        us = us + dt * vs + dt * dt * ((0.5 - b) * a_prev + b * a_new)
        vs = vs + dt * ((1 - g) * a_prev + g * a_new)
        th = th + dt * thd + dt * dt * ((0.5 - b) * thdd + b * thdd_new)
        thd, thdd = thd_new, thdd_new
        RA = (
            v.ms * a_new + (v.cs1 + v.cs2) * vs + (v.ks1 + v.ks2) * us
            + (v.cs1 * d1 - v.cs2 * d2) * thd + (v.ks1 * d1 - v.ks2 * d2) * th
        )  # fmt: skip
        RB = (
            v.Is * thdd
            + d1 * (v.cs1 * (vs + d1 * thd) + v.ks1 * (us + d1 * th))
            - d2 * (v.cs2 * (vs - d2 * thd) + v.ks2 * (us - d2 * th))
        )
        P = ((d2 * RA + RB) / (d1 + d2), (d1 * RA - RB) / (d1 + d2))
        body = (us + d1 * th, us - d2 * th)
        bodyv = (vs + d1 * thd, vs - d2 * thd)
        for j in range(2):
            k, c = ks[j], cs[j]
            # P = c u'[n+1] + k u[n+1] with the Newmark velocity relation
            num = P[j] + c * (
                g / (b * dt) * u[j] - (1 - g / b) * ud[j] - dt * (1 - g / (2 * b)) * udd[j]
            )
            u_new = num / (k + c * g / (b * dt))
            udd_new = (u_new - u[j]) / (b * dt * dt) - ud[j] / (b * dt) - (0.5 / b - 1) * udd[j]
            ud[j] = ud[j] + dt * ((1 - g) * udd[j] + g * udd_new)
            u[j], udd[j] = u_new, udd_new
            S = c * (bodyv[j] - ud[j]) + k * (body[j] - u[j])
            out[j, i] = u[j] + (mu[j] * udd[j] - S) / kt[j]
            out[4 + j, i] = u[j]
        out[2, i] = us
        out[3, i] = th
        a_prev = a_new
    return DirectResult(
        y_front=out[0], y_rear=out[1], u_s=out[2], theta_s=out[3], u_front=out[4], u_rear=out[5]
    )


_IMPLEMENTATIONS: dict[
    str, Callable[[NDArray[np.float64], NDArray[np.float64], Newmark, VehicleParams], DirectResult]
] = {"filter": _direct_filtered, "loop": _direct_loop}


def direct_inverse(
    accel: ArrayLike,
    pitch_rate: ArrayLike,
    dt: float,
    vehicle: VehicleParams = TABLE1,
    *,
    gamma: float = 0.5,
    beta: float = 0.25,
    implementation: str = "filter",
) -> DirectResult:
    """Rail level under each axle from body acceleration and pitch rate (paper, Fig. 2).

    Parameters
    ----------
    accel : array_like, shape (n,)
        Body vertical acceleration at the accelerometer (``vehicle.sensor_x_m`` ahead of the
        centre of gravity), m/s², gravity removed, positive up, starting from static
        equilibrium.
    pitch_rate : array_like, shape (n,)
        Body pitch rate, rad/s, positive nose-up.
    dt : float
        Sample step, s.
    vehicle : VehicleParams
        The half-car.
    gamma, beta : float
        Newmark parameters of the integration (0.5, 0.25: average acceleration).
    implementation : {'filter', 'loop'}
        How the recursions run: ``'filter'`` as IIR filters over the whole run (the fast
        one); ``'loop'`` per sample in Python, the transcription of the paper's flow chart
        kept as the reference the filters are checked and benchmarked against.

    Returns
    -------
    DirectResult
        Levels relative to the first sample, m.

    Notes
    -----
    With ``P_i = c_si u'_ui + k_si u_ui`` the suspension forces on the axles, the two body
    equations give ``P_1 + P_2 = R_A`` and ``d1 P_1 - d2 P_2 = R_B`` with the right-hand
    sides known from the integrated body motion; each ``P_i`` then drives a Newmark
    recursion for axle ``i`` and the axle equation gives the contact deflection
    ``y_i = u_ui + (m_ui u''_ui - S_i) / k_ti`` where ``S_i`` is the suspension force on the
    axle. All quantities are deviations from the static start, so gravity drops out.
    """
    a_m, qd = _check(accel, pitch_rate)
    nm = Newmark(dt, gamma, beta)
    run = _IMPLEMENTATIONS.get(implementation)
    if run is None:
        raise ParameterError(
            f"implementation must be one of {sorted(_IMPLEMENTATIONS)}, got {implementation!r}",
            field="implementation",
        )
    return run(a_m, qd, nm, vehicle)


direct_inverse_loop = partial(direct_inverse, implementation="loop")
""":func:`direct_inverse` with ``implementation='loop'``: the per-sample reference."""


def filtered_direct_inverse(
    accel: ArrayLike,
    pitch_rate: ArrayLike,
    dt: float,
    vehicle: VehicleParams,
    f_lo: float,
    f_hi: float,
    *,
    gamma: float = 0.6,
    beta: float = 0.3025,
    order: int = 4,
) -> DirectResult:
    """Direct integration made usable on real logs: band-pass first, then dissipative Newmark.

    The inputs are band-passed (zero-phase Butterworth, ``order``, ``[f_lo, f_hi]`` Hz) to
    remove bias, drift and the noise outside the band, and the recursion runs with a
    numerically dissipative ``gamma > 0.5`` (default 0.6, ``beta = (gamma + 0.5)² / 4``) so that
    its Nyquist mode decays. Levels still drift slowly (double integration); the caller
    band-passes the result again along chainage. Units as :func:`direct_inverse`.
    """
    from scipy.signal import butter, sosfiltfilt

    a, q = _check(accel, pitch_rate)
    if not (0 < f_lo < f_hi < 0.5 / dt):
        raise InversionError(f"band {f_lo}..{f_hi} Hz must lie between 0 and {0.5 / dt} Hz")
    sos = butter(order, [f_lo, f_hi], btype="band", fs=1.0 / dt, output="sos")
    af = sosfiltfilt(sos, a - a.mean())
    qf = sosfiltfilt(sos, q - q.mean())
    # the band-passed signals do not start from rest: fade them in over one longest period
    ramp_n = min(a.size // 4, int(1.0 / (f_lo * dt)))
    if ramp_n > 1:
        ramp = 0.5 - 0.5 * np.cos(np.linspace(0.0, np.pi, ramp_n))
        af[:ramp_n] *= ramp
        qf[:ramp_n] *= ramp
    return direct_inverse(af, qf, dt, vehicle, gamma=gamma, beta=beta)
