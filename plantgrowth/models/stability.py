"""Where the material law stops being stable: loss of strong ellipticity (issue 20, item 2).

For a hyperelastic law ``S(E)`` (second Piola stress of the Green-Lagrange strain, in the
grown, intermediate configuration) the first Piola stress is ``P = Fe S`` and its tangent
``A_iJkL = dP_iJ / dFe_kL = delta_ik S_JL + Fe_iM C_MJPL Fe_kP`` with ``C = dS/dE``. The law is
strongly elliptic at a state where the acoustic tensor

    Q(N)_ik = A_iJkL N_J N_L = (N . S N) delta_ik + Fe M(N) Fe^T,   M(N)_MP = C_MJPL N_J N_L

is positive definite for every unit direction N; where its smallest eigenvalue, minimised over
N, turns negative, the equations admit a discontinuous deformation gradient (a localisation,
the continuum's picture of walls that buckle) and the model's solution is no longer unique.
A rotation ``Fe -> R Fe`` rotates Q (``R Q R^T``), so only the stretch matters: a linear run
is judged with ``Fe = sqrt(I + 2 eps_el)``, the finite tangent at ``Ee = eps_el``.

Elasticity tensors come in the paper's Voigt storage with engineering shear
(``S = C [E11, E22, 2 E12]``), so ``C_MJPL = C_voigt[v(M, J), v(P, L)]`` with v(1,1) = 0,
v(2,2) = 1, v(1,2) = v(2,1) = 2.
"""

from __future__ import annotations

import numpy as np

VOIGT_INDEX = np.array([[0, 2], [2, 1]])
"""v(M, J): the Voigt row of the tensor index pair (M, J)."""
DIRECTIONS = 90
"""Directions N = (cos phi, sin phi), phi in [0, pi), sampled before the parabolic refinement
around the best one: Q(N) is a trigonometric polynomial of degree 1 in 2 phi, so its smallest
eigenvalue is smooth wherever it is simple, and a parabola through three samples 2 degrees
apart, then one 8 times closer (REFINEMENTS), find its minimum to ~1e-10 of the tensor's
scale (tests/test_stability.py)."""
REFINEMENTS = 2


def elasticity_tensor(C_voigt: np.ndarray) -> np.ndarray:
    """(n, 2, 2, 2, 2) ``C_MJPL`` from (n, 3, 3) Voigt matrices (engineering shear)."""
    v = VOIGT_INDEX
    return C_voigt[:, v[:, :, None, None], v[None, None, :, :]]


def acoustic_tensor(Fe: np.ndarray, S: np.ndarray, C4: np.ndarray, N: np.ndarray) -> np.ndarray:
    """(n, k, 2, 2) ``Q(N)`` for (n, 2, 2) Fe and S, (n, 2, 2, 2, 2) C and (n, k, 2) unit
    directions."""
    M = np.einsum("nmjpl,nkj,nkl->nkmp", C4, N, N)
    NSN = np.einsum("njl,nkj,nkl->nk", S, N, N)
    return NSN[..., None, None] * np.eye(2) + np.einsum("nim,nkmp,njp->nkij", Fe, M, Fe)


def smallest_acoustic_eigenvalue(
    Fe: np.ndarray, S: np.ndarray, C_voigt: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The smallest eigenvalue of Q(N) over all unit directions N, per state, and the angle
    phi of that N (radians, in [0, pi)); (n,) each.

    Q is linear in ``N (x) N = (I + cos(2 phi) J1 + sin(2 phi) J2) / 2`` (J1 = diag(1, -1),
    J2 the symmetric swap), so ``Q(phi) = (Q[I] + cos(2 phi) Q[J1] + sin(2 phi) Q[J2]) / 2``:
    three 2x2 matrices per state, then only elementwise arithmetic on the angle grid.

    Args:
        Fe: (n, 2, 2) elastic deformation (any rotation: only its stretch matters).
        S: (n, 2, 2) second Piola stress at that state (the pressure term included).
        C_voigt: (n, 3, 3) tangent ``dS/dE`` in Voigt storage (constant for St Venant-
            Kirchhoff laws and the homogenized ``S = E_hom Ee``).
    """
    C4 = elasticity_tensor(C_voigt)
    X = np.array([np.eye(2), np.diag([1.0, -1.0]), np.array([[0.0, 1.0], [1.0, 0.0]])])
    M = np.einsum("nmjpl,xjl->nxmp", C4, X)
    SX = np.einsum("njl,xjl->nx", S, X)
    Qx = 0.5 * (SX[..., None, None] * np.eye(2) + np.einsum("nim,nxmp,njp->nxij", Fe, M, Fe))

    a, b, d = Qx[..., 0, 0], 0.5 * (Qx[..., 0, 1] + Qx[..., 1, 0]), Qx[..., 1, 1]  # (n, 3)

    def at(c: np.ndarray, s: np.ndarray) -> np.ndarray:  # cos, sin of 2 phi -> eigenvalues
        A = a[:, :1] + c * a[:, 1:2] + s * a[:, 2:]
        B = b[:, :1] + c * b[:, 1:2] + s * b[:, 2:]
        D = d[:, :1] + c * d[:, 1:2] + s * d[:, 2:]
        half = 0.5 * (A - D)
        return 0.5 * (A + D) - np.sqrt(half * half + B * B)

    def at_angles(phi: np.ndarray) -> np.ndarray:
        return at(np.cos(2.0 * phi), np.sin(2.0 * phi))

    step = np.pi / DIRECTIONS
    grid = np.arange(DIRECTIONS) * step
    values = at(np.cos(2.0 * grid), np.sin(2.0 * grid))
    rows = np.arange(len(Fe))
    best = np.argmin(values, axis=1)
    phi, value = grid[best], values[rows, best]
    for _ in range(REFINEMENTS):  # a parabola through phi and its neighbours, then closer
        lo, hi = at_angles(np.stack([phi - step, phi + step], axis=1)).T
        curvature = lo - 2.0 * value + hi
        with np.errstate(divide="ignore", invalid="ignore"):
            shift = np.where(curvature > 0.0, 0.5 * (lo - hi) / curvature, 0.0)
        trial = phi + np.clip(shift, -1.0, 1.0) * step
        at_trial = at_angles(trial[:, None])[:, 0]
        better = at_trial < value
        phi, value = np.where(better, trial, phi), np.where(better, at_trial, value)
        step /= 8.0
    return value, np.mod(phi, np.pi)


def isotropic_voigt(E: float, nu: float) -> np.ndarray:
    """(3, 3) plane-stress St Venant-Kirchhoff tangent (walls, MODEL.md 1) in Voigt storage."""
    lam, mu = E * nu / (1.0 - nu**2), E / (2.0 * (1.0 + nu))
    return np.array([[lam + 2 * mu, lam, 0.0], [lam, lam + 2 * mu, 0.0], [0.0, 0.0, mu]])


def svk_stress(Fe: np.ndarray, C_voigt: np.ndarray) -> np.ndarray:
    """(n, 2, 2) ``S = C E`` with ``E = (Fe^T Fe - I) / 2``."""
    E = 0.5 * (np.swapaxes(Fe, 1, 2) @ Fe - np.eye(2))
    e = np.stack([E[:, 0, 0], E[:, 1, 1], 2.0 * E[:, 0, 1]], axis=1)
    s = np.einsum("nij,nj->ni", C_voigt, e)
    return np.stack([np.stack([s[:, 0], s[:, 2]], -1), np.stack([s[:, 2], s[:, 1]], -1)], axis=1)
