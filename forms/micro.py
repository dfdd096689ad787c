"""The cell-resolved microscopic model on the walls Omega^delta (docs/model.md section 7).

[var_inequal] with a pressure that is constant in each cell, written as the membrane traction:
``int Jg E[eps_el(u, Fg)] : grad(psi) Fg^{-1} dx = -int_Gamma Jg P (Fg^{-T} N) . psi ds``
(+ tractions), with ``eps_el = sym(grad(u) Fg^{-1}) + sym(Fg^{-1}) - I``; Fg, E, nu, P are
constant per cell. The bilinear part is :func:`elasticity.wall_bilinear_form`.
"""

from __future__ import annotations

import ufl

from .elasticity import Fibres, elastic_strain, growth_strain, growth_weighted_work, walls_stress


def micro_growth_rhs(psi, Fg, E, nu, dx, fibres: Fibres | None = None) -> ufl.Form:
    """Growth load ``-int Jg C_w[sym(Fg^{-1}) - I] : grad(psi) Fg^{-1} dx`` (C_w isotropic
    unless ``fibres`` are given)."""
    return -growth_weighted_work(walls_stress(growth_strain(Fg), E, nu, Fg, fibres), psi, Fg, dx)


def membrane_pressure_rhs(psi, Fg, P, n, ds) -> ufl.Form:
    """Turgor on the plasma membranes: ``-int_Gamma Jg P (Fg^{-T} N) . psi ds``."""
    return -ufl.det(Fg) * P * ufl.inner(ufl.dot(ufl.inv(Fg).T, n), psi) * ds


def wall_stress_average_form(u, tau, Fg, E, nu, dx, fibres: Fibres | None = None) -> ufl.Form:
    """``int C_w[eps_el] : tau dx`` with tau a DG0 tensor test function: per mesh cell, the
    integral of the wall stress (summed per biological cell for the growth law)."""
    return ufl.inner(walls_stress(elastic_strain(u, Fg), E, nu, Fg, fibres), tau) * dx


def elastic_strain_average_form(u, tau, Fg, dx) -> ufl.Form:
    """``int eps_el : tau dx`` per mesh cell (strain-based growth)."""
    return ufl.inner(elastic_strain(u, Fg), tau) * dx


def enclosed_area_form(u, n, ds) -> ufl.Form:
    """Area enclosed by the deformed boundary, ``1/2 int (X1 dX2 - X2 dX1)`` with X = x + u and
    ``dX = (I + grad u) t ds``, t = (-n2, n1) (Green's theorem on the outer boundary)."""
    X = ufl.SpatialCoordinate(u.ufl_function_space().mesh) + u
    t = ufl.as_vector([-n[1], n[0]])
    dX = ufl.dot(ufl.Identity(2) + ufl.grad(u), t)
    return 0.5 * (X[0] * dX[1] - X[1] * dX[0]) * ds
