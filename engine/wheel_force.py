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

from .spectral import BINS_PER_BLOCK, FFT_WORKERS, BandSpectrum, dof_response
from .vehicle import VehicleModel


def force_response(vehicle: VehicleModel, omega: NDArray[np.float64]) -> NDArray[np.complex128]:
    """Dynamic contact force per unit rail level, N/m.

    ``G[k] @ [Y1, Y2] = [F1, F2]`` (shape (m, 2, 2), ``omega`` in rad/s): dynamic contact
    force of the front and rear measured point (the half car's axle, a bogie's two wheels
    together; N, compression positive) for unit rail level (m) under point 1 and point 2,
    from the DOF response :func:`engine.spectral.dof_response`: with ``F`` the kind's
    :meth:`~engine.vehicle.VehicleModel.axle_input`, ``G = diag(sum F) - F^T X``.
    """
    F = vehicle.axle_input()
    X = dof_response(vehicle, omega)
    G = -np.einsum("dj,mdk->mjk", F, X)
    G[:, 0, 0] += F[:, 0].sum()
    G[:, 1, 1] += F[:, 1].sum()
    return G


def dynamic_wheel_forces(
    y_front: NDArray[np.float64],
    y_rear: NDArray[np.float64],
    dt: float,
    vehicle: VehicleModel,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Dynamic part of each axle's contact force from the rail levels under the axles.

    Parameters
    ----------
    y_front, y_rear : ndarray
        Rail level under the front and rear axle at each sample, m, positive up (deviations;
        any constant offset is ignored).
    dt : float
        Sample step, s.
    vehicle : VehicleModel
        Any vehicle kind.
    Returns
    -------
    f_front, f_rear : ndarray
        Contact force minus the static axle load, N, compression positive.
    """
    n = y_front.size
    pad = min(n, 4096)
    nfft = sfft.next_fast_len(n + 2 * pad, real=True)

    y = np.stack([y_front, y_rear])
    buf = np.zeros((2, nfft))
    buf[:, pad : pad + n] = y - np.linspace(
        y[:, :64].mean(axis=1), y[:, -64:].mean(axis=1), n, axis=-1
    )
    Y1, Y2 = sfft.rfft(buf, axis=-1, workers=FFT_WORKERS)
    omega = 2 * np.pi * sfft.rfftfreq(nfft, dt)
    F = np.empty((2, omega.size), dtype=np.complex128)
    # block by block: the (m, 2, 2) response of a whole hour would be ~100 MB per temporary
    for k0 in range(0, omega.size, BINS_PER_BLOCK):
        blk = slice(k0, k0 + BINS_PER_BLOCK)
        G = force_response(vehicle, omega[blk])
        F[0, blk] = G[:, 0, 0] * Y1[blk] + G[:, 0, 1] * Y2[blk]
        F[1, blk] = G[:, 1, 0] * Y1[blk] + G[:, 1, 1] * Y2[blk]
    f1, f2 = sfft.irfft(F, nfft, axis=-1, workers=FFT_WORKERS)[:, pad : pad + n]
    return f1, f2


def force_spectrum(band: BandSpectrum, vehicle: VehicleModel) -> BandSpectrum:
    """Dynamic contact force of each axle (N; compression positive, the static load not
    included) as a band spectrum, from the rail levels' band spectrum (m) of the spectral
    inverse: the force response at the band's bins only, without transforming the levels
    again (the same forces as :func:`dynamic_wheel_forces` away from the log's first and
    last seconds, where the inverse's mirrored padding replaces zero padding)."""
    F = np.empty_like(band.values)
    for k0 in range(0, band.omega.size, BINS_PER_BLOCK):
        blk = slice(k0, k0 + BINS_PER_BLOCK)
        G = force_response(vehicle, band.omega[blk])
        F[:, blk] = np.einsum("mij,jm->im", G, band.values[:, blk])
    return band.with_values(F)
