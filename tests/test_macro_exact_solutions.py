"""Exact solutions of the coupled macro model (docs/model.md sections 4-5) and exact
coefficient fields.

Homogeneous parameters, constant P1, a uniform Fg and no loads: the total stress
``S = E_hom eps_el + (K_hom + (phi_w - 1) I) P1`` vanishes for the linear u with
``E_hom eps_el = ((1 - phi_w) I - K_hom) P1``, ``eps_el = sym(grad u Fg^{-1}) + sym(Fg^{-1}) - I``;
that u satisfies the weak form with a traction-free boundary, u2 = 0 on x2 = 0 (grad u has no
21 entry) and u1(0) = 0, so it is *the* solution, and it lies in the P1 space: the discrete u
equals it up to the direct solver's round-off. The expected u is computed here from tensors of an
independent :class:`CellSolver` (same mesh resolution, so the same discrete cell problems), so
the check covers the way from the cell problems to the macro solve (key reduction, E scaling,
projection of Fg to the coarse nodes, interpolation to the fine cells, the macro forms) and the
numpy side of the growth law (eps_el, sigma_hom, eps_hom).

Tolerances: the macro system has 10^3-10^4 dofs; its LU solve leaves a relative error of about
cond(A) * 1e-16 (measured on u: 7e-12 at h = 0.1 with 4,340 dofs, 2e-13 at h = 0.35; 9e-12 on
2 ranks); the independent cell solve repeats the run's own (exact invariances Fg -> Fg / sqrt(det
Fg), E -> 1, the same mesh and LU) to round-off; hence 1e-9 relative to the largest value.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from plantgrowth.base.tensors import voigt_matrix
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.models.macro.model import MacroModel
from plantgrowth.models.macro.problem import rectangle_mesh
from plantgrowth.scene import load_scene, parse_scene
from plantgrowth.unitcell.solver import CellSolver

pytestmark = pytest.mark.mpi  # scripts/README.md, "Tests": every test also runs on 2 ranks

ROOT = Path(__file__).resolve().parents[1]
ROUND_OFF = 1e-9  # LU round-off of the macro and cell solves (module docstring)


def macro_model(scene) -> MacroModel:
    comm = MPI.COMM_WORLD
    return MacroModel(scene, rectangle_mesh(scene, comm), comm)


def cell_tensors(scene, Fg: np.ndarray):
    """E_hom (Voigt), K_hom, dbar of the scene's (homogeneous) cell at Fg, solved on COMM_SELF."""
    material = scene.material
    solver = CellSolver(scene.cell.at(0.0, 0.0), scene.accuracy.cell_resolution, MPI.COMM_SELF)
    return solver.solve(Fg, material.E.start, material.nu.start)


def exact_elastic_strain(C: np.ndarray, K: np.ndarray, phi_w: float, P1: float) -> np.ndarray:
    """eps_el with ``E_hom eps_el = ((1 - phi_w) I - K_hom) P1`` (C: Voigt matrix of E_hom)."""
    s = ((1.0 - phi_w) * np.eye(2) - K) * P1
    e = np.linalg.solve(C, [s[0, 0], s[1, 1], s[0, 1]])
    return np.array([[e[0], 0.5 * e[2]], [0.5 * e[2], e[1]]])


def exact_displacement_gradient(eps_el: np.ndarray, Fg: np.ndarray) -> np.ndarray:
    """H = grad u with ``sym(H Fg^{-1}) = eps_el - sym(Fg^{-1}) + I`` and H21 = 0 (u2 = 0 on
    x2 = 0; u1(0) = 0 then fixes the rigid rotation and translation)."""
    Finv = np.linalg.inv(Fg)
    target = eps_el - 0.5 * (Finv + Finv.T) + np.eye(2)
    unknowns = [(0, 0), (0, 1), (1, 1)]  # H11, H12, H22

    def components(S: np.ndarray) -> list[float]:
        return [S[0, 0], S[1, 1], 0.5 * (S[0, 1] + S[1, 0])]

    M = np.column_stack(
        [components(np.outer(np.eye(2)[i], np.eye(2)[j]) @ Finv) for i, j in unknowns]
    )
    h = np.linalg.solve(M, components(target))
    H = np.zeros((2, 2))
    for (i, j), value in zip(unknowns, h, strict=True):
        H[i, j] = value
    return H


