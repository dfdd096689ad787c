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
DIRECTIONS = 180
"""Directions N = (cos phi, sin phi), phi in [0, pi), sampled before the parabolic refinement
around the best one: Q(N) is a trigonometric polynomial of degree 2 in phi, so its smallest
eigenvalue is smooth wherever it is simple, and a parabola through three samples 1 degree
apart finds its minimum to ~1e-8 of the tensor's scale."""


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


def _smallest_eigenvalue(Q: np.ndarray) -> np.ndarray:
    """Smallest eigenvalue of symmetric 2x2 matrices (..., 2, 2), in closed form."""
    a, b, d = Q[..., 0, 0], 0.5 * (Q[..., 0, 1] + Q[..., 1, 0]), Q[..., 1, 1]
    return 0.5 * (a + d) - np.hypot(0.5 * (a - d), b)


def smallest_acoustic_eigenvalue(
    Fe: np.ndarray, S: np.ndarray, C_voigt: np.ndarray, chunk: int = 4096
) -> tuple[np.ndarray, np.ndarray]:
    """The smallest eigenvalue of Q(N) over all unit directions N, per state, and the angle
    phi of that N (radians, in [0, pi)); (n,) each.

    Args:
        Fe: (n, 2, 2) elastic deformation (any rotation: only its stretch matters).
        S: (n, 2, 2) second Piola stress at that state (the pressure term included).
        C_voigt: (n, 3, 3) tangent ``dS/dE`` in Voigt storage (constant for St Venant-
            Kirchhoff laws and the homogenized ``S = E_hom Ee``).
        chunk: states per vectorised block (memory: chunk x DIRECTIONS x 4 floats).
    """
    step = np.pi / DIRECTIONS
    phi = np.arange(DIRECTIONS) * step
    out_value = np.empty(len(Fe))
    out_phi = np.empty(len(Fe))
    for start in range(0, len(Fe), chunk):
        part = slice(start, start + chunk)
        C4 = elasticity_tensor(C_voigt[part])

        def at(angles: np.ndarray, C4=C4, part=part) -> np.ndarray:  # (n, k) for angles (n, k)
            N = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
            return _smallest_eigenvalue(acoustic_tensor(Fe[part], S[part], C4, N))

        n = len(C4)
        grid = np.broadcast_to(phi, (n, DIRECTIONS))
        values = at(grid)
        best = np.argmin(values, axis=1)
        rows = np.arange(n)
        centre = phi[best]
        trio = at(np.stack([centre - step, centre, centre + step], axis=1))
        lo, mid, hi = trio.T
        curvature = lo - 2.0 * mid + hi
        with np.errstate(divide="ignore", invalid="ignore"):
            shift = np.where(curvature > 0.0, 0.5 * (lo - hi) / curvature, 0.0)
        refined = centre + np.clip(shift, -1.0, 1.0) * step
        value = at(refined[:, None])[:, 0]
        keep = value < values[rows, best]
        out_value[part] = np.where(keep, value, values[rows, best])
        out_phi[part] = np.mod(np.where(keep, refined, centre), np.pi)
    return out_value, out_phi


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
