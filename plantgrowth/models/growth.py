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


def symmetric_function(A: np.ndarray, f) -> np.ndarray:
    """``Q f(Lambda) Q^T`` for symmetric (n, 2, 2) tensors ``A = Q Lambda Q^T``."""
    lam, Q = np.linalg.eigh(A)
    return np.einsum("nij,nj,nkj->nik", Q, f(lam), Q)


def positive_part(A: np.ndarray) -> np.ndarray:
    """``A_+``: the tensor rebuilt from the positive parts of the eigenvalues."""
    return symmetric_function(A, lambda lam: np.maximum(lam, 0.0))


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
        return symmetric_function(G, lambda lam: np.exp(dt * lam)) @ Fg
    raise ValueError(f"integrator must be one of {INTEGRATORS}, got {integrator!r}")
