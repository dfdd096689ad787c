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

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

VOIGT_INDEX = np.array([[0, 2], [2, 1]])
"""v(M, J): the Voigt row of the tensor index pair (M, J)."""
DIRECTIONS = 24
"""Directions N = (cos phi, sin phi), phi in [0, pi), sampled first (every 7.5 degrees)."""
BASINS = 2
"""The deepest local minima of the samples that are refined: an anisotropic tangent can have
two basins of nearly equal depth, and the samples' best may lie in the shallower one (measured
on 4,000 random states of homogenized honeycombs, grown and elongated cells and isotropic walls,
against a 20,000-direction sweep: up to 9e-3 of the shear modulus off with one basin refined,
exact to round-off with two: tests/test_stability.py)."""
REFINEMENTS = 10
SHRINK = 0.3
"""Each refinement takes the best of the current angle, its neighbours at +/- step and their
parabola's vertex, then shrinks the step by SHRINK: 10 of them take 7.5 degrees to 5e-5
degrees, the minimum to round-off (tests/test_stability.py)."""
_BASIS_MATRICES = np.array([np.eye(2), np.diag([1.0, -1.0]), [[0.0, 1.0], [1.0, 0.0]]])
"""I, J1, J2: ``2 N (x) N = I + cos(2 phi) J1 + sin(2 phi) J2`` for N = (cos phi, sin phi)."""


def _angle_basis(phi: np.ndarray) -> np.ndarray:
    """(3, ...) the rows 1, cos 2 phi, sin 2 phi."""
    return np.stack([np.ones_like(phi), np.cos(2.0 * phi), np.sin(2.0 * phi)])


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
    M = np.einsum("nmjpl,xjl->nxmp", C4, _BASIS_MATRICES)
    SX = np.einsum("njl,xjl->nx", S, _BASIS_MATRICES)
    Qx = Fe[:, None] @ M @ np.swapaxes(Fe, 1, 2)[:, None]
    Qx = 0.5 * (Qx + SX[..., None, None] * np.eye(2))
    # the eigenvalues of [[A, B], [B, D]] are mean -/+ sqrt(half^2 + B^2), each of mean, half
    # and B a combination of (1, cos 2 phi, sin 2 phi): one matrix product per angle set
    mean = 0.5 * (Qx[..., 0, 0] + Qx[..., 1, 1])
    half = 0.5 * (Qx[..., 0, 0] - Qx[..., 1, 1])
    B = 0.5 * (Qx[..., 0, 1] + Qx[..., 1, 0])

    def at(phi: np.ndarray) -> np.ndarray:  # (k,) angles for all states, or (n, k) each
        if phi.ndim == 1:
            basis = _angle_basis(phi)
            h, b = half @ basis, B @ basis
            return mean @ basis - np.sqrt(h * h + b * b)
        c, s = np.cos(2.0 * phi), np.sin(2.0 * phi)
        h, b, m = (x[:, :1] + c * x[:, 1:2] + s * x[:, 2:] for x in (half, B, mean))
        return m - np.sqrt(h * h + b * b)

    step = np.pi / DIRECTIONS
    grid = np.arange(DIRECTIONS) * step
    values = at(grid)
    # the BASINS deepest local minima of the periodic samples, each refined
    local = (values <= np.roll(values, 1, axis=1)) & (values <= np.roll(values, -1, axis=1))
    order = np.argsort(np.where(local, values, np.inf), axis=1)[:, :BASINS]
    phi = grid[order].reshape(-1)
    value = np.take_along_axis(values, order, axis=1).reshape(-1)
    mean, half, B = (np.repeat(x, BASINS, axis=0) for x in (mean, half, B))
    rows = np.arange(len(phi))
    for _ in range(REFINEMENTS):  # the best of phi, its neighbours and their parabola's vertex
        lo, hi = at(np.stack([phi - step, phi + step], axis=1)).T
        curvature = lo - 2.0 * value + hi
        with np.errstate(divide="ignore", invalid="ignore"):
            shift = np.where(curvature > 0.0, 0.5 * (lo - hi) / curvature, 0.0)
        vertex = phi + np.clip(shift, -1.0, 1.0) * step
        candidates = np.stack([phi, phi - step, phi + step, vertex], axis=1)
        found = np.column_stack([value, lo, hi, at(vertex[:, None])[:, 0]])
        best = np.argmin(found, axis=1)
        phi, value = candidates[rows, best], found[rows, best]
        step *= SHRINK
    value, phi = value.reshape(-1, BASINS), phi.reshape(-1, BASINS)
    best = np.argmin(value, axis=1)[:, None]
    value, phi = np.take_along_axis(value, best, 1)[:, 0], np.take_along_axis(phi, best, 1)[:, 0]
    return value, np.mod(phi, np.pi)


