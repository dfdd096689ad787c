"""The macro model's water (docs/model.md, "Water fluxes", macro model); linear kinematics but
for :func:`water_held_finite` (the finite step's residual: models/macro/water_finite.py).

Turgor P is a field solved with u; the water held per unit reference area is
``m = Jg [(1 - phi_w) + b : eps_el + P / M]`` with the Biot tensor ``b = (1 - phi_w) I - K_hom``.
One backward-Euler step, the water balance tested with q and multiplied by ``-dt``, is the
symmetric saddle point
``[K  -B; -B^T  -(S + D + dt H)] [u; P] = [f; -g]``:
``K`` the elasticity of section 4, ``B(P, v) = int Jg P b : grad(v) Fg^{-1}`` (the turgor's stress
``-b P``), ``S`` the storage ``int Jg P q / M``, ``H`` Darcy's conductance with the supplies,
``D`` the pressure stabilisation ``int Jg beta Fg^{-T} grad P . Fg^{-T} grad q`` applied to the
step's change of P (P1-P1 pair, see docs/model.md).
"""

from __future__ import annotations

import ufl

from .elasticity import elastic_strain, grown_length, growth_strain, growth_weighted_work
from .finite import elastic_deformation, green_lagrange_strain


def biot_tensor(K, phi_w):
    """``b = (1 - phi_w) I - K_hom``."""
    return (1.0 - phi_w) * ufl.Identity(2) - K


def water_held(u, P, Fg, K, phi_w, inv_M):
    """``m = Jg [(1 - phi_w) + b : eps_el(u, Fg) + P / M]`` per unit reference area."""
    b = biot_tensor(K, phi_w)
    return ufl.det(Fg) * ((1.0 - phi_w) + ufl.inner(b, elastic_strain(u, Fg)) + inv_M * P)


def water_held_finite(u, P, Fg, K, phi_w, inv_M):
    """``m = Jg [(1 - phi_w) det(Fe) - K_hom : Ee + P / M]`` per unit reference area, finite
    kinematics (Fe, Ee: forms/finite.py): its derivative in u is minus the turgor's part of the
    finite macro residual's derivative in P, ``Jg ((1 - phi_w) cof(Fe) - Fe K_hom) : grad(du)
    Fg^{-1}``, so the (u, P) Jacobian is symmetric."""
    Fe = elastic_deformation(u, Fg)
    Ee = green_lagrange_strain(u, Fg)
    return ufl.det(Fg) * ((1.0 - phi_w) * ufl.det(Fe) - ufl.inner(K, Ee) + inv_M * P)


def water_at_rest(q, Fg, K, phi_w, dx) -> ufl.Form:
    """``int Jg [(1 - phi_w) + b : (sym(Fg^{-1}) - I)] q dx``: the part of ``int m q`` with
    neither u nor P."""
    b = biot_tensor(K, phi_w)
    return ufl.det(Fg) * ((1.0 - phi_w) + ufl.inner(b, growth_strain(Fg))) * q * dx


def turgor_coupling(P, v, Fg, K, phi_w, dx) -> ufl.Form:
    """``B(P, v) = int Jg P b : grad(v) Fg^{-1} dx``: the work of the turgor's stress ``-b P``
    (with a sign), and with v = u the lumens' water ``int Jg b : sym(grad u Fg^{-1}) P``."""
    return growth_weighted_work(P * biot_tensor(K, phi_w), v, Fg, dx)


def storage_form(P, q, Fg, inv_M, dx) -> ufl.Form:
    """``S(P, q) = int Jg P q / M dx``."""
    return ufl.det(Fg) * inv_M * P * q * dx


def grown_gradient_form(p, q, Fg, k, dx) -> ufl.Form:
    """``int Jg k Fg^{-T} grad p . Fg^{-T} grad q dx`` (k a tensor or a scalar, grown frame):
    Darcy's ``-int Q . grad q`` with ``Q = -Jg Fg^{-1} kappa Fg^{-T} grad p`` for k = kappa, and
    the pressure stabilisation for k = beta."""
    FinvT = ufl.inv(Fg).T
    gp, gq = ufl.dot(FinvT, ufl.grad(p)), ufl.dot(FinvT, ufl.grad(q))
    return ufl.det(Fg) * ufl.inner(k * gp, gq) * dx


def edge_supply_form(p, q, Fg, L_s, n, ds) -> ufl.Form:
    """``int L_s |cof(Fg) N| p q ds`` (``|cof(Fg) N| = Jg |Fg^{-T} N|``, the grown length)."""
    return L_s * grown_length(Fg, n) * p * q * ds


def region_supply_form(p, q, Fg, L_r, dx) -> ufl.Form:
    """``int Jg L_r p q dx`` (L_r zero outside the supplied regions)."""
    return ufl.det(Fg) * L_r * p * q * dx


def conductance_form(p, q, Fg, kappa, L_r, dx, edges) -> ufl.Form:
    """``H(p, q)``: Darcy's conductance, the regions' and the edges' (``edges``: pairs
    ``(L_s, ds)``, each edge's conductance and measure; n is taken from p's mesh)."""
    n = ufl.FacetNormal(p.ufl_function_space().mesh)
    H = grown_gradient_form(p, q, Fg, kappa, dx) + region_supply_form(p, q, Fg, L_r, dx)
    for L_s, ds in edges:
        H += edge_supply_form(p, q, Fg, L_s, n, ds)
    return H


def darcy_flux(psi, Fg, kappa):
    """``Q = -Jg Fg^{-1} kappa Fg^{-T} grad psi``: the water flux per unit reference length (the
    grown frame's Darcy law carried back by the growth map's Piola transform)."""
    Finv = ufl.inv(Fg)
    return -ufl.det(Fg) * ufl.dot(Finv, ufl.dot(kappa, ufl.dot(Finv.T, ufl.grad(psi))))
