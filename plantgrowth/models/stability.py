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

from plantgrowth.base.tensors import det2, smallest_eigenvalue_sym3
from plantgrowth.models import nonelliptic_sets
from plantgrowth.models.nonelliptic_sets import NonellipticSet

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
NEWTON_STEPS = 5
"""Refinement steps of each basin (:func:`_newton_minimum`)."""
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

    grid = np.arange(DIRECTIONS) * (np.pi / DIRECTIONS)
    basis = _angle_basis(grid)
    h, b = half @ basis, B @ basis
    values = mean @ basis - np.sqrt(h * h + b * b)
    # the BASINS deepest local minima of the periodic samples, each refined
    local = (values <= np.roll(values, 1, axis=1)) & (values <= np.roll(values, -1, axis=1))
    order = np.argsort(np.where(local, values, np.inf), axis=1)[:, :BASINS]
    coefficients = [np.repeat(x, BASINS, axis=0) for x in (mean, half, B)]
    theta, value = _newton_minimum(
        coefficients, 2.0 * grid[order].reshape(-1),
        np.take_along_axis(values, order, axis=1).reshape(-1), 2.0 * np.pi / DIRECTIONS,
    )  # fmt: skip
    value, theta = value.reshape(-1, BASINS), theta.reshape(-1, BASINS)
    best = np.argmin(value, axis=1)[:, None]
    value = np.take_along_axis(value, best, axis=1)[:, 0]
    phi = 0.5 * np.take_along_axis(theta, best, axis=1)[:, 0]
    return value, np.mod(phi, np.pi)


def _newton_minimum(
    coefficients: list[np.ndarray], theta: np.ndarray, value: np.ndarray, span: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray]:
    """Safeguarded Newton iterations on ``lambda(theta) = m - sqrt(h^2 + b^2)``, each of m, h, b
    ``x0 + x1 cos theta + x2 sin theta`` (coefficients: three (k, 3) arrays), from the sampled
    ``theta`` with its ``value``: a step is ``-lambda' / lambda''`` (downhill by ``span`` where
    lambda'' <= 0), at most ``span``, kept only if lambda decreases, else the span halves.
    Quadratic convergence: NEWTON_STEPS reach round-off from a sample 15 degrees (in theta)
    from the minimum. Returns the refined (theta, value)."""
    (m0, m1, m2), (h0, h1, h2), (b0, b1, b2) = (x.T for x in coefficients)
    span = np.full_like(theta, span)

    def at(t: np.ndarray) -> np.ndarray:
        c, s = np.cos(t), np.sin(t)
        return m0 + m1 * c + m2 * s - np.hypot(h0 + h1 * c + h2 * s, b0 + b1 * c + b2 * s)

    for _ in range(NEWTON_STEPS):
        c, s = np.cos(theta), np.sin(theta)
        h, b = h0 + h1 * c + h2 * s, b0 + b1 * c + b2 * s
        dm, dh, db = m2 * c - m1 * s, h2 * c - h1 * s, b2 * c - b1 * s
        r = np.maximum(np.hypot(h, b), 1e-300)
        g = h * dh + b * db
        # At a double root (r ~ 0) lambda is not smooth: d2 is then inf or NaN, which fails
        # d2 > 0 and falls back to the downhill step of length span.
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            d1 = dm - g / r  # lambda'; x'' = x0 - x for each of m, h, b
            curvature = dh**2 + db**2 - h * (h - h0) - b * (b - b0)
            d2 = -(m1 * c + m2 * s) - curvature / r + g**2 / r**3
            step = np.where(d2 > 0.0, -d1 / d2, -np.sign(d1) * span)
        trial = theta + np.clip(step, -span, span)
        found = at(trial)
        better = found < value
        theta, value = np.where(better, trial, theta), np.where(better, found, value)
        span = np.where(better, span, 0.5 * span)
    return theta, value


def isotropic_voigt(E, nu) -> np.ndarray:
    """(..., 3, 3) plane-stress St Venant-Kirchhoff tangents (walls, docs/model.md section 1) in
    Voigt storage, for scalars or arrays of E and nu."""
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


