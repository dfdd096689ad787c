"""Solver for the growth-weighted unit-cell problems (MODEL.md section 3, paper Algorithm 3).

One :class:`CellSolver` owns a periodic unit-cell mesh, its constraints and its compiled forms.
``solve(Fg, E, nu)`` assembles and factorizes the shared bilinear form once and solves the four
right-hand sides ([UC_weak] for b_11, b_22, b_12 and [UCw_weak]); calls with new Fg, E, nu reuse
mesh, constraints and forms.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import dolfinx_mpc
import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.forms import cell_problems
from plantgrowth.forms.elasticity import wall_bilinear_form
from plantgrowth.linear import lu_solver
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.meshes.unit_cell import CELL_TAGS, FACET_TAGS, build_unit_cell_mesh
from plantgrowth.periodic import periodic_constraint
from plantgrowth.tensors import (
    VOIGT_NAMES,
    VOIGT_PAIRS,
    isotropic_tensor,
    orthotropic_moduli,
    unit_strain,
)

DEFAULT_RESOLUTION = 3
"""Elements across a wall (P2): about 0.3% error on moduli for the reference cell."""


@dataclass(frozen=True)
class CellResult:
    """Homogenized quantities of one cell problem (paper [maacro_E], [maacro_K], [P2]).

    Attributes:
        E_hom: (2, 2, 2, 2) effective elasticity tensor.
        K_hom: (2, 2) effective pressure tensor (None if not computed).
        dbar_w: (2, 2, 2, 2) ``dbar[w^ij]_kl`` (i, j symmetric; None if not computed).
        dbar_v: (2, 2) ``dbar[v]`` (None if not computed).
        phi_w: wall fraction |Y_w| / |Y|.
        P2_matrix: (2, 2) M with ``P2vec = M grad(P1)``, or None for a non-hexagonal domain.
        ndofs: global number of unconstrained displacement dofs.
        seconds: wall time of the solve (assembly, factorization, four solves, averages).
    """

    E_hom: np.ndarray
    K_hom: np.ndarray | None
    dbar_w: np.ndarray | None
    dbar_v: np.ndarray | None
    phi_w: float
    P2_matrix: np.ndarray | None
    ndofs: int
    seconds: float

    @property
    def E_voigt(self) -> np.ndarray:
        """The six components {E1111, E2222, E1122, E1212, E1112, E2212}."""
        return np.array([self.E_hom[i, j, k, l] for (i, j), (k, l) in VOIGT_PAIRS])

    def P2vec(self, grad_P1: np.ndarray) -> np.ndarray:
        """``P2vec = (1/|Y|) int_Gamma P2 N`` for ``P2 = -grad(P1) . y`` ([P2], MODEL.md 6)."""
        if self.P2_matrix is None:
            raise ValueError("P2vec is defined on the hexagonal cell only")
        return self.P2_matrix @ np.asarray(grad_P1, dtype=float)

    def summary(self) -> dict:
        """Flat dictionary of the CLI's JSON keys."""
        E = self.E_voigt
        out = dict(zip(VOIGT_NAMES, E.tolist(), strict=True))
        out.update(K11=self.K_hom[0, 0], K22=self.K_hom[1, 1], K12=self.K_hom[0, 1])
        out.update(orthotropic_moduli(E))
        out.update(phi_w=self.phi_w, ndofs=self.ndofs, seconds=self.seconds)
        return {k: (float(v) if k != "ndofs" else int(v)) for k, v in out.items()}