def displacement_error(model: MacroModel, H: np.ndarray) -> tuple[float, float]:
    """(max |u - H x|, max |H x|) over the P1 nodes of all ranks."""
    V = model.problem.V
    x = V.tabulate_dof_coordinates()[:, :2]
    u = model.problem.u.x.array.reshape(-1, 2)[: len(x)]
    expected = x @ H.T
    comm = model.comm
    error = comm.allreduce(float(np.abs(u - expected).max(initial=0.0)), op=MPI.MAX)
    scale = comm.allreduce(float(np.abs(expected).max(initial=0.0)), op=MPI.MAX)
    return error, scale


def test_reference_scene_displacement_at_t0_is_linear():
    """The reference scene (docs/model.md section 9) at t = 0: u = H x with H = [[e11, 2 e12], [0,
    e22]], eps_el = E_hom^{-1} ((1 - phi_w) I - K_hom) P1 (docs/model.md section 4); regular
    hexagon: e12 = 0 and e11 = e22 up to the cell mesh's anisotropy (~1e-9). Measured error 7e-12
    relative."""
    scene = load_scene(ROOT / "scenes" / "reference_stress.toml")
    model = macro_model(scene)
    Fg = model.initial_growth()
    model.step(Fg)
    r = cell_tensors(scene, np.eye(2))
    eps_el = exact_elastic_strain(voigt_matrix(r.E_hom), r.K_hom, r.phi_w, scene.P1.start)
    H = exact_displacement_gradient(eps_el, np.eye(2))
    assert H[0, 0] > 0.01  # turgor does stretch the soft reference tissue (1.6%)
    error, scale = displacement_error(model, H)
    print(f"reference scene: max |u - H x| / max |H x| = {error / scale:.2e}")
    assert error <= ROUND_OFF * scale


SHEARED_FG = np.array([[1.15, 0.2], [0.05, 0.95]])  # not symmetric, det = 1.0825


@pytest.fixture(scope="module")
def sheared():
    """A homogeneous strain-law scene with E = 2 and the uniform, non-symmetric growth tensor
    SHEARED_FG (growth.Fg0), first step; cell inputs kept exact (key_tolerance 1e-12, no
    surrogate: cell_tolerance 0)."""
    scene = parse_scene(
        {
            "tissue": {"h": 0.35, "H": 1.0},
            "material": {"E": 2.0, "nu": 0.3},
            "growth": {
                "law": "strain", "eta": 1.5, "tau": 0.0005,
                "Fg0": SHEARED_FG.tolist(),
            },
            "accuracy": {"cell_resolution": 1, "key_tolerance": 1e-12, "cell_tolerance": 0.0},
            "time": {"t_max": 1.0},
        }
    )  # fmt: skip
    model = macro_model(scene)
    Fg = model.initial_growth()
    result = model.step(Fg)
    return scene, model, result, cell_tensors(scene, SHEARED_FG)


def _relative(a: np.ndarray, b: np.ndarray, comm: MPI.Comm) -> float:
    """max |a - b| / max |b| over all ranks."""
    error = comm.allreduce(float(np.abs(a - b).max(initial=0.0)), op=MPI.MAX)
    return error / comm.allreduce(float(np.abs(b).max(initial=0.0)), op=MPI.MAX)


def test_sheared_growth_coefficients_are_the_cell_problem_at_Fg(sheared):
    """Every fine cell carries the cell problem's E_hom, K_hom, phi_w at the uniform Fg (not at
    Fg^T), times E = 2 for E_hom: projection and interpolation of a constant are exact."""
    scene, model, _, r = sheared
    problem = model.problem
    C = problem.cell_values(problem.C).reshape(-1, 3, 3)
    K = problem.cell_values(problem.K).reshape(-1, 2, 2)
    phi_w = problem.cell_values(problem.phi_w)[:, 0]
    assert _relative(C, voigt_matrix(r.E_hom)[None], model.comm) < ROUND_OFF
    assert _relative(K, r.K_hom[None], model.comm) < ROUND_OFF
    assert _relative(phi_w, np.full_like(phi_w, r.phi_w), model.comm) < ROUND_OFF
    # the test can see a transposed Fg: E_hom(Fg^T) differs
    r_T = cell_tensors(scene, SHEARED_FG.T)
    assert _relative(voigt_matrix(r_T.E_hom), voigt_matrix(r.E_hom), model.comm) > 1e-3