def normalised(
    Fe: np.ndarray, S: np.ndarray, C_voigt: np.ndarray, screened: bool = False
) -> np.ndarray:
    """(n,) the smallest acoustic eigenvalue over the mean shear modulus: 1 for unstressed
    isotropic walls, negative where the law has lost strong ellipticity. ``screened``: where
    :func:`lower_bound` is positive (the state is certainly elliptic) its value is that bound,
    not the minimum; the sign is exact everywhere (what the run's checks need)."""
    mu = mean_shear_modulus(C_voigt)
    if not screened:
        return smallest_acoustic_eigenvalue(Fe, S, C_voigt)[0] / mu
    out = lower_bound(Fe, S, C_voigt)
    todo = out <= 0.0
    out[todo] = smallest_acoustic_eigenvalue(Fe[todo], S[todo], C_voigt[todo])[0]
    return out / mu


def lower_bound(Fe: np.ndarray, S: np.ndarray, C_voigt: np.ndarray) -> np.ndarray:
    """(n,) ``lambda_min(S) + sigma_min(Fe)^2 lambda_min(C_voigt) / 2``, at most the smallest
    acoustic eigenvalue (where C_voigt is positive definite; -inf elsewhere): ``N . S N >=
    lambda_min(S)``, and with ``w = Fe^T v``, ``|w| >= sigma_min(Fe)``, ``w . M(N) w = e . C e >=
    lambda_min(C) |e|^2 >= lambda_min(C) |sym(w (x) N)|^2 >= lambda_min(C) |w|^2 / 2`` (e the
    Voigt vector of sym(w (x) N) with engineering shear). A cheap certificate of ellipticity:
    where it is positive, no direction needs sweeping."""
    C_min = smallest_eigenvalue_sym3(C_voigt)
    FtF = np.swapaxes(Fe, 1, 2) @ Fe
    bound = _smallest_symmetric2(S) + _smallest_symmetric2(FtF) * 0.5 * C_min
    return np.where(C_min > 0.0, bound, -np.inf)


def _smallest_symmetric2(A: np.ndarray) -> np.ndarray:
    """(n,) the smaller eigenvalue of symmetric (n, 2, 2) matrices."""
    half = 0.5 * (A[:, 0, 0] - A[:, 1, 1])
    return 0.5 * (A[:, 0, 0] + A[:, 1, 1]) - np.hypot(half, 0.5 * (A[:, 0, 1] + A[:, 1, 0]))


def stretch_of_strain(eps: np.ndarray) -> np.ndarray:
    """(n, 2, 2) ``sqrt(I + 2 eps)``: the symmetric stretch whose Green-Lagrange strain is eps
    (how a linear run's elastic strain is judged by the finite law), in closed form for 2 x 2:
    ``sqrt(M) = (M + sqrt(det M) I) / sqrt(tr M + 2 sqrt(det M))``. A state where I + 2 eps is
    not positive definite has compressed a direction to nothing: far past any stability limit,
    it gets Fe = 0."""
    M = np.eye(2) + 2.0 * eps
    det, trace = det2(M), M[:, 0, 0] + M[:, 1, 1]
    positive = (det > 0.0) & (trace > 0.0)  # both eigenvalues
    root_det = np.sqrt(np.where(positive, det, 1.0))
    scale = np.sqrt(np.where(positive, trace + 2.0 * root_det, 1.0))
    U = (M + root_det[:, None, None] * np.eye(2)) / scale[:, None, None]
    return np.where(positive[:, None, None], U, 0.0)


