"""Wall material law and growth kinematics shared by every weak form (docs/model.md sections
1, 3, 4).

Pure UFL: UFL expressions (or ``fem.Constant``/``fem.Function``) in, UFL expressions out.
"""

from __future__ import annotations

import ufl


def lame_parameters(E, nu) -> tuple:
    """Plane-stress Lame constants (paper appendix A).

    ``mu = E / (2 (1 + nu))``, ``lam = E nu / (1 - nu^2)``.
    """
    return E / (2.0 * (1.0 + nu)), E * nu / (1.0 - nu**2)


def wall_stress(e, E, nu):
    """Isotropic wall stress ``E[e] = lam tr(e) I + 2 mu e`` (docs/model.md section 1)."""
    mu, lam = lame_parameters(E, nu)
    return lam * ufl.tr(e) * ufl.Identity(e.ufl_shape[0]) + 2.0 * mu * e


def grad_g(z, Fg):
    """Growth-weighted gradient ``grad(z) Fg^{-1}`` (docs/model.md section 3)."""
    return ufl.grad(z) * ufl.inv(Fg)


def sym_grad_g(z, Fg):
    """``d[z] = sym(grad(z) Fg^{-1})``, the paper's generalised strain."""
    return ufl.sym(grad_g(z, Fg))


def growth_weighted_work(stress, psi, Fg, dx) -> ufl.Form:
    """``int Jg stress : grad(psi) Fg^{-1} dx``: virtual work in the reference configuration,
    shared by the cell, macro and micro problems ([UC_weak], [macro_weak_222], [var_inequal])."""
    return ufl.det(Fg) * ufl.inner(stress, grad_g(psi, Fg)) * dx


def grown_length(Fg, n):
    """``Jg |Fg^{-T} N|``: the grown length of a boundary element of unit reference length and
    reference normal N (Nanson's formula for the growth map Fg)."""
    FinvT_n = ufl.dot(ufl.inv(Fg).T, n)
    return ufl.det(Fg) * ufl.sqrt(ufl.inner(FinvT_n, FinvT_n))


def boundary_traction(f, psi, Fg, n, ds) -> ufl.Form:
    """``int Jg |Fg^{-T} N| f . psi ds``, a traction f given per grown length (docs/model.md
    section 4)."""
    return grown_length(Fg, n) * ufl.inner(f, psi) * ds


def growth_strain(Fg):
    """The displacement-free part of the elastic strain: ``sym(Fg^{-1}) - I``."""
    return ufl.sym(ufl.inv(Fg)) - ufl.Identity(2)


def elastic_strain(u, Fg):
    """``eps_el(u, Fg) = sym(grad(u) Fg^{-1}) + sym(Fg^{-1}) - I`` (docs/model.md section 4)."""
    return sym_grad_g(u, Fg) + growth_strain(Fg)


def wall_bilinear_form(z, psi, Fg, E, nu, dx) -> ufl.Form:
    """``int Jg E[sym(grad(z) Fg^{-1})] : grad(psi) Fg^{-1} dx``: the walls' stiffness, shared by
    the cell problems [UC_weak], [UCw_weak] and the micro model [var_inequal]."""
    return growth_weighted_work(wall_stress(sym_grad_g(z, Fg), E, nu), psi, Fg, dx)