def test_sheared_growth_displacement_is_linear(sheared):
    """u = H x with sym(H Fg^{-1}) = eps_el - sym(Fg^{-1}) + I; eps_el has a shear part here
    (E_hom(Fg) is anisotropic), so shear terms of the forms are exercised."""
    _, model, _, r = sheared
    P1 = 0.001
    eps_el = exact_elastic_strain(voigt_matrix(r.E_hom), r.K_hom, r.phi_w, P1)
    assert abs(eps_el[0, 1]) > 0.05 * np.abs(eps_el).max()
    H = exact_displacement_gradient(eps_el, SHEARED_FG)
    Finv = np.linalg.inv(SHEARED_FG)
    assert np.abs(H @ Finv - Finv @ H).max() > 0.05 * np.abs(H).max()  # they do not commute
    error, scale = displacement_error(model, H)
    print(f"sheared growth: max |u - H x| / max |H x| = {error / scale:.2e}")
    assert error <= ROUND_OFF * scale


def test_sheared_growth_stress_and_strain_rate_are_exact(sheared):
    """sigma_hom = (1 - phi_w) P1 I in every cell; the wall-averaged strain eps_hom / phi_w is
    the wall compliance times the wall-averaged stress sigma_hom / phi_w (both are averages of
    the same discrete cell field), so G = eta [(1 - nu)/E (1 - phi_w)/phi_w P1 - tau]_+ I
    exactly, for any Fg, here with E = 2, a non-symmetric Fg and tau > 0."""
    scene, model, result, r = sheared
    P1, E, nu = 0.001, 2.0, 0.3
    sigma = model.problem.cell_values(model.out.sigma).reshape(-1, 2, 2)
    expected_sigma = (1.0 - r.phi_w) * P1 * np.eye(2)
    assert _relative(sigma, expected_sigma[None], model.comm) < ROUND_OFF
    g = scene.growth
    rate = g.eta.start * ((1.0 - nu) / E * (1.0 - r.phi_w) / r.phi_w * P1 - g.tau.start)
    assert rate > 1e-3
    G = result.G
    assert _relative(G, rate * np.eye(2)[None], model.comm) < ROUND_OFF


def test_gradient_E_coefficients_are_E_times_the_reference_cell():
    """E linear in x1 (0.5 -> 2), Fg = I: the coarse nodes carry E(x_node) E_hom(E = 1) and
    their P1 interpolant at a fine cell's midpoint is E(x1_mid) E_hom(E = 1) exactly (linear in
    x1): round-off only. K_hom and phi_w do not depend on E: constant."""
    scene = parse_scene(
        {
            "tissue": {"h": 0.35, "H": 1.0},
            "material": {"E": {"from": 0.5, "to": 2.0}},
            "growth": {"law": "stress"},
            "accuracy": {"cell_resolution": 1},
            "time": {"t_max": 1.0},
        }
    )
    model = macro_model(scene)
    model.step(model.initial_growth())
    problem = model.problem
    solver = CellSolver(HoneycombCell(), 1, MPI.COMM_SELF)
    r = solver.solve(np.eye(2), 1.0, scene.material.nu.start)
    x1, x2 = problem.midpoints[: problem.n_cells, :2].T
    expected = scene.material.E(x1, x2)[:, None, None] * voigt_matrix(r.E_hom)[None]
    C = problem.cell_values(problem.C).reshape(-1, 3, 3)
    E = scene.material.E(x1, x2)
    spread = model.comm.allreduce(E.max(), op=MPI.MAX) - model.comm.allreduce(E.min(), op=MPI.MIN)
    assert spread > 1.0  # the field does vary over the cells
    assert _relative(C, expected, model.comm) < ROUND_OFF
    K = problem.cell_values(problem.K).reshape(-1, 2, 2)
    assert _relative(K, r.K_hom[None], model.comm) < ROUND_OFF
