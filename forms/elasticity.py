"""Wall material law and growth kinematics shared by every weak form (docs/model.md sections
1, 3, 4).

Pure UFL: UFL expressions (or ``fem.Constant``/``fem.Function``) in, UFL expressions out.
"""

from __future__ import annotations

from typing import NamedTuple

import ufl


class Fibres(NamedTuple):
    """Fibre reinforcement of the walls (docs/model.md, "Fibre-reinforced walls"), as UFL
    coefficients: ``stiffness`` E_f (= fibre_stiffness * E), ``director`` m (grown frame) and
    ``tangent`` t, the reference tangent of the mid-line segment each wall point belongs to."""

    stiffness: object
    director: object
    tangent: object


def lame_parameters(E, nu) -> tuple:
    """Plane-stress Lame constants (paper appendix A).

    ``mu = E / (2 (1 + nu))``, ``lam = E nu / (1 - nu^2)``.
    """
    return E / (2.0 * (1.0 + nu)), E * nu / (1.0 - nu**2)


def wall_stress(e, E, nu):
    """Isotropic wall stress ``E[e] = lam tr(e) I + 2 mu e`` (docs/model.md section 1)."""
    mu, lam = lame_parameters(E, nu)
    return lam * ufl.tr(e) * ufl.Identity(e.ufl_shape[0]) + 2.0 * mu * e


def fibre_stress(e, Fg, fibres: Fibres):
    """``E_f q (t_g . e t_g) t_g (x) t_g``: the fibre part of ``C_w[e]``, with the grown tangent
    ``t_g = Fg t / |Fg t|`` and the fibre weight ``q = (m . t_g)^2``."""
    Ft = ufl.dot(Fg, fibres.tangent)
    tg = Ft / ufl.sqrt(ufl.inner(Ft, Ft))
    q = ufl.inner(fibres.director, tg) ** 2
    return fibres.stiffness * q * ufl.inner(tg, ufl.dot(e, tg)) * ufl.outer(tg, tg)


def walls_stress(e, E, nu, Fg, fibres: Fibres | None = None):
    """``C_w[e]``: the isotropic wall stress, plus :func:`fibre_stress` for fibred walls."""
    stress = wall_stress(e, E, nu)
    return stress if fibres is None else stress + fibre_stress(e, Fg, fibres)


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


def wall_bilinear_form(z, psi, Fg, E, nu, dx, fibres: Fibres | None = None) -> ufl.Form:
    """``int Jg C_w[sym(grad(z) Fg^{-1})] : grad(psi) Fg^{-1} dx``: the walls' stiffness, shared
    by the cell problems [UC_weak], [UCw_weak] and the micro model [var_inequal] (C_w isotropic
    unless ``fibres`` are given)."""
    return growth_weighted_work(walls_stress(sym_grad_g(z, Fg), E, nu, Fg, fibres), psi, Fg, dx)
