"""Finite kinematics: the multiplicative split F = Fe Fg (docs/model.md section 10).

``Fe = (I + grad u) Fg^{-1}``, ``Ee = (Fe^T Fe - I) / 2`` (Green-Lagrange, intermediate frame).
Residuals ``R(u; psi)`` are returned as linear forms in the test function psi; their Jacobians
are ``ufl.derivative(R, u)`` (:func:`jacobian`), never written by hand.

- macro: ``int Jg (Fe S_w + P_l) : grad(psi) Fg^{-1} dx - int_{Gamma_N} |cof(F) N| f . psi ds``
  with the walls' ``S_w = E_hom Ee + K_hom P1`` (= sigma_hom) and the lumens' water
  ``P_l = -(1 - phi_w) P1 cof(Fe)``, a follower pressure on the current lumen area; the grad(P1)
  and P2vec body forces of section 4 cancel (P2vec = (1 - phi_w) grad P1) and are not assembled;
- micro: St Venant-Kirchhoff walls, ``S = lam tr(Ee) I + 2 mu Ee``, and the follower turgor
  ``-P cof(F) N`` per reference length on the membranes.
"""

from __future__ import annotations

import ufl

from .elasticity import Fibres, growth_weighted_work, walls_stress
from .macro import from_voigt, voigt


def deformation_gradient(u):
    """``F = I + grad u``."""
    return ufl.Identity(2) + ufl.grad(u)


def elastic_deformation(u, Fg):
    """``Fe = (I + grad u) Fg^{-1}``."""
    return deformation_gradient(u) * ufl.inv(Fg)


def green_lagrange_strain(u, Fg):
    """``Ee = (Fe^T Fe - I) / 2``; equals the linear eps_el to first order in grad u and Fg - I."""
    Fe = elastic_deformation(u, Fg)
    return 0.5 * (Fe.T * Fe - ufl.Identity(2))


def cofactor(F):
    """``cof(F) = det(F) F^{-T}``: maps reference normals times length to current ones."""
    return ufl.det(F) * ufl.inv(F).T


def walls_macro_stress(u, Fg, C, K, P1):
    """The walls' second Piola stress ``S_w = E_hom Ee + K_hom P1`` (= sigma_hom; K = None: no
    pressure term)."""
    S = from_voigt(ufl.dot(C, voigt(green_lagrange_strain(u, Fg))))
    return S if K is None else S + K * P1


def lumen_pressure_stress(Fe, phi_w, P1):
    """The lumens' water as a first Piola stress of the intermediate frame, ``P_l = -(1 - phi_w)
    P1 cof(Fe)``: a pressure on the current lumen area (a follower; docs/model.md section 10)."""
    return -(1.0 - phi_w) * P1 * cofactor(Fe)


def macro_first_piola(u, Fg, C, K, phi_w, P1):
    """``Fe S_w + P_l`` (intermediate frame): the walls' stress carried by Fe plus the lumens'
    follower pressure (K = None: walls only)."""
    Fe = elastic_deformation(u, Fg)
    P = Fe * walls_macro_stress(u, Fg, C, K, P1)
    return P if K is None else P + lumen_pressure_stress(Fe, phi_w, P1)


def macro_residual(u, psi, Fg, C, K, phi_w, P1, dx) -> ufl.Form:
    """Volume part of the macro residual, ``int Jg (Fe S_w + P_l) : grad(psi) Fg^{-1} dx``."""
    return growth_weighted_work(macro_first_piola(u, Fg, C, K, phi_w, P1), psi, Fg, dx)


def macro_prestress_work(u, psi, Fg, K, phi_w, P1, dx) -> ufl.Form:
    """The turgor part of the macro residual, ``int Jg (Fe K_hom P1 + P_l) : grad(psi) Fg^{-1}
    dx``: the step's external load from turgor (the walls' prestress and the lumens' water)."""
    Fe = elastic_deformation(u, Fg)
    turgor = Fe * K * P1 + lumen_pressure_stress(Fe, phi_w, P1)
    return growth_weighted_work(turgor, psi, Fg, dx)


def current_length(u, n):
    """``|cof(F) N|``: the current length of a boundary element of unit reference length and
    reference normal N (Nanson's formula)."""
    cN = ufl.dot(cofactor(deformation_gradient(u)), n)
    return ufl.sqrt(ufl.inner(cN, cN))


def follower_traction(u, f, psi, n, ds) -> ufl.Form:
    """``int |cof(F) N| f . psi ds``: a traction f given per current length."""
    return current_length(u, n) * ufl.inner(f, psi) * ds


def wall_second_piola(u, Fg, E, nu, fibres: Fibres | None = None):
    """St Venant-Kirchhoff wall stress ``S = C_w[Ee]``: ``lam tr(Ee) I + 2 mu Ee``, plus the
    fibre part for fibred walls."""
    return walls_stress(green_lagrange_strain(u, Fg), E, nu, Fg, fibres)


def micro_residual(u, psi, Fg, E, nu, dx, fibres: Fibres | None = None) -> ufl.Form:
    """Walls part of the micro residual, ``int Jg (Fe S) : grad(psi) Fg^{-1} dx`` (first Piola
    stress ``Jg Fe S Fg^{-T}``)."""
    Fe = elastic_deformation(u, Fg)
    return growth_weighted_work(Fe * wall_second_piola(u, Fg, E, nu, fibres), psi, Fg, dx)


def follower_pressure(u, psi, P, n, ds) -> ufl.Form:
    """Turgor on the deformed membranes moved to the residual's side: ``+int P cof(F) N . psi ds``
    (the load is ``-P cof(F) N`` per reference length, N the walls' outward normal)."""
    return P * ufl.inner(ufl.dot(cofactor(deformation_gradient(u)), n), psi) * ds


def wall_stress_average_form(u, tau, Fg, E, nu, dx, fibres: Fibres | None = None) -> ufl.Form:
    """``int S : tau dx`` per mesh cell (stress-based micro growth, intermediate frame)."""
    return ufl.inner(wall_second_piola(u, Fg, E, nu, fibres), tau) * dx


def elastic_strain_average_form(u, tau, Fg, dx) -> ufl.Form:
    """``int Ee : tau dx`` per mesh cell (strain-based micro growth)."""
    return ufl.inner(green_lagrange_strain(u, Fg), tau) * dx


def jacobian(residual: ufl.Form, u) -> ufl.Form:
    """The exact Jacobian ``dR/du`` in the direction of a trial function (UFL-derived)."""
    return ufl.derivative(residual, u, ufl.TrialFunction(u.ufl_function_space()))


def lumen_area(u, weight, n, ds) -> ufl.Form:
    """The area the deformed membrane encloses, ``(1/2) int x . cof(F) N_l dS`` with
    ``x = X + u`` and ``N_l = -n`` out of the lumen (n: the walls' outward normal), weighted by
    ``weight`` (a cell's indicator). On the symmetry plane, where a cut cell's lumen is open,
    x2 = 0 and cof(F) N_l has no x1 component, so the open side adds nothing."""
    x = ufl.SpatialCoordinate(u.ufl_function_space().mesh) + u
    return -0.5 * weight * ufl.inner(x, ufl.dot(cofactor(deformation_gradient(u)), n)) * ds
