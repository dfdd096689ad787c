"""Growth-weighted unit-cell problems and their averages (docs/model.md section 3).

[UC_weak]:  int_{Y_w} Jg E[ d[w] + b ] : grad_g(phi) dy = 0,   d[w] = sym(grad(w) Fg^{-1})
[UCw_weak]: int_{Y_w} Jg ( E[ d[v] ] + I ) : grad_g(phi) dy = 0
E is the wall tensor C_w: isotropic, or with fibres (``elasticity.Fibres``) its section-11 form.
All problems share one bilinear form; they differ in the right-hand side only.
"""

from __future__ import annotations

import ufl

from .elasticity import Fibres, growth_weighted_work, sym_grad_g, walls_stress


def cell_strain_rhs(b, phi, Fg, E, nu, dx, fibres: Fibres | None = None) -> ufl.Form:
    """Right-hand side of [UC_weak] for the unit strain ``b = b_ij`` (a 2x2 ``Constant``)."""
    return -growth_weighted_work(walls_stress(b, E, nu, Fg, fibres), phi, Fg, dx)


def cell_pressure_rhs(phi, Fg, dx) -> ufl.Form:
    """Right-hand side of [UCw_weak]: the unit pressure term ``-int Jg I : grad_g(phi)``."""
    return -growth_weighted_work(ufl.Identity(2), phi, Fg, dx)


def stress_average_form(z, selector, Fg, E, nu, dx, fibres: Fibres | None = None) -> ufl.Form:
    """``int_{Y_w} C_w[d[z]] : S dy``; with S = e_k (x) e_l it gives one component of
    ``|Y| * mean(C_w d[z])`` used in [maacro_E] and [maacro_K]."""
    return ufl.inner(walls_stress(sym_grad_g(z, Fg), E, nu, Fg, fibres), selector) * dx


def wall_average_form(b, selector, Fg, E, nu, dx, fibres: Fibres | None = None) -> ufl.Form:
    """``int_{Y_w} C_w[b] : S dy``: the first term of [maacro_E] (``phi_w E[b]`` for isotropic
    walls, a sum over the segment families for fibred ones)."""
    return ufl.inner(walls_stress(b, E, nu, Fg, fibres), selector) * dx


def strain_average_form(z, selector, Fg, dx) -> ufl.Form:
    """``int_{Y_w} d[z] : S dy``, one component of ``|Y| * dbar[z]`` (needed by the strain law)."""
    return ufl.inner(sym_grad_g(z, Fg), selector) * dx


def membrane_moment_form(selector, x, n, ds) -> ufl.Form:
    """``int_Gamma (S n) . x dgamma``; with S = e_i (x) e_j it gives ``int_Gamma y_j N_i``, from
    which ``P2vec = -(1/|Y|) int_Gamma (grad P1 . y) N`` follows for P2 = -grad(P1) . y ([P2])."""
    return ufl.inner(ufl.dot(selector, n), x) * ds


# --- constant-coefficient basis (Fg constant over the cell) -------------------------------------
# With G = Fg^{-1} constant, the cell-problem forms above are linear combinations of the integrals
# below (weights from Fg, E, nu): the bilinear form of [UC_weak]/[UCw_weak] of the products
# ``int d_a z_i d_c phi_j``, its right-hand sides and the averages of the moments ``int d_c phi_j``.


def gradient_product_form(z, phi, P, Q, dx) -> ufl.Form:
    """``int_{Y_w} (grad z : P)(grad phi : Q) + (grad z : Q)(grad phi : P) dy``.

    With ``P = e_i (x) e_a`` and ``Q = e_j (x) e_c`` (constant 2x2 selectors) it gives the
    symmetrized product ``B_pq + B_qp`` of ``B_pq = int d_a z_i d_c phi_j`` (p = (i, a),
    q = (j, c)); the bilinear form of [UC_weak] is a weighted sum of them.
    """
    return (
        ufl.inner(ufl.grad(z), P) * ufl.inner(ufl.grad(phi), Q)
        + ufl.inner(ufl.grad(z), Q) * ufl.inner(ufl.grad(phi), P)
    ) * dx


def gradient_moment_form(phi, Q, dx) -> ufl.Form:
    """``int_{Y_w} grad(phi) : Q dy``; with ``Q = e_j (x) e_c`` the moment ``int d_c phi_j``.

    The right-hand sides of [UC_weak] and [UCw_weak] are weighted sums of these moments, and the
    averages of [maacro_E], [maacro_K] and dbar are their dot products with the solution.
    """
    return ufl.inner(ufl.grad(phi), Q) * dx


def lumen_area_change_form(z, Fg, n, ds) -> ufl.Form:
    """``int_Gamma z . Jg Fg^{-T} n_c dgamma``, ``n_c = -n`` (n: the walls' outward normal, into
    the lumen): the change of the grown lumen's area, to first order, when the membrane moves by
    z (docs/model.md, "Water fluxes"; Nanson's formula carries the reference normal to the grown
    membrane)."""
    return -ufl.det(Fg) * ufl.inner(z, ufl.dot(ufl.inv(Fg).T, n)) * ds