@dataclass(frozen=True)
class Ellipticity:
    """One step's stability check over the tissue, with the resolution rule
    (plantgrowth.models.nonelliptic_sets).

    Attributes:
        nonelliptic_area_fraction: the area fraction (reference configuration) of the connected
            non-elliptic sets larger than one cell (macro: of fine cells; micro: of wall
            triangles, where every set counts): where the model loses stability.
        singular_area_fraction: that of the sets within one cell (singular points).
        smallest: the smallest normalised acoustic eigenvalue (:func:`normalised`; where the
            whole tissue is elliptic, the smallest of the screened values, a lower bound).
        place: (x1, x2), reference coordinates, where it is.
        extended: the sets larger than one cell, largest first.
        singular: the sets within one cell (singular points), largest first.
        remedy: what the user can change, appended to :meth:`describe` ("": nothing said).
    """

    nonelliptic_area_fraction: float
    singular_area_fraction: float
    smallest: float
    place: tuple[float, float]
    extended: tuple[NonellipticSet, ...] = ()
    singular: tuple[NonellipticSet, ...] = ()
    remedy: str = ""

    @property
    def lost(self) -> bool:
        """True where a non-elliptic set is larger than one cell: the model loses stability."""
        return len(self.extended) > 0

    def describe(self, t: float) -> str:
        """The loss of stability (the largest set) in a biologist's words: "compressed" only
        where the walls' stress has a compressive principal value."""
        worst = self.extended[0]
        size = (
            f"{worst.cells:.3g} cells" if np.isfinite(worst.cells) else "the walls of the tissue"
        )
        lost = (
            f"(loss of ellipticity: smallest acoustic eigenvalue {worst.smallest:.3g} times the "
            f"shear modulus, on {self.nonelliptic_area_fraction:.2%} of the tissue, the largest "
            f"connected set {size}) at {worst.where()}, t = {t:g}; results past this point are "
            "outside the model" + (f"; {self.remedy}" if self.remedy else "")
        )
        values, angle = principal_stresses(worst.stress)
        if values[0] < 0.0:
            return (
                f"the cell walls are compressed (principal stress {values[0]:.3g} along "
                f"{angle:.0f} degrees from x1, in the units of E) beyond the point where they "
                f"would buckle {lost}"
            )
        return (
            f"the walls are in tension there (principal stresses {values[0]:.3g} and "
            f"{values[1]:.3g}), but the honeycomb has lost its stiffness against a shear band: "
            "its cells are too distorted (grown or stretched much more along one direction than "
            "the other) to keep their shape; lower the growth anisotropy (eta, tau, Fg0, cell "
            f"shape) or the loads there {lost}"
        )


def principal_stresses(S: np.ndarray) -> tuple[np.ndarray, float]:
    """((2,) the principal values of a symmetric 2 x 2 stress, ascending; the angle of the
    smaller one's direction, whole degrees from x1 in [0, 180))."""
    values, vectors = np.linalg.eigh(0.5 * (S + S.T))
    return values, round(float(np.degrees(np.arctan2(vectors[1, 0], vectors[0, 0])))) % 180


def check(
    values: np.ndarray,
    areas: np.ndarray,
    points: np.ndarray,
    comm,
    stress: np.ndarray,
    vertices: np.ndarray | None = None,
    grown: np.ndarray | None = None,
    cell_areas: np.ndarray | None = None,
) -> Ellipticity:
    """Collective: the :class:`Ellipticity` of this rank's units.

    Args:
        values: (m,) each unit's smallest normalised eigenvalue (negative: non-elliptic).
        areas: (m,) the units' reference areas.
        points: (m, 2) the place of each unit's smallest value.
        stress: (m, 2, 2) the walls' stress there.
        vertices: (m, k) global mesh-vertex indices per unit (None: the non-elliptic units
            form one set).
        grown: (m,) grown areas ``Jg A`` (None: the reference areas).
        cell_areas: (m,) a cell's grown area ``Jg |Y|`` at each unit (None: 0, every set is
            larger than a cell).
    """
    bad = values < 0.0
    grown = areas if grown is None else grown
    cell_areas = np.zeros_like(areas) if cell_areas is None else cell_areas
    mine = [x[bad] for x in (values, areas, grown, cell_areas, points, stress)]
    mine.append(None if vertices is None else vertices[bad])
    gathered = comm.gather(mine, root=0)
    total = comm.allreduce(float(areas.sum()), op=MPI.SUM)
    found = None
    if comm.rank == 0:
        v, a, g, c, p, S = (np.concatenate([x[k] for x in gathered]) for k in range(6))
        vx = None if vertices is None else np.concatenate([x[6] for x in gathered])
        found = nonelliptic_sets.sets_of(v, vx, a, g, c, p.reshape(-1, 2), S.reshape(-1, 2, 2))
    found = comm.bcast(found, root=0)
    i = int(np.argmin(values)) if len(values) else None
    here = (float(values[i]), tuple(float(x) for x in points[i])) if i is not None else None
    smallest, place = min((x for x in comm.allgather(here) if x is not None), key=lambda x: x[0])
    singular = tuple(s for s in found if s.singular)
    extended = tuple(s for s in found if not s.singular)

    def fraction(sets) -> float:
        return sum(s.reference_area for s in sets) / total if total > 0 else 0.0

    return Ellipticity(
        fraction(extended), fraction(singular), smallest, place, extended, singular
    )
