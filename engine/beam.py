"""Finite-element model of the rail: Hermite Euler-Bernoulli beam elements on discrete supports.

One element per support spacing; each node (a support) has two DOFs, deflection ``w`` (m,
positive up) and rotation ``phi`` (rad), ordered ``[w_0, phi_0, w_1, phi_1, ...]``. Matrices
are kept in LAPACK upper banded storage (3 super-diagonals), so that the track can be
factorised once and solved in O(n) per step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from .track import Track

BANDWIDTH = 3
"""Number of super-diagonals of the assembled rail matrices."""


def element_matrices(
    EI: float, mass_per_m: float, length: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Stiffness and consistent mass matrices of one Hermite beam element.

    Parameters
    ----------
    EI : float
        Bending stiffness, N m².
    mass_per_m : float
        Mass per unit length, kg/m.
    length : float
        Element length, m.

    Returns
    -------
    Ke, Me : ndarray, shape (4, 4)
        For the DOFs ``[w_a (m), phi_a (rad), w_b (m), phi_b (rad)]``.
    """
    L = length
    Ke = (EI / L**3) * np.array(
        [
            [12.0, 6 * L, -12.0, 6 * L],
            [6 * L, 4 * L**2, -6 * L, 2 * L**2],
            [-12.0, -6 * L, 12.0, -6 * L],
            [6 * L, 2 * L**2, -6 * L, 4 * L**2],
        ]
    )
    Me = (mass_per_m * L / 420.0) * np.array(
        [
            [156.0, 22 * L, 54.0, -13 * L],
            [22 * L, 4 * L**2, 13 * L, -3 * L**2],
            [54.0, 13 * L, 156.0, -22 * L],
            [-13 * L, -3 * L**2, -22 * L, 4 * L**2],
        ]
    )
    return Ke, Me


def hermite_shape(xi: NDArray[np.float64], length: float) -> NDArray[np.float64]:
    """Hermite shape functions at local coordinates ``xi`` in [0, 1] of an element.

    Returns an array of shape ``xi.shape + (4,)``; the deflection at ``xi`` is
    ``N @ [w_a, phi_a, w_b, phi_b]``.
    """
    x = np.asarray(xi, dtype=float)
    x2 = x * x
    x3 = x2 * x
    return np.stack(
        [1 - 3 * x2 + 2 * x3, length * (x - 2 * x2 + x3), 3 * x2 - 2 * x3, length * (x3 - x2)],
        axis=-1,
    )


@dataclass(frozen=True)
class RailMatrices:
    """Assembled rail matrices in upper banded storage, shape ``(4, n_dof)``.

    ``band[BANDWIDTH + i - j, j] = A[i, j]`` for ``i <= j`` (LAPACK ``'U'`` layout).
    Supports add their stiffness and damping to the deflection DOFs.
    """

    K: NDArray[np.float64]
    M: NDArray[np.float64]
    C: NDArray[np.float64]
    n_nodes: int
    spacing: float

    @property
    def n_dof(self) -> int:
        """Number of rail DOFs (two per node)."""
        return 2 * self.n_nodes

    def locate(self, x: NDArray[np.float64]) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
        """Element index and shape-function values at chainages ``x`` (m).

        Returns
        -------
        first_dof : ndarray of int
            Index of the first DOF of the element containing each ``x``.
        shape : ndarray, shape ``x.shape + (4,)``
            Hermite shape functions there.
        """
        xa = np.asarray(x, dtype=float)
        e = np.clip(np.floor(xa / self.spacing).astype(np.intp), 0, self.n_nodes - 2)
        xi = xa / self.spacing - e
        return 2 * e, hermite_shape(xi, self.spacing)

    def to_sparse(self, band: NDArray[np.float64]) -> sp.csr_matrix:
        """Full symmetric sparse matrix from an upper banded array."""
        n = self.n_dof
        diags = [band[BANDWIDTH - d, d:] for d in range(BANDWIDTH + 1)]
        upper = sp.diags(diags, list(range(BANDWIDTH + 1)), shape=(n, n), format="csr")
        strict = sp.diags(diags[1:], list(range(1, BANDWIDTH + 1)), shape=(n, n), format="csr")
        return (upper + strict.T).tocsr()


def assemble_rail(track: Track) -> RailMatrices:
    """Assemble the rail's stiffness, mass and damping matrices (banded) for a track.

    Parameters
    ----------
    track : Track
        Track geometry, rail properties and per-support stiffness (N/m) and damping (N s/m).

    Returns
    -------
    RailMatrices
        Banded ``K`` (N/m, N, N m), ``M`` (kg, kg m, kg m²) and ``C`` (N s/m).
    """
    p = track.params
    n_nodes = track.n_supports
    n = 2 * n_nodes
    Ke, Me = element_matrices(p.EI, p.mass_per_m, p.spacing)
    K = np.zeros((BANDWIDTH + 1, n))
    M = np.zeros((BANDWIDTH + 1, n))
    for a in range(4):
        for b in range(a, 4):
            # element e contributes Ke[a, b] at (2e + a, 2e + b); upper band row BANDWIDTH + a - b
            cols = 2 * np.arange(n_nodes - 1) + b
            K[BANDWIDTH + a - b, cols] += Ke[a, b]
            M[BANDWIDTH + a - b, cols] += Me[a, b]
    K[BANDWIDTH, 0::2] += track.k
    C = np.zeros((BANDWIDTH + 1, n))
    C[BANDWIDTH, 0::2] = p.c_support
    return RailMatrices(K=K, M=M, C=C, n_nodes=n_nodes, spacing=p.spacing)
