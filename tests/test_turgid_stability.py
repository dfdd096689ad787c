"""Stability a turgid tissue obeys (docs/model.md section 10 as amended; docs/stability.md).

The lumens' water is a follower pressure ``P_l = -(1 - phi_w) P1 cof(Fe)``; the acoustic tensor
takes the walls' stress ``S_w = E_hom Ee + K_hom P1`` only (water at a given pressure resists no
shear); a non-elliptic set within one cell is a singular point, reported, never a stop.
"""

from __future__ import annotations

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from petsc4py import PETSc
from scipy.optimize import brentq

import plantgrowth as pg
from plantgrowth.forms import finite
from plantgrowth.models.nonelliptic_sets import NonellipticSet, connected_sets, sets_of
from plantgrowth.models.stability import (
    Ellipticity,
    acoustic_tensor,
    elasticity_tensor,
    smallest_acoustic_eigenvalue,
)
from plantgrowth.runner.step_warnings import StepWarnings

P1 = 1e-3
HEX = pg.cell(resolution=2)  # the reference cell: regular hexagon, w = 0.05, E = 1
C_HEX = np.array([[HEX["E1111"], HEX["E1122"], HEX["E1112"]],
                  [HEX["E1122"], HEX["E2222"], HEX["E2212"]],
                  [HEX["E1112"], HEX["E2212"], HEX["E1212"]]])  # fmt: skip
PHI_W = HEX["phi_w"]


# --- the follower term and its tangent -----------------------------------------------------------


@pytest.mark.mpi
def test_the_follower_terms_jacobian_matches_finite_differences():
    """The macro residual with the lumens' follower term at a random u and an anisotropic Fg:
    its UFL Jacobian applied to a direction equals the central difference of the residual,
    to the difference's own O(eps^2) truncation (eps = 1e-6 of a unit displacement: 1e-9
    relative, far below the follower term's share of the tangent, (1 - phi_w) P1 / E_hom_1111 ~
    3%)."""
    msh = dmesh.create_unit_square(MPI.COMM_WORLD, 4, 4)
    V = fem.VectorFunctionSpace(msh, ("Lagrange", 1))
    T0 = fem.TensorFunctionSpace(msh, ("DG", 0))
    C = fem.Constant(msh, PETSc.ScalarType(C_HEX))
    K = fem.Constant(msh, PETSc.ScalarType(0.3 * np.eye(2)))
    phi_w = fem.Constant(msh, PETSc.ScalarType(PHI_W))
    P = fem.Constant(msh, PETSc.ScalarType(P1))
    Fg = fem.Function(T0)
    Fg.interpolate(lambda x: np.tile(np.array([[1.2, 0.1], [0.0, 0.9]]).reshape(4, 1), x.shape[1]))
    u, du = fem.Function(V), fem.Function(V)
    u.interpolate(lambda x: 0.05 * np.array([np.sin(3 * x[1]) + x[0], np.cos(2 * x[0]) * x[1]]))
    du.interpolate(lambda x: np.array([np.cos(x[0] + 2 * x[1]), x[0] * x[1] - 0.3]))
    psi = ufl.TestFunction(V)
    residual = finite.macro_residual(u, psi, Fg, C, K, phi_w, P, ufl.dx)
    R, J = fem.form(residual), fem.form(finite.jacobian(residual, u))

    def assemble_R() -> np.ndarray:
        vec = fem.petsc.assemble_vector(R)
        vec.ghostUpdate(PETSc.InsertMode.ADD, PETSc.ScatterMode.REVERSE)
        return vec.array.copy()

    A = fem.petsc.assemble_matrix(J)
    A.assemble()
    Jdu = A.createVecLeft()
    A.mult(du.vector, Jdu)
    eps, base = 1e-6, u.x.array.copy()
    values = []
    for sign in (1.0, -1.0):
        u.x.array[:] = base + sign * eps * du.x.array
        values.append(assemble_R())
    difference = (values[0] - values[1]) / (2 * eps)
    error = MPI.COMM_WORLD.allreduce(float(np.abs(difference - Jdu.array).max()), op=MPI.MAX)
    scale = MPI.COMM_WORLD.allreduce(float(np.abs(Jdu.array).max()), op=MPI.MAX)
    assert error <= 1e-7 * scale


def first_piola(Fe: np.ndarray, C: np.ndarray, K: np.ndarray, lumens: bool = True) -> np.ndarray:
    """``Fe S_w + P_l`` with ``S_w = C[Ee] + K P1`` and ``P_l = -(1 - phi_w) P1 cof(Fe)``."""
    Ee = 0.5 * (Fe.T @ Fe - np.eye(2))
    s = C @ np.array([Ee[0, 0], Ee[1, 1], 2 * Ee[0, 1]])
    S = np.array([[s[0], s[2]], [s[2], s[1]]]) + K * P1
    cof = np.array([[Fe[1, 1], -Fe[1, 0]], [-Fe[0, 1], Fe[0, 0]]])
    return Fe @ S + (-(1.0 - PHI_W) * P1 * cof if lumens else 0.0)


