"""The unit cell's hydraulic coefficients (docs/model.md, "Water fluxes"): the Biot tensor b, the
storage 1/M and the conductivity kappa per unit wall conductivity L.

The identities checked here hold exactly for the discrete cell solutions, on any mesh: the
lumen's area change computed on the membrane equals ``b : e + P/M`` (the divergence theorem is
exact for the piecewise polynomial correctors on the straight-sided wall mesh, the constrained
space is exactly periodic, and the bilinear form is symmetric), and ``1/M`` is the energy of v.
Their residuals are solver round-off: one LU solve of a system of condition number up to ~1e8
(thin walls, P2); measured at most 1.7e-15 on one rank and 0.9e-15 on two (absolute, on
quantities of order 0.1 to 1) for the area change, 9.4e-15 and 4.6e-15 (relative) for 1/M
against the energy of v. ROUND_OFF = 1e-10, what tests/test_cell_solver.py allows for its
exact identities, leaves the margin for thinner walls. kappa is a closed form: it is checked
to 1e-14, a few ulps of its O(1) entries.
"""

from __future__ import annotations

import numpy as np
import pytest
from dolfinx import fem
from mpi4py import MPI

from plantgrowth.base.errors import InputError
from plantgrowth.forms import cell_problems
from plantgrowth.forms.elasticity import sym_grad_g
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.unitcell.hydraulic_coefficients import (
    biot_tensor,
    conductivity,
    lumen_area_change,
    storage,
)
from plantgrowth.unitcell.solver import CellSolver

ROUND_OFF = 1e-10
CLOSED_FORM = 1e-14
RESOLUTION = 2  # the identities hold on any mesh: the cheapest that resolves the walls


def _rotation(t: float) -> np.ndarray:
    return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])


ANISOTROPIC = np.array([[1.3, 0.1], [0.0, 0.9]])
CASES = {
    # Fg, cell, (fibre_stiffness, fibre_angle) or None for isotropic walls
    "identity": (np.eye(2), HoneycombCell(), None),
    "anisotropic": (ANISOTROPIC, HoneycombCell(), None),
    "rotated": (_rotation(0.7) @ ANISOTROPIC, HoneycombCell(), None),
    "elongated-cell": (ANISOTROPIC, HoneycombCell(l1=1.5, theta_deg=40.0, w=0.08), None),
    "fibred": (ANISOTROPIC, HoneycombCell(), (5.0, 20.0)),
}
LOADS = [  # (e, P): a stretch, a shear with turgor, turgor alone
    (np.array([[1.0, 0.0], [0.0, 0.0]]), 0.0),
    (np.array([[0.3, 0.2], [0.2, -0.5]]), 0.7),
    (np.zeros((2, 2)), 1.0),
]


@pytest.fixture(scope="module")
def solved():
    """``solved(name)``: (solver, result, Fg) of a case, each solver built once."""
    cache: dict = {}

    def get(name: str):
        if name not in cache:
            Fg, cell, fibres = CASES[name]
            solver = CellSolver(cell, RESOLUTION, MPI.COMM_WORLD, fibres=fibres is not None)
            extra = {} if fibres is None else dict(fibre_stiffness=fibres[0], fibre_angle=fibres[1])
            cache[name] = (solver, solver.solve(Fg, 1.0, 0.3, **extra), Fg)
        return cache[name]

    yield get
    cache.clear()


@pytest.mark.mpi
@pytest.mark.parametrize("name", CASES)
def test_lumen_area_change_on_the_membrane_is_b_e_plus_P_over_M(solved, name):
    """The derivation of b and 1/M: the membrane integral (its own measure, growth-weighted
    normal) against the averages the solver computes from K_hom and dbar[v]."""
    solver, result, Fg = solved(name)
    b, inv_M = biot_tensor(result), storage(result)
    for e, P in LOADS:
        direct = lumen_area_change(solver, Fg, e, P)
        assert direct == pytest.approx(np.sum(b * e) + P * inv_M, abs=ROUND_OFF), (e, P)
    # the macro strain's own term is the lumen fraction 1 - phi_w: b differs from it by K_hom
    assert np.abs(b - (1.0 - result.phi_w) * np.eye(2)).max() > 1e-2


