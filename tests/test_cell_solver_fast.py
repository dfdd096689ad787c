"""The basis path of ``CellSolver.solve`` equals a direct assembly of the UFL forms.

``CellSolver`` builds the cell problems of docs/model.md section 3 from integrals assembled once per
geometry (``GradientBasis``: the matrix as a weighted sum of ten products, the right-hand sides
and averages from four moments). The reference here is the direct route, written with the forms
of ``forms.cell_problems`` as docs/model.md section 3 states them: dolfinx_mpc assembles
[UC_weak]/[UCw_weak] for the given Fg, E, nu, PETSc factorizes (LU on one rank, MUMPS on several),
and the averages are ``fem.assemble_scalar`` of the stress and strain average forms, component by
component. Fibred cells (walls split by segment family, docs/model.md "Fibre-reinforced walls")
are compared the same way, the reference's wall tensor being the UFL ``walls_stress`` with its
own fibre coefficients.

Tolerances: the two routes assemble the same matrix up to the summation order (measured
<= 1.1e-15 relative to the largest entry) and then factorize it differently (Cholesky in nested
dissection order, or MUMPS, against PETSc's LU). The homogenized quantities are energy
averages; measured differences are <= 2.4e-13 relative to the largest component, and we allow
the 1e-10 that ``test_cell_solver.py`` allows for round-off.
"""

from __future__ import annotations

import dolfinx_mpc
import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.base.tensors import director, isotropic_tensor, unit_strain
from plantgrowth.forms import cell_problems
from plantgrowth.forms.elasticity import Fibres, lame_parameters, wall_bilinear_form
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.models.linear import lu_solver
from plantgrowth.unitcell.solver import STRAIN_PROBLEMS, CellSolver, tensor_weights

# round-off of two direct factorizations of the same matrix (see the module docstring)
ROUND_OFF = 1e-10
# two assemblies of the same matrix differ by summation order only: a few ulps of the largest entry
ASSEMBLY_ROUND_OFF = 1e-13


def _rotation(t: float) -> np.ndarray:
    return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])


CASES = [
    (np.eye(2), 1.0, 0.3),
    (np.diag([1.5, 1.0]), 2.0, 0.1),
    (np.array([[1.2, 0.3], [0.0, 1.0]]), 0.7, 0.45),
    (1.3 * _rotation(0.4), 1.0, 0.0),
    (np.array([[1.1, -0.2], [0.35, 0.8]]) @ _rotation(-1.1), 1.5, 0.3),
]
CASE_IDS = ["identity", "grown", "sheared", "rotated", "general"]
FIBRES = [(0.0, 0.0), (5.0, 90.0), (1.0, 17.0), (20.0, -40.0), (2.5, 133.0)]
"""(fibre_stiffness, fibre_angle) of each case on a fibred cell (0: isotropic, on split walls)."""
GEOMETRIES = {
    # (cell, resolution, shape, origin, fibres)
    "elongated-hexagon": (HoneycombCell(l1=1.5, theta_deg=40.0), 1, "hexagon", (0.0, 0.0), False),
    "parallelogram": (HoneycombCell(w=0.1), 1, "parallelogram", (0.1, -0.45), False),
    "reference-res2": (HoneycombCell(), 2, "hexagon", (0.0, 0.0), False),
    "fibred-hexagon": (HoneycombCell(l1=1.5, theta_deg=40.0), 1, "hexagon", (0.0, 0.0), True),
    "fibred-parallelogram": (HoneycombCell(w=0.1), 1, "parallelogram", (0.1, -0.45), True),
}
COMMS = {"world": MPI.COMM_WORLD, "self": MPI.COMM_SELF}