class CellSolver:
    """Periodic unit-cell solver, reusable for many (Fg, E, nu) on one geometry.

    Args:
        cell: the honeycomb parameters.
        resolution: elements across the wall thickness.
        comm: communicator of the cell mesh (``COMM_SELF`` inside the coupled loop).
        shape: fundamental domain, ``"hexagon"`` or ``"parallelogram"``.
        origin: lower-left corner of the parallelogram.
        degree: Lagrange degree of the displacement (P2 resolves wall bending; P1 locks).
    """

    def __init__(
        self,
        cell: HoneycombCell,
        resolution: int = DEFAULT_RESOLUTION,
        comm: MPI.Comm = MPI.COMM_SELF,
        shape: str = "hexagon",
        origin: tuple[float, float] = (0.0, 0.0),
        degree: int = 2,
    ) -> None:
        self.cell = cell
        self.shape = shape
        self.comm = comm
        self.unit_cell = build_unit_cell_mesh(cell, resolution, comm, shape, origin)
        mesh = self.unit_cell.mesh
        self.V = fem.VectorFunctionSpace(mesh, ("Lagrange", degree))
        tol = 1e-3 * self.unit_cell.h
        pin = self.unit_cell.domain.pin_point
        pinned = fem.locate_dofs_geometrical(
            self.V, lambda x: np.hypot(x[0] - pin[0], x[1] - pin[1]) < tol
        )
        self.bcs = [fem.dirichletbc(np.zeros(2, dtype=PETSc.ScalarType), pinned, self.V)]
        self.mpc = periodic_constraint(self.V, self.unit_cell.domain, self.bcs, tol)

        dx = ufl.Measure("dx", domain=mesh, subdomain_data=self.unit_cell.cell_tags)(
            CELL_TAGS["walls"]
        )
        ds = ufl.Measure("ds", domain=mesh, subdomain_data=self.unit_cell.facet_tags)
        self._Fg = fem.Constant(mesh, np.eye(2, dtype=PETSc.ScalarType))
        self._E = fem.Constant(mesh, PETSc.ScalarType(1.0))
        self._nu = fem.Constant(mesh, PETSc.ScalarType(0.3))
        self._b = fem.Constant(mesh, np.zeros((2, 2), dtype=PETSc.ScalarType))
        self._S = fem.Constant(mesh, np.zeros((2, 2), dtype=PETSc.ScalarType))
        z, phi = ufl.TrialFunction(self.V), ufl.TestFunction(self.V)
        self._z = fem.Function(self.mpc.function_space)
        Fg, E, nu = self._Fg, self._E, self._nu
        self.bilinear_form = fem.form(wall_bilinear_form(z, phi, Fg, E, nu, dx))
        self._L_strain = fem.form(cell_problems.cell_strain_rhs(self._b, phi, Fg, E, nu, dx))
        self._L_pressure = fem.form(cell_problems.cell_pressure_rhs(phi, Fg, dx))
        self._stress_avg = fem.form(
            cell_problems.stress_average_form(self._z, self._S, Fg, E, nu, dx)
        )
        self._strain_avg = fem.form(cell_problems.strain_average_form(self._z, self._S, Fg, dx))

        self.area = cell.area
        self.wall_area = self._integrate(fem.form(fem.Constant(mesh, 1.0) * dx))
        self.P2_matrix = None
        if shape == "hexagon":
            x = ufl.SpatialCoordinate(mesh)
            n = ufl.FacetNormal(mesh)
            moment = fem.form(
                cell_problems.membrane_moment_form(self._S, x, n, ds(FACET_TAGS["membrane"]))
            )
            # int_Gamma y_j N_i with the cell centre at the origin; P2 = -grad(P1) . y
            M = np.array(
                [
                    [self._integrate(moment, unit_strain(j, i, sym=False)) for j in range(2)]
                    for i in range(2)
                ]
            )
            self.P2_matrix = -M / self.area

        self.A = dolfinx_mpc.assemble_matrix(self.bilinear_form, self.mpc, bcs=self.bcs)
        self.ksp = lu_solver(self.A, comm, "plantgrowth_cell_", serial="petsc")
        self._rhs = dolfinx_mpc.assemble_vector(self._L_pressure, self.mpc)
        self.ndofs = self.V.dofmap.index_map.size_global * self.V.dofmap.index_map_bs

    def _integrate(self, form: fem.FormMetaClass, selector: np.ndarray | None = None) -> float:
        if selector is not None:
            self._S.value[:] = selector
        return self.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM)

    def _solve_rhs(self, L: fem.FormMetaClass) -> None:
        """Solve A z = L into ``self._z`` (constrained dofs back-substituted)."""
        dolfinx_mpc.assemble_vector(L, self.mpc, b=self._rhs)
        self._rhs.ghostUpdate(addv=PETSc.InsertMode.ADD_VALUES, mode=PETSc.ScatterMode.REVERSE)
        fem.petsc.set_bc(self._rhs, self.bcs)
        self.ksp.solve(self._rhs, self._z.vector)
        self._z.x.scatter_forward()
        self.mpc.backsubstitution(self._z.vector)

    def _averages(self, form: fem.FormMetaClass) -> np.ndarray:
        """(1/|Y|) int_{Y_w} X_kl for the current ``self._z``; X is the form's tensor."""
        return (
            np.array(
                [[self._integrate(form, unit_strain(k, l)) for l in range(2)] for k in range(2)]
            )
            / self.area
        )

    def solve(
        self,
        Fg: np.ndarray | None = None,
        E: float = 1.0,
        nu: float = 0.3,
        pressure: bool = True,
        strain_averages: bool = True,
    ) -> CellResult:
        """Homogenize for the growth tensor Fg and wall moduli (E, nu).

        Returns E_hom ([maacro_E]) and, when asked for, K_hom ([maacro_K], the pressure problem
        [UCw_weak]) and the strain averages dbar[w^ij], dbar[v] (needed by the strain law only);
        what is not asked for is not computed and is None in the result.
        """
        start = time.perf_counter()
        self._Fg.value[:] = np.eye(2) if Fg is None else np.asarray(Fg, dtype=float)
        self._E.value = E
        self._nu.value = nu
        dolfinx_mpc.assemble_matrix(self.bilinear_form, self.mpc, bcs=self.bcs, A=self.A)
        self.ksp.setOperators(self.A)
        self.ksp.setUp()

        wall = isotropic_tensor(E, nu)
        phi_w = self.wall_area / self.area
        E_hom = np.zeros((2, 2, 2, 2))
        dbar_w = np.zeros((2, 2, 2, 2)) if strain_averages else None
        for i, j in ((0, 0), (1, 1), (0, 1)):
            b = unit_strain(i, j)
            self._b.value[:] = b
            self._solve_rhs(self._L_strain)
            E_hom[i, j] = E_hom[j, i] = phi_w * np.einsum("klmn,mn->kl", wall, b) + self._averages(
                self._stress_avg
            )
            if strain_averages:
                dbar_w[i, j] = dbar_w[j, i] = self._averages(self._strain_avg)
        K_hom = dbar_v = None
        if pressure:
            self._solve_rhs(self._L_pressure)
            K_hom = self._averages(self._stress_avg)
            dbar_v = self._averages(self._strain_avg) if strain_averages else None
        seconds = self.comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
        return CellResult(E_hom, K_hom, dbar_w, dbar_v, phi_w, self.P2_matrix, self.ndofs, seconds)
