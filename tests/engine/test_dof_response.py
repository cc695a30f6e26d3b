"""The vehicle's frequency response summed over its modes equals the direct per-bin solve.

:func:`engine.spectral.dof_response` evaluates ``Z(w)^-1 E K_t`` as a sum over the eight
state-space modes (one eigen-decomposition) for speed on hour-long spectra; these tests pin it
to the definition — ``m`` independent 4x4 solves of ``Z = K + i w C - w^2 M`` — for the
registered vehicle, vehicles far from it (heavy, undamped, stiff contact, offset sensor), the
axles-only slice the wheel force uses, and the fallback taken for nearly defective modes.
"""

from __future__ import annotations

import numpy as np
import pytest

from engine import spectral
from engine.vehicle import HEAVY, VehicleParams

OMEGA = 2 * np.pi * np.concatenate([[0.0], np.logspace(-2, 2.5, 400)])  # rad/s, 0 to ~316 Hz

VEHICLES = {
    "table 1": VehicleParams(),
    "heavy": HEAVY,
    "undamped": VehicleParams(cs1=0.0, cs2=0.0),
    "stiff contact, long body": VehicleParams(kt1=1e9, kt2=2e9, d1=9.0, d2=7.5, ms=40000.0),
    "soft, heavily damped": VehicleParams(ks1=5e3, ks2=5e3, cs1=5e6, cs2=5e6),
}


def _direct(vehicle: VehicleParams, w: np.ndarray) -> np.ndarray:
    M, C, K = vehicle.matrices()
    F = np.zeros((4, 2))
    F[2, 0], F[3, 1] = vehicle.kt1, vehicle.kt2
    Z = -(w[:, None, None] ** 2) * M + 1j * w[:, None, None] * C + K
    return np.linalg.solve(Z, np.broadcast_to(F, (w.size, 4, 2)).astype(complex))


@pytest.mark.parametrize("name", list(VEHICLES))
def test_modal_sum_equals_the_per_bin_solve(name: str) -> None:
    vehicle = VEHICLES[name]
    want = _direct(vehicle, OMEGA)
    got = spectral.dof_response(vehicle, OMEGA)
    assert got.shape == (OMEGA.size, 4, 2)
    scale = np.abs(want).max(axis=0)  # per DOF and input: the response's own size
    assert np.all(np.abs(got - want) <= 1e-9 * scale), name
    # at w = 0 the body follows the rails statically: u_u = Y under each axle, exactly
    np.testing.assert_allclose(got[0, 2:, :].real, np.eye(2), atol=1e-9)


def test_a_dof_slice_returns_those_rows_only() -> None:
    full = spectral.dof_response(VEHICLES["table 1"], OMEGA)
    axles = spectral.dof_response(VEHICLES["table 1"], OMEGA, dofs=slice(2, 4))
    assert axles.shape == (OMEGA.size, 2, 2)
    np.testing.assert_allclose(axles, full[:, 2:4, :], rtol=1e-12, atol=1e-15)


def test_nearly_defective_modes_fall_back_to_the_per_bin_solve(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    calls: list[int] = []
    real = spectral._solve_by_bin

    def spy(*args: object) -> np.ndarray:
        calls.append(1)
        return real(*args)  # type: ignore[arg-type]

    monkeypatch.setattr(spectral, "_solve_by_bin", spy)
    vehicle = VEHICLES["heavy"]
    modal = spectral.dof_response(vehicle, OMEGA)
    assert not calls  # a well-conditioned vehicle takes the modal sum
    monkeypatch.setattr(spectral, "MODAL_COND_MAX", 0.0)  # every vehicle counts as defective
    fallback = spectral.dof_response(vehicle, OMEGA, dofs=slice(2, 4))
    assert calls == [1]
    np.testing.assert_allclose(fallback, _direct(vehicle, OMEGA)[:, 2:4, :], rtol=0, atol=0)
    np.testing.assert_allclose(fallback, modal[:, 2:4, :], rtol=1e-8, atol=1e-12)