class _Reference:
    """The direct route: the UFL forms of [UC_weak], [UCw_weak] and the averages, assembled for
    each (Fg, E, nu) on the solver's mesh, constraint and Dirichlet condition."""

    def __init__(self, solver: CellSolver) -> None:
        self.solver = solver
        mesh = solver.unit_cell.mesh
        dx = solver.dx
        self.Fg = fem.Constant(mesh, np.eye(2))
        self.E = fem.Constant(mesh, 1.0)
        self.nu = fem.Constant(mesh, 0.3)
        self.b = fem.Constant(mesh, np.zeros((2, 2)))
        self.S = fem.Constant(mesh, np.zeros((2, 2)))
        self.fibres = None
        if solver.fibres:  # E_f, m: the reference's own; t: the tangent of each wall cell
            tangent = solver.fibre_coefficients.tangent
            self.fibres = Fibres(fem.Constant(mesh, 0.0), fem.Constant(mesh, np.zeros(2)), tangent)
        z, phi = ufl.TrialFunction(solver.V), ufl.TestFunction(solver.V)
        self.z = fem.Function(solver.mpc.function_space)
        Fg, E, nu, fibres = self.Fg, self.E, self.nu, self.fibres
        self.a = fem.form(wall_bilinear_form(z, phi, Fg, E, nu, dx, fibres))
        self.L_strain = fem.form(cell_problems.cell_strain_rhs(self.b, phi, Fg, E, nu, dx, fibres))
        self.L_pressure = fem.form(cell_problems.cell_pressure_rhs(phi, Fg, dx))
        self.stress_average = fem.form(
            cell_problems.stress_average_form(self.z, self.S, Fg, E, nu, dx, fibres)
        )
        self.wall_average = fem.form(
            cell_problems.wall_average_form(self.b, self.S, Fg, E, nu, dx, fibres)
        )
        self.strain_average = fem.form(cell_problems.strain_average_form(self.z, self.S, Fg, dx))

    def matrix(self, Fg: np.ndarray, E: float, nu: float, fibres=(0.0, 0.0)) -> PETSc.Mat:
        self.Fg.value[:] = Fg
        self.E.value = E
        self.nu.value = nu
        if self.fibres is not None:
            self.fibres.stiffness.value = fibres[0] * E
            self.fibres.director.value[:] = director(fibres[1])
        s = self.solver
        return dolfinx_mpc.assemble_matrix(self.a, s.mpc, bcs=s.bcs)

    def _average(self, form: fem.FormMetaClass) -> np.ndarray:
        values = np.zeros((2, 2))
        for k in range(2):
            for l in range(2):
                self.S.value[:] = unit_strain(k, l)
                values[k, l] = self.solver.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM)
        return values / self.solver.area

    def _solve(self, ksp: PETSc.KSP, L: fem.FormMetaClass) -> None:
        s = self.solver
        b = dolfinx_mpc.assemble_vector(L, s.mpc)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD_VALUES, mode=PETSc.ScatterMode.REVERSE)
        fem.petsc.set_bc(b, s.bcs)
        ksp.solve(b, self.z.vector)
        self.z.x.scatter_forward()
        s.mpc.backsubstitution(self.z.vector)
        b.destroy()

    def solve(self, Fg: np.ndarray, E: float, nu: float, fibres=(0.0, 0.0)) -> dict:
        """E_hom, K_hom, dbar_w, dbar_v; the pressure corrector v stays in ``self.z``."""
        A = self.matrix(Fg, E, nu, fibres)
        ksp = lu_solver(A, self.solver.comm, "test_cell_reference_", serial="petsc")
        out = {"E_hom": np.zeros((2, 2, 2, 2)), "dbar_w": np.zeros((2, 2, 2, 2))}
        for i, j in STRAIN_PROBLEMS:
            self.b.value[:] = unit_strain(i, j)
            self._solve(ksp, self.L_strain)
            E_ij = self._average(self.wall_average)  # (1/|Y|) int C_w[b_ij]
            out["E_hom"][i, j] = out["E_hom"][j, i] = E_ij + self._average(self.stress_average)
            out["dbar_w"][i, j] = out["dbar_w"][j, i] = self._average(self.strain_average)
        self._solve(ksp, self.L_pressure)
        out["K_hom"] = self._average(self.stress_average)
        out["dbar_v"] = self._average(self.strain_average)
        ksp.destroy()
        A.destroy()
        return out


@pytest.fixture(scope="module")
def pair():
    """``pair(geometry, comm)``: a CellSolver and its _Reference, one per key."""
    cache: dict = {}

    def get(geometry: str, comm: str) -> tuple[CellSolver, _Reference]:
        key = (geometry, comm)
        if key not in cache:
            cell, resolution, shape, origin, fibres = GEOMETRIES[geometry]
            solver = CellSolver(
                cell, resolution, COMMS[comm], shape=shape, origin=origin, fibres=fibres
            )
            cache[key] = (solver, _Reference(solver))
        return cache[key]

    yield get
    cache.clear()


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    """Largest component difference relative to the largest component."""
    return float(np.abs(a - b).max() / np.abs(b).max())