def finite_difference_tangent(P, Fe: np.ndarray, eps: float = 1e-7) -> np.ndarray:
    """A_iJkL = dP_iJ / dFe_kL by central differences."""
    A = np.zeros((2, 2, 2, 2))
    for k in range(2):
        for L in range(2):
            step = np.zeros((2, 2))
            step[k, L] = eps
            A[:, :, k, L] = (P(Fe + step) - P(Fe - step)) / (2 * eps)
    return A


def test_Q_is_the_tangent_of_the_full_first_piola_stress_and_the_lumens_add_nothing():
    """At a sheared, stretched Fe with a grown anisotropic cell's tensors: Q(N) from
    ``(N . S_w N) I + Fe M(N) Fe^T`` equals ``A_iJkL N_J N_L`` of the finite-difference tangent of
    ``Fe S_w + P_l`` for 12 directions, and the lumens' part alone contracts to zero (cof is
    linear in 2D and ``cof(a x N) N = 0``). Tolerance 1e-7 of |Q|: central differences of a
    quadratic-plus-cubic function at eps = 1e-7 leave ~eps^2 |d3P| plus round-off eps_mach / eps
    ~ 1e-9."""
    cell = pg.cell(resolution=1, l1=1.5, Fg=[[1.3, 0.2], [0.0, 0.9]])
    C = np.array([[cell["E1111"], cell["E1122"], cell["E1112"]],
                  [cell["E1122"], cell["E2222"], cell["E2212"]],
                  [cell["E1112"], cell["E2212"], cell["E1212"]]])  # fmt: skip
    K = np.array([[0.4, 0.05], [0.05, 0.3]])
    Fe = np.array([[1.05, 0.12], [-0.07, 0.93]])
    A = finite_difference_tangent(lambda F: first_piola(F, C, K), Fe)
    A_lumens = finite_difference_tangent(
        lambda F: first_piola(F, C, K) - first_piola(F, C, K, lumens=False), Fe
    )
    Ee = 0.5 * (Fe.T @ Fe - np.eye(2))
    s = C @ np.array([Ee[0, 0], Ee[1, 1], 2 * Ee[0, 1]])
    S_w = np.array([[s[0], s[2]], [s[2], s[1]]]) + K * P1
    phi = np.linspace(0.0, np.pi, 12, endpoint=False)
    N = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    Q = acoustic_tensor(Fe[None], S_w[None], elasticity_tensor(C[None]), N[None])[0]
    scale = np.abs(Q).max()
    assert np.abs(np.einsum("iJkL,nJ,nL->nik", A, N, N) - Q).max() <= 1e-7 * scale
    assert np.abs(np.einsum("iJkL,nJ,nL->nik", A_lumens, N, N)).max() <= 1e-7 * scale


def test_the_hexagons_Q_changes_sign_at_minus_its_shear_modulus():
    """Fe = I, ``S_w = diag(s, (1 - phi_w) P1)``, regular hexagon: Q's smallest eigenvalue over
    all N is s + E_hom_1212 (N = e1, the shear mode), zero at s = -E_hom_1212 (brentq to 1e-14;
    the refined minimum is exact to round-off, tests/test_stability.py)."""

    def smallest(s: float) -> float:
        S = np.diag([s, (1.0 - PHI_W) * P1])
        return float(smallest_acoustic_eigenvalue(np.eye(2)[None], S[None], C_HEX[None])[0][0])

    root = brentq(smallest, -10 * HEX["E1212"], 0.0, xtol=1e-14)
    assert root == pytest.approx(-HEX["E1212"], rel=1e-8)
    assert smallest(-0.99 * HEX["E1212"]) > 0.0 > smallest(-1.01 * HEX["E1212"])


