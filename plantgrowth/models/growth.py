"""Growth law and time integration, vectorised over fine-mesh cells (docs/model.md section 4).

[G_stress]  G~ = eta [ sigma_hom / phi_w - tau I ]_+
[G_strain]  G~ = eta [ eps_hom   / phi_w - tau I ]_+
[def_G_11]  G  = clip(G~, -M, M) component-wise
[macro_growth_eq]  dFg/dt = G Fg
All arrays carry the cell index first: tensors are (n, 2, 2).
"""

from __future__ import annotations

import numpy as np

from plantgrowth.base.tensors import from_voigt_stress, inv2, voigt_matrix, voigt_vector

INTEGRATORS = ("euler", "exp")


def _spectral(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Symmetric (n, 2, 2) ``A = m I + D``: the mean eigenvalue m, the deviator D (trace 0)
    and its eigenvalue r >= 0 (A's eigenvalues are ``m -/+ r``), each (n,) or (n, 2, 2)."""
    m = 0.5 * (A[:, 0, 0] + A[:, 1, 1])
    D = A - m[:, None, None] * np.eye(2)
    return m, D, np.hypot(D[:, 0, 0], 0.5 * (A[:, 0, 1] + A[:, 1, 0]))


def positive_part(A: np.ndarray) -> np.ndarray:
    """``A_+``: the tensor rebuilt from the positive parts of the eigenvalues, in closed form
    for symmetric (n, 2, 2) A: A where both are >= 0, 0 where both are <= 0, else
    ``lam_1 (A - lam_2 I) / (lam_1 - lam_2)`` (lam_1 > 0 > lam_2: no cancellation)."""
    m, _, r = _spectral(A)
    high, low = m + r, m - r
    mixed = (high > 0.0) & (low < 0.0)
    weight = np.where(mixed, high / np.where(mixed, high - low, 1.0), 0.0)
    shift = np.where(mixed, low, 0.0)
    out = weight[:, None, None] * (A - shift[:, None, None] * np.eye(2))
    return np.where((low >= 0.0)[:, None, None], A, out)


def exp_symmetric(A: np.ndarray, dt: float) -> np.ndarray:
    """``expm(dt A)`` of symmetric (n, 2, 2) A, in closed form: with ``A = m I + D``, ``D^2 =
    r^2 I``, ``expm(dt A) = e^(dt m) (cosh(dt r) I + sinh(dt r) / r D)``."""
    m, D, r = _spectral(A)
    x = dt * r
    small = x < 1e-8  # sinh(x) / x = 1 + x^2 / 6 + ...: 1 to round-off
    sinhc = np.where(small, 1.0, np.sinh(x) / np.where(small, 1.0, x))
    out = np.cosh(x)[:, None, None] * np.eye(2) + (dt * sinhc)[:, None, None] * D
    return np.exp(dt * m)[:, None, None] * out


def elastic_strain(grad_u: np.ndarray, Fg: np.ndarray) -> np.ndarray:
    """``eps_el = sym(grad(u) Fg^{-1}) + sym(Fg^{-1}) - I``."""
    Finv = inv2(Fg)
    A = grad_u @ Finv + Finv
    return 0.5 * (A + np.swapaxes(A, 1, 2)) - np.eye(2)


def green_lagrange_strain(grad_u: np.ndarray, Fg: np.ndarray) -> np.ndarray:
    """``Ee = (Fe^T Fe - I) / 2`` with ``Fe = (I + grad u) Fg^{-1}`` (docs/model.md section 10)."""
    Fe = (np.eye(2) + grad_u) @ inv2(Fg)
    return 0.5 * (np.swapaxes(Fe, 1, 2) @ Fe - np.eye(2))


def homogenized_stress(C: np.ndarray, eps_el: np.ndarray, K: np.ndarray | None, P1: np.ndarray):
    """[sigma_hom]: ``E_hom eps_el + K_hom P1`` (C is the 3x3 Voigt form of E_hom)."""
    sigma = from_voigt_stress(np.einsum("nij,nj->ni", C, voigt_vector(eps_el)))
    return sigma if K is None else sigma + K * P1[:, None, None]


def homogenized_strain(
    eps_el: np.ndarray,
    phi_w: np.ndarray,
    dbar_w: np.ndarray,
    dbar_v: np.ndarray | None,
    P1: np.ndarray,
) -> np.ndarray:
    """[strain_hom]: ``phi_w eps_el + sum_ij eps_el_ij dbar[w^ij] + P1 dbar[v]``."""
    eps = phi_w[:, None, None] * eps_el + np.einsum("nij,nijkl->nkl", eps_el, dbar_w)
    return eps if dbar_v is None else eps + P1[:, None, None] * dbar_v


def growth_rate(
    X: np.ndarray, phi_w: np.ndarray, eta: np.ndarray, tau: np.ndarray, clamp: float
) -> np.ndarray:
    """``G = clip(eta [X / phi_w - tau I]_+, -M, M)`` for X = sigma_hom or eps_hom."""
    driving = X / phi_w[:, None, None] - tau[:, None, None] * np.eye(2)
    return np.clip(eta[:, None, None] * positive_part(driving), -clamp, clamp)


def homogeneous_strain_rate(cell, P1: float, eta: float, tau: float = 0.0) -> np.ndarray:
    """The strain-law G (2, 2) of a homogeneous, unloaded tissue under the constant turgor P1
    (docs/model.md section 4's exact solution; with fibred walls, consequence 4 of the fibre
    section), from one cell's tensors (``cell``: E_hom, K_hom, phi_w, dbar_w, dbar_v, e.g. a
    :class:`~plantgrowth.unitcell.solver.CellSolver` result): ``eps_el = E_hom^-1 ((1 - phi_w) I
    - K_hom) P1``, eps_hom by [strain_hom], ``G = eta [eps_hom / phi_w - tau I]_+`` (no clamp)."""
    stress = ((1.0 - cell.phi_w) * np.eye(2) - cell.K_hom) * P1
    e = np.linalg.solve(voigt_matrix(cell.E_hom), [stress[0, 0], stress[1, 1], stress[0, 1]])
    eps_el = np.array([[[e[0], 0.5 * e[2]], [0.5 * e[2], e[1]]]])
    phi = np.array([cell.phi_w])
    eps = homogenized_strain(eps_el, phi, cell.dbar_w[None], cell.dbar_v[None], np.array([P1]))
    return growth_rate(eps, phi, np.array([eta]), np.array([tau]), np.inf)[0]


def advance(Fg: np.ndarray, G: np.ndarray, dt: float, integrator: str) -> np.ndarray:
    """One step of dFg/dt = G Fg.

    ``euler``: the paper's ``Fg + dt G Fg`` (first order; unstable or non-physical for large
    dt G). ``exp``: ``expm(dt G) Fg``, exact for G constant over the step, with
    ``det = exp(dt tr G) det Fg`` so det Fg never decreases where G >= 0, for any dt.
    """
    if integrator == "euler":
        return Fg + dt * G @ Fg
    if integrator == "exp":
        return exp_symmetric(G, dt) @ Fg
    raise ValueError(f"integrator must be one of {INTEGRATORS}, got {integrator!r}")