def test_stiffness_weights_are_the_lame_expansion():
    """S[(i, a), (j, c)] = Jg (lam G_ai G_cj + mu (delta_ij (G G^T)_ac + G_aj G_ci)), G = Fg^-1:
    the coefficients of ``int d_a z_i d_c phi_j`` in [UC_weak]'s bilinear form (pure arithmetic:
    relative 1e-14)."""
    rng = np.random.default_rng(3)
    d = np.eye(2)
    for _ in range(10):
        Fg = np.eye(2) + 0.4 * rng.standard_normal((2, 2))
        E, nu = rng.uniform(0.5, 2.0), rng.uniform(0.0, 0.45)
        G, Jg = np.linalg.inv(Fg), np.linalg.det(Fg)
        mu, lam = lame_parameters(E, nu)
        coeff = Jg * (
            lam * np.einsum("ai,cj->aicj", G, G)
            + mu * (np.einsum("ij,ac->aicj", d, G @ G.T) + np.einsum("aj,ci->aicj", G, G))
        )
        expected = coeff.transpose(1, 0, 3, 2).reshape(4, 4)  # rows (i, a), columns (j, c)
        S = tensor_weights(Fg, isotropic_tensor(E, nu))
        assert _rel(S, expected) < 1e-14
        assert _rel(S, S.T) < 1e-15


@pytest.mark.mpi
@pytest.mark.parametrize("comm", COMMS)
@pytest.mark.parametrize("geometry", GEOMETRIES)
def test_matrix_equals_direct_assembly(pair, geometry, comm):
    """After a solve, ``A`` (the weighted sum of the basis, in dof order) equals dolfinx_mpc's
    assembly of the bilinear form, unit diagonal of Dirichlet and slave rows included: same
    pattern, values equal up to summation order."""
    solver, reference = pair(geometry, comm)
    for (Fg, E, nu), fibres in zip(CASES, FIBRES, strict=True):
        fibres = fibres if solver.fibres else (0.0, 0.0)
        solver.solve(Fg, E, nu, fibre_stiffness=fibres[0], fibre_angle=fibres[1])
        A, A_ref = solver.A, reference.matrix(Fg, E, nu, fibres)
        I, J, V = A.getValuesCSR()  # the owned rows, same layout on each rank
        I_ref, J_ref, V_ref = A_ref.getValuesCSR()
        np.testing.assert_array_equal(I, I_ref)
        np.testing.assert_array_equal(J, J_ref)
        scale = solver.comm.allreduce(np.abs(V_ref).max(), op=MPI.MAX)
        assert np.abs(V - V_ref).max() < ASSEMBLY_ROUND_OFF * scale
        A.destroy()
        A_ref.destroy()


@pytest.mark.parametrize("comm", COMMS)
@pytest.mark.parametrize("geometry", GEOMETRIES)
@pytest.mark.parametrize("case", range(len(CASES)), ids=CASE_IDS)
def test_solve_equals_direct_assembly(pair, geometry, comm, case):
    """E_hom, K_hom, dbar_w, dbar_v of every flag combination equal the reference's; what is not
    asked for is None."""
    solver, reference = pair(geometry, comm)
    Fg, E, nu = CASES[case]
    fibres = FIBRES[case] if solver.fibres else (0.0, 0.0)
    expected = reference.solve(Fg, E, nu, fibres)
    for pressure in (True, False):
        for strain_averages in (True, False):
            r = solver.solve(Fg, E, nu, pressure, strain_averages, *fibres)
            asked = {
                "E_hom": True,
                "K_hom": pressure,
                "dbar_w": strain_averages,
                "dbar_v": pressure and strain_averages,
            }
            for name, present in asked.items():
                value = getattr(r, name)
                if not present:
                    assert value is None, name
                    continue
                assert _rel(value, expected[name]) < ROUND_OFF, (name, pressure, strain_averages)


@pytest.mark.mpi
@pytest.mark.parametrize("comm", COMMS)
def test_last_solution_is_the_pressure_corrector(pair, comm):
    """The field left in the solver is the back-substituted pressure corrector v of the reference.

    A displacement, unlike an energy average, feels the condition number (~1e8 for thin P2
    walls) times the round-off of the two factorizations: measured <= 3.2e-12 relative on the
    geometries here; 1e-8 allowed."""
    solver, reference = pair("elongated-hexagon", comm)
    Fg, E, nu = CASES[-1]
    reference.solve(Fg, E, nu)
    solver.solve(Fg, E, nu)
    v, v_ref = solver._z.x.array, reference.z.x.array
    scale = solver.comm.allreduce(np.abs(v_ref).max(), op=MPI.MAX)
    error = solver.comm.allreduce(np.abs(v - v_ref).max(), op=MPI.MAX)
    assert error < 1e-8 * scale