@pytest.mark.mpi
def test_a_free_turgid_tissue_is_elliptic_with_the_turgors_margin():
    """A free homogeneous turgid tissue (finite kinematics, regular hexagon): the walls carry
    S_w = (1 - phi_w) P1 I and Fe = lambda R, so Q's smallest eigenvalue is exactly
    ``(1 - phi_w) P1 + det(Fe) mu_hom``, the unpressurized tissue's mu_hom (at Fe = I, S = 0) plus
    the turgor's margin (1 - phi_w) P1 up to the stretch's O(Ee) factor. Checked to 1e-6 of the
    margin: Newton's relative residual 1e-10 times these systems' conditioning (1e-8) over the
    margin's share of Q (~0.6)."""
    from plantgrowth.models.macro.model import macro_model
    from plantgrowth.scene import parse_scene

    sc = parse_scene({
        "kinematics": "finite", "tissue": {"width": 2.0, "height": 1.0, "h": 0.25, "H": 1.0},
        "growth": {"law": "stress"}, "time": {"t_max": 1.0},
        "accuracy": {"cell_resolution": 2, "cell_tolerance": 0.0},
    })  # fmt: skip
    model = macro_model(sc, MPI.COMM_WORLD)
    model.step(model.initial_growth())
    problem, n = model.problem, model.problem.n_owned
    Fe, S, C = (x[:n] for x in problem.walls_state())
    turgid = smallest_acoustic_eigenvalue(Fe, S, C)[0]
    unpressurized = smallest_acoustic_eigenvalue(np.tile(np.eye(2), (n, 1, 1)), 0 * S, C)[0]
    margin = (1.0 - problem.cell_values(problem.phi_w)[:n, 0]) * P1
    exact = margin + np.linalg.det(Fe) * unpressurized
    comm = MPI.COMM_WORLD
    assert comm.allreduce(float(np.abs(turgid - exact).max(initial=0)), op=MPI.MAX) <= 1e-6 * P1
    # the margin itself, against the unpressurized tissue: (1 - phi_w) P1 to O(Ee) (< 5%)
    gain = (turgid - unpressurized) / margin
    assert comm.allreduce(float(np.abs(gain - 1.0).max(initial=0)), op=MPI.MAX) < 0.05


# --- the resolution rule -------------------------------------------------------------------------


def test_units_sharing_a_vertex_form_one_set():
    """Two triangles sharing an edge and one touching only a corner are one set; a fourth apart
    is another."""
    vertices = np.array([[0, 1, 2], [1, 2, 3], [3, 4, 5], [10, 11, 12]])
    count, labels = connected_sets(vertices)
    assert count == 2 and len(set(labels[:3])) == 1 and labels[3] != labels[0]


def unit_sets(n: int, area: float, cell_area: float) -> list[NonellipticSet]:
    """n connected units (a strip) of equal area, each with the given cell area."""
    vertices = np.array([[i, i + 1, i + 2] for i in range(n)])
    ones = np.ones(n)
    return sets_of(-ones, vertices, area * ones, area * ones, cell_area * ones,
                   np.zeros((n, 2)), np.zeros((n, 2, 2)))  # fmt: skip


def test_a_set_is_singular_by_its_area_against_a_cells_not_by_its_count():
    """The rule compares areas: many small fine cells whose total exceeds a cell's grown area
    are an instability; one fine cell larger than a cell (a coarse mesh, small cells) is one
    too; a few fine cells within one cell's area are a singular point."""
    (many,) = unit_sets(40, 0.01, 0.3)
    assert many.area == pytest.approx(0.4) and not many.singular and many.cells > 1.0
    (one,) = unit_sets(1, 0.5, 0.3)
    assert not one.singular
    (few,) = unit_sets(5, 0.01, 0.3)
    assert few.singular and few.cells == pytest.approx(0.05 / 0.3)


def ellipticity(fraction: float, s: np.ndarray | None = None) -> Ellipticity:
    stress = np.diag([-2e-3, 1e-3]) if s is None else s
    worst = NonellipticSet((1.0, 2.0), fraction, fraction, 0.1, -0.2, stress)
    return Ellipticity(fraction, 0.0, -0.2, (1.0, 2.0), (worst,) if fraction > 0 else ())


def test_the_nonelliptic_area_warns_when_it_appears_and_each_time_it_doubles():
    """Warnings at 0.01 (appears), 0.025 (> 2x), 0.1; none at 0.015 or 0.03 (same band). A run
    resumed after the 0.025 step warns for the same later steps as the whole run."""
    series = [0.0, 0.01, 0.015, 0.025, 0.03, 0.1]

    def warned(warnings: StepWarnings, fractions) -> list[float]:
        out = []
        for f in fractions:
            if warnings._nonelliptic(0, 0.0, ellipticity(f)):
                out.append(f)
        return out

    assert warned(StepWarnings(), series) == [0.01, 0.025, 0.1]
    resumed = StepWarnings(nonelliptic_reached=max(series[:4]))
    assert warned(resumed, series[4:]) == [0.1]
    text = StepWarnings()._nonelliptic(3, 3.0, ellipticity(0.01))[0]
    assert "appeared" in text and "0.01 of the tissue" in text


def test_compressed_only_where_the_walls_stress_has_a_compressive_principal_value():
    """The words: "compressed", with the value and the direction, where S_w has a negative
    principal value; otherwise the walls are said to be in tension and the lost shear
    stiffness is named."""
    compressed = ellipticity(0.2, np.diag([1e-3, -2e-3])).describe(4.0)
    assert "compressed (principal stress -0.002 along 90 degrees from x1" in compressed
    tension = ellipticity(0.2, np.diag([1e-3, 2e-3])).describe(4.0)
    assert "compressed" not in tension and "in tension" in tension and "shear band" in tension