@pytest.mark.mpi
@pytest.mark.parametrize("name", CASES)
def test_storage_is_positive_and_the_energy_of_v(solved, name):
    """``1/M = -tr dbar[v] = (1/|Y|) int C_w[d[v]] : d[v] > 0`` (v tested with itself)."""
    solver, result, Fg = solved(name)
    v = solver.correctors()[3]
    mesh = solver.unit_cell.mesh
    F = fem.Constant(mesh, Fg)
    E, nu = fem.Constant(mesh, 1.0), fem.Constant(mesh, 0.3)
    d_v = sym_grad_g(v, F)
    energy = fem.form(
        cell_problems.stress_average_form(v, d_v, F, E, nu, solver.dx, solver.fibre_coefficients)
    )
    energy = solver.comm.allreduce(fem.assemble_scalar(energy), op=MPI.SUM) / solver.area
    inv_M = storage(result)
    assert inv_M > 0.0
    assert inv_M == pytest.approx(energy, rel=ROUND_OFF)


def test_regular_cell_values():
    """Regular hexagon (w = 0.05, E = 1, nu = 0.3): b = beta I (isotropic like K_hom), 1/M as
    measured at resolution 2 (0.098316; resolution 3 gives 0.098357: a discretization
    difference, which the identities above do not depend on), ``beta = 1 - phi_w - K11``."""
    solver = CellSolver(HoneycombCell(), RESOLUTION, MPI.COMM_SELF)
    result = solver.solve(np.eye(2), 1.0, 0.3)
    b = biot_tensor(result)
    np.testing.assert_allclose(b, b[0, 0] * np.eye(2), atol=ROUND_OFF)
    assert b[0, 0] == pytest.approx(1.0 - HoneycombCell().phi_w - result.K_hom[0, 0], rel=1e-12)
    assert storage(result) == pytest.approx(0.0983163, rel=1e-6)  # printed digits


def test_b_and_storage_follow_the_exact_invariances():
    """What the surrogate may rely on: Fg -> g Fg changes neither; a rotation R Fg turns b into
    R b R^T and leaves 1/M; E -> 2 E halves 1/M and leaves b (all exact in the discrete
    problem: round-off)."""
    solver = CellSolver(HoneycombCell(l1=1.5, theta_deg=40.0), RESOLUTION, MPI.COMM_SELF)
    base = solver.solve(ANISOTROPIC, 1.0, 0.3)
    b0, m0 = biot_tensor(base), storage(base)
    scaled = solver.solve(1.7 * ANISOTROPIC, 1.0, 0.3)
    R = _rotation(0.9)
    rotated = solver.solve(R @ ANISOTROPIC, 1.0, 0.3)
    stiffer = solver.solve(ANISOTROPIC, 2.0, 0.3)
    np.testing.assert_allclose(biot_tensor(scaled), b0, atol=ROUND_OFF)
    np.testing.assert_allclose(biot_tensor(rotated), R @ b0 @ R.T, atol=ROUND_OFF)
    np.testing.assert_allclose(biot_tensor(stiffer), b0, atol=ROUND_OFF)
    assert storage(scaled) == pytest.approx(m0, rel=ROUND_OFF)
    assert storage(rotated) == pytest.approx(m0, rel=ROUND_OFF)
    assert storage(stiffer) == pytest.approx(m0 / 2.0, rel=ROUND_OFF)


# --- kappa ------------------------------------------------------------------------------------


def _network_conductivity(cell: HoneycombCell, Fg: np.ndarray) -> np.ndarray:
    """kappa / L from the hexagon's six sides: the wall whose mid-point is d/2 joins the cell
    to its neighbour at d; a flux ``L ell (Fg d) . grad(psi)`` through each, half of it the
    cell's (every wall is shared)."""
    hexagon = cell.hexagon()
    kappa = np.zeros((2, 2))
    for a, b in zip(hexagon, np.roll(hexagon, -1, axis=0), strict=True):
        d = a + b  # twice the side's mid-point: the lattice vector across it
        ell = np.linalg.norm(Fg @ (b - a))
        kappa += 0.5 * ell * np.outer(Fg @ d, Fg @ d)
    return kappa / (np.linalg.det(Fg) * cell.area)


def test_kappa_of_the_regular_hexagon_is_sqrt3_I():
    np.testing.assert_allclose(
        conductivity(HoneycombCell(), np.eye(2)), np.sqrt(3.0) * np.eye(2), atol=CLOSED_FORM
    )