def isotropic_voigt(E, nu) -> np.ndarray:
    """(..., 3, 3) plane-stress St Venant-Kirchhoff tangents (walls, MODEL.md 1) in Voigt storage,
    for scalars or arrays of E and nu."""
    E, nu = np.broadcast_arrays(np.asarray(E, dtype=float), np.asarray(nu, dtype=float))
    lam, mu = E * nu / (1.0 - nu**2), E / (2.0 * (1.0 + nu))
    C = np.zeros((*E.shape, 3, 3))
    C[..., 0, 0] = C[..., 1, 1] = lam + 2.0 * mu
    C[..., 0, 1] = C[..., 1, 0] = lam
    C[..., 2, 2] = mu
    return C


def svk_stress(Fe: np.ndarray, C_voigt: np.ndarray) -> np.ndarray:
    """(n, 2, 2) ``S = C E`` with ``E = (Fe^T Fe - I) / 2``."""
    E = 0.5 * (np.swapaxes(Fe, 1, 2) @ Fe - np.eye(2))
    e = np.stack([E[:, 0, 0], E[:, 1, 1], 2.0 * E[:, 0, 1]], axis=1)
    s = np.einsum("nij,nj->ni", C_voigt, e)
    return np.stack([np.stack([s[:, 0], s[:, 2]], -1), np.stack([s[:, 2], s[:, 1]], -1)], axis=1)


def mean_shear_modulus(C_voigt: np.ndarray) -> np.ndarray:
    """(n,) ``(C1111 + C2222 - 2 C1122 + 4 C1212) / 8``: the shear modulus of the law's isotropic
    part (its mean over orientations; mu for isotropic walls), the scale of :func:`normalised`."""
    C = C_voigt
    return (C[:, 0, 0] + C[:, 1, 1] - 2.0 * C[:, 0, 1] + 4.0 * C[:, 2, 2]) / 8.0


def normalised(Fe: np.ndarray, S: np.ndarray, C_voigt: np.ndarray) -> np.ndarray:
    """(n,) the smallest acoustic eigenvalue over the mean shear modulus: 1 for unstressed
    isotropic walls, negative where the law has lost strong ellipticity."""
    return smallest_acoustic_eigenvalue(Fe, S, C_voigt)[0] / mean_shear_modulus(C_voigt)


def stretch_of_strain(eps: np.ndarray) -> np.ndarray:
    """(n, 2, 2) ``sqrt(I + 2 eps)``: the symmetric stretch whose Green-Lagrange strain is eps
    (how a linear run's elastic strain is judged by the finite law), in closed form for 2 x 2:
    ``sqrt(M) = (M + sqrt(det M) I) / sqrt(tr M + 2 sqrt(det M))``. A state where I + 2 eps is
    not positive definite has compressed a direction to nothing: far past any stability limit,
    it gets Fe = 0."""
    M = np.eye(2) + 2.0 * eps
    det, trace = np.linalg.det(M), M[:, 0, 0] + M[:, 1, 1]
    positive = (det > 0.0) & (trace > 0.0)  # both eigenvalues
    root_det = np.sqrt(np.where(positive, det, 1.0))
    scale = np.sqrt(np.where(positive, trace + 2.0 * root_det, 1.0))
    U = (M + root_det[:, None, None] * np.eye(2)) / scale[:, None, None]
    return np.where(positive[:, None, None], U, 0.0)


@dataclass(frozen=True)
class Ellipticity:
    """One step's stability check over the tissue.

    Attributes:
        nonelliptic_area_fraction: the area fraction (reference configuration) of the units
            (macro: fine cells; micro: wall triangles) where the law is not strongly elliptic.
        smallest: the smallest normalised acoustic eigenvalue (:func:`normalised`).
        place: (x1, x2), reference coordinates, where it is.
    """

    nonelliptic_area_fraction: float
    smallest: float
    place: tuple[float, float]

    def describe(self, t: float) -> str:
        """The first loss of ellipticity in a biologist's words."""
        x1, x2 = self.place
        return (
            f"the tissue is compressed beyond the point where its cell walls would buckle (loss "
            f"of ellipticity: smallest acoustic eigenvalue {self.smallest:.3g} times the shear "
            f"modulus, on {self.nonelliptic_area_fraction:.2%} of the tissue) at x1 = {x1:.4g}, "
            f"x2 = {x2:.4g}, t = {t:g}; results past this point are outside the model"
        )


def check(
    values: np.ndarray, nonelliptic: np.ndarray, areas: np.ndarray, points: np.ndarray, comm
) -> Ellipticity:
    """Collective: the :class:`Ellipticity` of this rank's units.

    Args:
        values: (n,) normalised smallest eigenvalue per sample point.
        nonelliptic: (m,) whether each unit has a sample below 0.
        areas: (m,) the units' reference areas.
        points: (n, 2) the sample points.
    """
    sums = comm.allreduce(np.array([areas[nonelliptic].sum(), areas.sum()]), op=MPI.SUM)
    i = int(np.argmin(values)) if len(values) else None
    mine = (float(values[i]), tuple(float(x) for x in points[i])) if i is not None else None
    smallest, place = min((x for x in comm.allgather(mine) if x is not None), key=lambda x: x[0])
    return Ellipticity(float(sums[0] / sums[1]) if sums[1] > 0 else 0.0, smallest, place)
