"""Macroscopic two-scale elasticity with growth (docs/model.md section 4, [macro_weak_222]).

``int Jg [E_hom eps_el + (K_hom + (phi_w - 1) I) P1] : grad(psi) Fg^{-1} dx
  = int Jg (1 - phi_w) Fg^{-T} grad(P1) . psi dx + int_{Gamma_N} Jg |Fg^{-T} N| f . psi ds
  - int Jg Fg^{-T} P2vec . psi dx``
with ``eps_el(u, Fg) = sym(grad(u) Fg^{-1}) + sym(Fg^{-1}) - I``. The effective tensor enters as a
3x3 Voigt matrix C acting on ``(e11, e22, 2 e12)``. Each term is its own function so that a
problem assembles only the terms its scene activates.
"""

from __future__ import annotations

import ufl

from .elasticity import growth_strain, growth_weighted_work, sym_grad_g


def voigt(e):
    """Engineering Voigt vector ``(e11, e22, 2 e12)`` of a symmetric 2x2 tensor."""
    return ufl.as_vector([e[0, 0], e[1, 1], 2.0 * e[0, 1]])


def from_voigt(s):
    """Symmetric 2x2 tensor from a stress Voigt vector ``(s11, s22, s12)``."""
    return ufl.as_matrix([[s[0], s[2]], [s[2], s[1]]])


def macro_bilinear_form(u, psi, Fg, C, dx) -> ufl.Form:
    """``int Jg E_hom sym(grad(u) Fg^{-1}) : grad(psi) Fg^{-1} dx``."""
    stress = from_voigt(ufl.dot(C, voigt(sym_grad_g(u, Fg))))
    return growth_weighted_work(stress, psi, Fg, dx)


def macro_growth_rhs(psi, Fg, C, dx) -> ufl.Form:
    """Growth load ``-int Jg E_hom (sym(Fg^{-1}) - I) : grad(psi) Fg^{-1} dx``."""
    stress = from_voigt(ufl.dot(C, voigt(growth_strain(Fg))))
    return -growth_weighted_work(stress, psi, Fg, dx)


def macro_pressure_rhs(psi, Fg, K, phi_w, P1, dx) -> ufl.Form:
    """Turgor load ``-int Jg (K_hom + (phi_w - 1) I) P1 : grad(psi) Fg^{-1} dx``."""
    stress = (K + (phi_w - 1.0) * ufl.Identity(2)) * P1
    return -growth_weighted_work(stress, psi, Fg, dx)


def macro_pressure_gradient_rhs(psi, Fg, phi_w, grad_P1, P2vec, dx) -> ufl.Form:
    """Body forces of a pressure gradient (docs/model.md section 6):
    ``int Jg Fg^{-T} ((1 - phi_w) grad(P1) - P2vec) . psi dx``."""
    force = ufl.dot(ufl.inv(Fg).T, (1.0 - phi_w) * grad_P1 - P2vec)
    return ufl.det(Fg) * ufl.inner(force, psi) * dx
