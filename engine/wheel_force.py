"""Wheel-rail contact force of each axle from the recovered rail levels and the vehicle model.

The half-car is linear: once the inversion has the rail level under each axle, ``y1(t)`` and
``y2(t)``, the vehicle's own equations give every DOF, in particular the axle displacements
``u_u1``, ``u_u2``; the contact spring then carries ``F_i = P_i + k_ti (y_i - u_ui)``
(compression positive, ``P_i`` the static axle load, deviations from the static state). In
the frequency domain ``Z(w) X = E K_t Y`` with ``Z = K_v + i w C_v - w² M_v``, so the dynamic
force per unit level is ``k_ti (delta_ij - (Z⁻¹ E K_t)_{2+i, j})``: zero at ``w = 0`` (a
uniform lift moves the whole vehicle rigidly), the static load being added separately.
"""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft
from numpy.typing import NDArray

from .spectral import dof_response
from .vehicle import VehicleParams


def force_response(vehicle: VehicleParams, omega: NDArray[np.float64]) -> NDArray[np.complex128]:
    """Dynamic contact force per unit rail level, N/m.

    ``G[k] @ [Y1, Y2] = [F1, F2]`` (shape (m, 2, 2), ``omega`` in rad/s): dynamic contact
    force of the front and rear axle (N, compression positive) for unit rail level (m) under
    axle 1 and axle 2, from the DOF response :func:`engine.spectral.dof_response`.
    """
    X = dof_response(vehicle, omega, slice(2, 4))  # the axles only
    kt = np.array([vehicle.kt1, vehicle.kt2])
    G = -kt[None, :, None] * X
    G[:, 0, 0] += kt[0]
    G[:, 1, 1] += kt[1]
    return G


def dynamic_wheel_forces(
    y_front: NDArray[np.float64],
    y_rear: NDArray[np.float64],
    dt: float,
    vehicle: VehicleParams,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Dynamic part of each axle's contact force from the rail levels under the axles.

    Parameters
    ----------
    y_front, y_rear : ndarray
        Rail level under the front and rear axle at each sample, m, positive up (deviations;
        any constant offset is ignored).
    dt : float
        Sample step, s.
    vehicle : VehicleParams
        The half-car.

    Returns
    -------
    f_front, f_rear : ndarray
        Contact force minus the static axle load, N, compression positive.
    """
    n = y_front.size
    pad = min(n, 4096)
    nfft = sfft.next_fast_len(n + 2 * pad, real=True)

    def spectrum(y: NDArray[np.float64]) -> NDArray[np.complex128]:
        yy = y - np.linspace(y[:64].mean(), y[-64:].mean(), n)
        buf = np.zeros(nfft)
        buf[pad : pad + n] = yy
        return sfft.rfft(buf)

    Y = np.stack([spectrum(y_front), spectrum(y_rear)], axis=-1)  # (m, 2)
    G = force_response(vehicle, 2 * np.pi * sfft.rfftfreq(nfft, dt))
    Fw = np.einsum("kij,kj->ki", G, Y)
    f1 = sfft.irfft(Fw[:, 0], nfft)[pad : pad + n]
    f2 = sfft.irfft(Fw[:, 1], nfft)[pad : pad + n]
    return f1, f2