@pytest.mark.parametrize(
    "cell", [HoneycombCell(), HoneycombCell(l1=1.5, l2=0.8, theta_deg=40.0)],
    ids=["regular", "elongated"],
)  # fmt: skip
@pytest.mark.parametrize(
    "Fg", [np.eye(2), ANISOTROPIC, _rotation(0.7) @ ANISOTROPIC, np.diag([2.0, 1.0])],
    ids=["identity", "anisotropic", "rotated", "grown-x1"],
)  # fmt: skip
def test_kappa_is_the_wall_network_of_the_hexagon(cell, Fg):
    """The lattice vectors paired with the right wall families (each b_k with the tangent of
    the walls it crosses: a wrong pairing differs once Fg stretches the families unequally)."""
    np.testing.assert_allclose(conductivity(cell, Fg), _network_conductivity(cell, Fg),
                               rtol=CLOSED_FORM, atol=CLOSED_FORM)  # fmt: skip


def test_kappa_transforms_with_the_growth_tensor():
    """Fg = R: the grown lattice is the rotated one, kappa = R kappa(I) R^T. Fg = s I: walls s
    times longer, s times farther apart, on s^2 times the area: kappa = s^3 / s^2 kappa(I) =
    s kappa(I) (fewer walls across a unit length, each passing s^2 more). So kappa(g Fg) =
    g kappa(Fg): kappa does not have the Fg -> Fg / sqrt(det Fg) invariance of b and 1/M."""
    cell = HoneycombCell(l1=1.5, l2=0.8, theta_deg=40.0)
    kappa0 = conductivity(cell, np.eye(2))
    R = _rotation(0.7)
    np.testing.assert_allclose(conductivity(cell, R), R @ kappa0 @ R.T, atol=CLOSED_FORM)
    np.testing.assert_allclose(conductivity(cell, 1.6 * np.eye(2)), 1.6 * kappa0, atol=CLOSED_FORM)
    np.testing.assert_allclose(
        conductivity(cell, 1.6 * ANISOTROPIC), 1.6 * conductivity(cell, ANISOTROPIC),
        atol=CLOSED_FORM,
    )  # fmt: skip
    # growth along x1 conducts better along x1 (longer walls across it) and worse along x2
    grown = conductivity(cell, np.diag([2.0, 1.0]))
    assert grown[0, 0] > kappa0[0, 0] and grown[1, 1] < kappa0[1, 1]


# --- bad input --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "Fg", [[[1.0, 0.0], [0.0, -1.0]], [[1.0, 0.0], [0.0, np.nan]], [1.0, 0.0]],
    ids=["det<0", "nan", "shape"],
)  # fmt: skip
def test_conductivity_rejects_a_bad_growth_tensor(Fg):
    with pytest.raises(InputError, match="Fg"):
        conductivity(HoneycombCell(), Fg)


def test_coefficients_name_what_the_solve_left_out():
    solver = CellSolver(HoneycombCell(), 1, MPI.COMM_SELF)
    with pytest.raises(ValueError, match="solve"):
        solver.correctors()
    no_pressure = solver.solve(np.eye(2), 1.0, 0.3, pressure=False)
    with pytest.raises(ValueError, match="pressure"):
        biot_tensor(no_pressure)
    with pytest.raises(ValueError, match="pressure=True"):
        lumen_area_change(solver, np.eye(2), np.eye(2), 1.0)
    solver.solve(np.eye(2), 1.0, 0.3)
    for e in (np.array([[0.0, 1.0], [0.0, 0.0]]), np.eye(3)):
        with pytest.raises(ValueError, match="symmetric 2x2 strain"):
            lumen_area_change(solver, np.eye(2), e, 1.0)
    with pytest.raises(ValueError, match="strain_averages"):
        storage(solver.solve(np.eye(2), 1.0, 0.3, strain_averages=False))
    sheared = CellSolver(HoneycombCell(w=0.1), 1, MPI.COMM_SELF, shape="parallelogram",
                         origin=(0.1, -0.45))  # fmt: skip
    sheared.solve(np.eye(2), 1.0, 0.3)
    with pytest.raises(ValueError, match="hexagon"):
        lumen_area_change(sheared, np.eye(2), np.eye(2), 1.0)
