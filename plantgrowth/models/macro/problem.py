"""The macroscopic elasticity problem on the fine mesh m (docs/model.md section 4, Algorithm 2).

P1 displacement; every coefficient (Fg, E_hom, K_hom, phi_w, P2vec) is piecewise constant on
the fine cells, so the forms are integrated exactly by one-point quadrature. Only the terms
the scene activates are assembled. Boundary conditions (plantgrowth/models/macro/boundary.py): ``u2
= 0`` on the symmetry edges x2 = 0 (no tangential traction), ``u = 0`` or its normal component 0
on the held edges (``[supports]``) and, unless a held edge holds u1, ``u1 = 0`` at the pinned
vertex (the origin of the rectangle; removes the remaining rigid translation); the other edges
carry the scene's tractions or none. The operator is
symmetric positive definite after these conditions, so large systems are solved by CG + BoomerAMG
(``solver.macro``), small ones by LU; a finite-kinematics Jacobian is not (GMRES + GAMG, then
LU where GMRES stops).
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.base.errors import RunError
from plantgrowth.base.tensors import inv2
from plantgrowth.forms import finite, macro
from plantgrowth.forms.elasticity import boundary_traction, grown_length
from plantgrowth.models import growth, stability
from plantgrowth.models.diagnostics import RESIDUAL_BOUND, TRUE_RESIDUAL_FACTOR
from plantgrowth.models.factor_reuse import FactorReuse
from plantgrowth.models.linear import (
    SPARE_FACTOR,
    SolveReport,
    assemble_and_solve,
    assemble_matrix,
    boomeramg_cg_solver,
    gamg_solver,
    lu_solver,
)
from plantgrowth.models.macro.boundary import Boundary, pinned_vertices, rectangle_boundary
from plantgrowth.models.macro.edge_loads import FORCE_LENGTH_RTOL, EdgeLoads
from plantgrowth.models.macro.supports import HeldEdges
from plantgrowth.models.newton import (
    NEWTON_ATOL,
    NewtonReport,
    NewtonSolver,
    global_extreme,
    log_report,
)
from plantgrowth.models.preconditioner_reuse import PreconditionerReuse
from plantgrowth.models.solution_history import SolutionHistory
from plantgrowth.models.turgor_ramp import solve_ramped
from plantgrowth.scene import Scene

log = logging.getLogger("plantgrowth")

NEWTON_KRYLOV_RTOL = 1e-10
"""GMRES's relative tolerance on a Newton step's ``|b - J du| / |b|``: 100 times below the residual
bound (diagnostics.RESIDUAL_BOUND), so that the true residual, which drifts from GMRES's
recursive one, passes it. (The linear CG solve stops at ``solver.macro_rtol``.)"""
MACRO_MAX_IT = 2000
"""CG's iteration limit: about 100 iterations at any size on the shipped scenes, 700 on the
thinnest-walled hard case (w = 0.005); a solve that needs more stops with a RunError."""
REBUILD_GROWTH = 1.5
"""CG's multigrid hierarchy is kept across steps and rebuilt once a solve needs more than 1.5 times
(and REBUILD_SETUP more than) the fewest iterations of a solve since the last rebuild
(plantgrowth.models.preconditioner_reuse; measured in docs/large_tissues.md, "Macro solve sized
by accuracy")."""
REBUILD_SETUP = 3
"""BoomerAMG's set-up in CG iterations: 0.80 s against 0.33 s an iteration on the organ system
(2 ranks, docs/large_tissues.md's preconditioner table), rounded up: fewer extra iterations
than this do not pay for a rebuild."""
HISTORY = 5
"""CG starts from the energy-norm projection onto the last 5 solutions (plantgrowth.models.
solution_history): on the organ scene (2 ranks, 1e-8) 2-5 iterations a step at steps 4-15,
against 6 with 3 solutions, 19-20 with 1 and 26-27 from the previous u as it is. With issue 33's
continuous surrogate 15-17 at steps that refine it (16, 22, 24, 34), 8 after them, and 8-12 at
every other step from 27 on: the projection predicts what moves smoothly in time, and the cells'
tensors jump where a refinement adds points and turn wherever a cell crosses a line of the
piecewise-bilinear interpolant. On gradient_E_strain forced onto CG, a cubic fit in s of the same
lattice values needs 2-4 at every step from 16 on, against 7-15, and on the organ 2-5 at steps
16-36 against 4-17 (docs/large_tissues.md, "Macro solve sized by accuracy";
scripts/benchmarks/bench_cg_steps.py)."""
SERIAL_LU = "petsc"
"""The linear macro problem's LU on one rank: PETSc's own (nested-dissection ordering; the matrix
is symmetric positive definite, so no pivoting is needed), MUMPS on several. On the reference
scene (4,340 dofs) the solve phase took 0.58 s over 61 steps against MUMPS's 0.77 s, results
within 1.2e-11 in u and 4e-10 in elastic_strain_max of MUMPS's (docs/large_tissues.md,
"Start-up"). Newton's Jacobians keep MUMPS."""
CG_MATRIX = "baij"
"""The CG path's matrix format: PETSc's block CSR in the 2 x 2 node blocks of the P1 vector
dofmap, whose blocks dolfinx inserts whole (one index per block instead of four). On the 1e5-dof
tissue of the scaling study (t = 0-10, CG) the solve phase took 0.146 s a step against AIJ's
0.171 on 1 rank and 0.0995 against 0.1075 on 2 (assembly, CG's products), with the same CG
iterations and summaries within 3.2e-10 (elastic_strain_max; docs/large_tissues.md, "The CG
matrix in 2 x 2 blocks"); BoomerAMG converts it to hypre's CSR when it builds its hierarchy.
LU keeps AIJ (PETSc's serial LU and its kept factors, which hold the reference scene to 7c43f7c's
results)."""
PREFIX = "plantgrowth_macro_"
NEWTON_PREFIX = PREFIX + "newton_"  # its own GAMG options (see linear.gamg_solver)
NEWTON_KRYLOV_MAX_IT = 500
"""GMRES iterations on a Newton step before LU takes over (NewtonSolver's fallback): 5 times
the 90-111 a solve needs on gradient_E_strain with finite kinematics."""
MAX_FORCE_UPDATES = 10
"""Newton solves after the first that may still move a total force's traction ``F / L``."""


def mesh_bounding_box(msh: mesh.Mesh) -> tuple[float, float]:
    """Collective: (width, height) of the mesh, whose bounding box starts at the origin."""
    x = msh.geometry.x
    top = [float(x[:, i].max()) if len(x) else 0.0 for i in range(2)]
    width, height = (msh.comm.allreduce(v, op=MPI.MAX) for v in top)
    return width, height


def rectangle_mesh(scene: Scene, comm: MPI.Comm) -> mesh.Mesh:
    """The stand-alone macro domain ``[0, width] x [0, height]`` with edges about ``h``."""
    t = scene.tissue
    nx, ny = max(1, round(t.width / t.h)), max(1, round(t.height / t.h))
    corners = [np.zeros(2), np.array([t.width, t.height])]
    return mesh.create_rectangle(comm, corners, [nx, ny], mesh.CellType.triangle)


def global_cell_vertices(msh: mesh.Mesh, n: int) -> np.ndarray:
    """(n, 3) the global indices of the first n cells' vertices (the same on every rank
    count: what connects fine cells across ranks, plantgrowth.models.nonelliptic_sets)."""
    local = msh.topology.connectivity(2, 0).array.reshape(-1, 3)[:n]
    return msh.topology.index_map(0).local_to_global(local.reshape(-1)).reshape(-1, 3)


class MacroProblem:
    """Fine mesh, pruned forms, boundary conditions and linear solver of the macro problem.

    Args:
        scene: the scene (pressure field, loads).
        msh: the fine mesh.
        boundary: its symmetry facets, pinned vertex and loadable edges; default: the scene's
            rectangle (bottom edge on x2 = 0, a vertex at the origin).
        water: u is solved with P by a :class:`~plantgrowth.models.macro.water.MacroWater`:
            the forms, matrix and solver of u alone are not built (``ksp`` stays None).
    """

    def __init__(
        self, scene: Scene, msh: mesh.Mesh, boundary: Boundary | None = None, water: bool = False
    ) -> None:
        self.mesh = msh
        self.boundary = boundary or rectangle_boundary(msh, scene.tissue.width, scene.tissue.height)
        comm = msh.comm
        self.V = fem.VectorFunctionSpace(msh, ("Lagrange", 1))
        self.Q0 = fem.FunctionSpace(msh, ("DG", 0))
        self.T0 = fem.TensorFunctionSpace(msh, ("DG", 0))
        self.u = fem.Function(self.V, name="u")
        self.Fg = fem.Function(self.T0, name="Fg")
        self.C = fem.Function(fem.TensorFunctionSpace(msh, ("DG", 0), shape=(3, 3)), name="C")
        self.phi_w = fem.Function(self.Q0, name="phi_w")

        cells = msh.topology.index_map(2)
        self.n_cells = cells.size_local + cells.num_ghosts
        self.n_owned = cells.size_local
        self._dg0_dofs: dict[int, tuple] = {}  # id(space) -> (space, its cells' dofs)
        self.midpoints = mesh.compute_midpoints(msh, 2, np.arange(self.n_cells, dtype=np.int32))
        area_form = fem.form(ufl.TestFunction(self.Q0) * ufl.dx)
        areas = fem.petsc.assemble_vector(area_form)
        self.areas = areas.array[self.Q0.dofmap.list.array[: self.n_owned]].copy()
        self.total_area = comm.allreduce(self.areas.sum(), op=MPI.SUM)
        self.bounding_box = mesh_bounding_box(msh)
        self.cell_vertices = global_cell_vertices(msh, self.n_owned)

        psi = ufl.TestFunction(self.V)
        self.finite = scene.kinematics == "finite"
        self.active_terms = ["elasticity", "growth"]
        self.K = None
        self.P2vec = None
        at_cells = self.midpoints[:, 0], self.midpoints[:, 1]
        P1 = grad_P1 = self.P1 = None
        self.P1_cells = None  # (n_cells,) when a pressure term is assembled
        if not (scene.P1.is_constant and float(scene.P1(0.0, 0.0)) == 0.0):
            self.K = fem.Function(self.T0, name="K")
            # P1 at the cell midpoints: the one-point rule integrates a linear P1 exactly (every
            # other factor of both kinematics' forms is constant on a cell)
            P1 = self.P1 = fem.Function(self.Q0)
            self.P1_cells = scene.P1(*at_cells)
            self.set_cell_values(P1, self.P1_cells)
            self.active_terms.append("pressure")
            if not scene.P1.is_constant:
                grad_P1 = fem.Function(fem.VectorFunctionSpace(msh, ("DG", 0)))
                self.set_cell_values(grad_P1, scene.P1.gradient(*at_cells))
        self.active_terms += [f"traction on {name}" for name in sorted(scene.loads)]
        self.active_terms += [f"{name} {kind}" for name, kind in sorted(scene.supports.items())]
        if not scene.pinned:
            self.active_terms.append("no pinned point (a held edge holds u1)")
        length = (lambda n: finite.current_length(self.u, n)) if self.finite else (
            lambda n: grown_length(self.Fg, n)
        )  # fmt: skip
        self.loads = EdgeLoads(
            scene.loads, msh, self.boundary.facets, self.boundary.edges, length,
            "current" if self.finite else "grown",
        )  # fmt: skip
        self.bcs = self._boundary_conditions(scene)
        self.ndofs = self.V.dofmap.index_map.size_global * self.V.dofmap.index_map_bs
        self.solver = scene.solver.macro_kind(self.ndofs)
        self.rtol = scene.solver.macro_rtol
        self.spare = scene.solver.macro_spare_iterations
        self.with_water = water
        self.ksp = self.factors = None  # factors: the kept LU factors (FactorReuse) or None
        if not water:
            self._linear_forms(scene, psi, P1, grad_P1)  # finite kinematics: Newton's predictor
        if self.finite:
            self._finite_forms(scene, psi, P1)
        self._grad_u = fem.Function(self.T0)
        self._grad_u_expr = fem.Expression(ufl.grad(self.u), self.T0.element.interpolation_points())
        log.info(
            "macro solver: %s (solver.macro = %r, %d fine dofs, threshold %d)",
            self._solver_name(), scene.solver.macro,
            self.ndofs, scene.solver.macro_threshold,
        )  # fmt: skip

    def _linear_forms(self, scene: Scene, psi, P1, grad_P1) -> None:
        """docs/model.md section 4: the bilinear form a, the load L of the active terms, matrix
        and solver."""
        u, dx = ufl.TrialFunction(self.V), ufl.dx
        rhs = macro.macro_growth_rhs(psi, self.Fg, self.C, dx)
        if self.K is not None:
            rhs += macro.macro_pressure_rhs(psi, self.Fg, self.K, self.phi_w, P1, dx)
            if grad_P1 is not None:
                self.P2vec = fem.Function(grad_P1.function_space, name="P2vec")
                rhs += macro.macro_pressure_gradient_rhs(
                    psi, self.Fg, self.phi_w, grad_P1, self.P2vec, dx
                )
                self.active_terms.append("pressure gradient (grad P1, P2)")
        rhs += self.loads.terms(lambda f, n, ds: boundary_traction(f, psi, self.Fg, n, ds))
        a = macro.macro_bilinear_form(u, psi, self.Fg, self.C, dx)
        self.held.set_residual(lambda: ufl.action(a, self.u) - rhs)
        self.a = fem.form(a)
        self.L = fem.form(rhs)
        self.A = fem.petsc.create_matrix(self.a, CG_MATRIX if self.solver == "iterative" else None)
        self.b = fem.petsc.create_vector(self.L)
        self.ksp = self._linear_solver(self.A)
        self.reuse, self.history, self.factors = None, None, None
        if self.solver != "iterative" and not self.finite:
            self.factors = FactorReuse(self.ksp, (self.Fg, self.C))
        if self.solver == "iterative":
            self.reuse = PreconditionerReuse(self.ksp, REBUILD_GROWTH, REBUILD_SETUP)
            self.history = SolutionHistory(HISTORY)

    def _finite_forms(self, scene: Scene, psi, P1) -> None:
        """docs/model.md section 10: the residual (grad P1 and P2vec cancel: not assembled) and
        its Newton solver; tractions follow the deformed edges."""
        u, dx = self.u, ufl.dx
        residual = finite.macro_residual(u, psi, self.Fg, self.C, self.K, self.phi_w, P1, dx)
        tractions = self.loads.terms(lambda f, n, ds: finite.follower_traction(u, f, psi, n, ds))
        load = None
        if self.K is not None:
            load = finite.macro_prestress_work(u, psi, self.Fg, self.K, self.phi_w, P1, dx)
        if tractions:
            residual -= tractions
            load = -tractions if load is None else load - tractions
        self.held.set_residual(lambda: residual)
        self.active_terms.append("finite kinematics (Newton, linear predictor)")
        self.newton = NewtonSolver(
            residual, self.u, self.bcs, self._jacobian_solver, load, self._newton_floor,
            lambda: self.smallest_stability(), predictor=self._linear_solve,
            fallback=self._direct_jacobian_solver if self.solver == "iterative" else None,
        )  # fmt: skip
        self.newton_report: NewtonReport | None = None

    def _solver_name(self) -> str:
        if self.with_water:
            kind = "MINRES + field split" if self.solver == "iterative" else "LU"
            return kind + " of u and P (water)"
        if self.solver != "iterative":
            return "LU"
        newton = ", Newton: GMRES + GAMG (LU where GMRES stops)" if self.finite else ""
        spare = (
            f", to macro_rtol / {SPARE_FACTOR:g} within {self.spare} iterations"
            if self.spare else ""
        )
        return "CG + BoomerAMG" + spare + newton

    def _linear_solver(self, A: PETSc.Mat) -> PETSc.KSP:
        if self.solver == "iterative":  # warm: from the guess SolutionHistory sets
            return boomeramg_cg_solver(
                A, self.mesh.comm, PREFIX, self.rtol, MACRO_MAX_IT, True, self.spare
            )
        return lu_solver(A, self.mesh.comm, PREFIX, serial=SERIAL_LU)

    def _jacobian_solver(self, J: PETSc.Mat) -> PETSc.KSP:
        """Newton's linear solver: GMRES + GAMG (a finite-kinematics Jacobian is non-symmetric
        under follower loads, indefinite under strong compression), or LU."""
        if self.solver == "iterative":
            return gamg_solver(
                J, self.V, NEWTON_PREFIX, NEWTON_KRYLOV_RTOL, NEWTON_KRYLOV_MAX_IT, spd=False
            )
        return self._direct_jacobian_solver(J)

    def _direct_jacobian_solver(self, J: PETSc.Mat) -> PETSc.KSP:
        return lu_solver(J, self.mesh.comm, NEWTON_PREFIX)

    def _boundary_conditions(self, scene: Scene) -> list:
        """docs/model.md section 4: u2 = 0 on x2 = 0, the held edges' components, and u1 = 0 at
        the pinned vertex unless a held edge holds u1 (all homogeneous)."""
        self.held = HeldEdges(self.V, self.boundary, scene.held_components())
        bcs = self.held.conditions()
        if scene.pinned:
            origin = pinned_vertices(self.mesh, self.boundary.pin)
            origin_dofs = fem.locate_dofs_topological(self.V.sub(0), 0, origin)
            bcs.append(fem.dirichletbc(PETSc.ScalarType(0.0), origin_dofs, self.V.sub(0)))
        return bcs

    def _cell_dofs(self, function: fem.Function) -> slice | np.ndarray:
        """The dofs (blocks) of the cells of a DG0 function, in cell order: a slice where they
        are the cells' own numbers (dolfinx numbers a DG0 space's dofs so: a slice copies
        values several times as fast as an index array), else the dofmap's array."""
        space = function.function_space
        if id(space) not in self._dg0_dofs:
            dofs = space.dofmap.list.array[: self.n_cells].copy()
            if np.array_equal(dofs, np.arange(self.n_cells)):
                dofs = slice(0, self.n_cells)
            self._dg0_dofs[id(space)] = space, dofs  # the space kept: its id stays its own
        return self._dg0_dofs[id(space)][1]

    def set_cell_values(self, function: fem.Function, values: np.ndarray) -> None:
        """Write per-cell values (n_cells, ...) into a DG0 function (cell order -> dof order)."""
        array = function.x.array.reshape(-1, function.function_space.dofmap.index_map_bs)
        array[self._cell_dofs(function)] = values.reshape(self.n_cells, -1)
        function.x.scatter_forward()

    def cell_values(self, function: fem.Function, array: np.ndarray | None = None) -> np.ndarray:
        """Per-cell values (n_cells, bs) of a DG0 function, or of ``array`` in its dof order (a
        copy of its values)."""
        values = function.x.array if array is None else array
        bs = function.function_space.dofmap.index_map_bs
        return values.reshape(-1, bs)[self._cell_dofs(function)].copy()

    def factorized_cells(self) -> tuple[dict[str, np.ndarray], float] | None:
        """The coefficients per cell of the matrix whose LU factors are kept (``lu_Fg``,
        ``lu_C``: what a resumed run factorizes again) and their floor; None without kept
        factors (:mod:`plantgrowth.models.factor_reuse`)."""
        kept = None if self.factors is None else self.factors.factorized()
        if kept is None:
            return None
        named = zip(("lu_Fg", "lu_C"), (self.Fg, self.C), kept[0], strict=True)
        return {name: self.cell_values(f, array) for name, f, array in named}, kept[1]

    def restore_factors(self, state: dict[str, np.ndarray], index: np.ndarray) -> None:
        """Collective: factorize the matrix of the saved :meth:`factorized_cells` (a resumed
        run; ``index``: this rank's cells in the saved arrays); nothing if none were saved. The
        step's own coefficients are set before its solve."""
        if self.factors is None or "lu_Fg" not in state:
            return
        self.set_cell_values(self.Fg, state["lu_Fg"][index])
        self.set_cell_values(self.C, state["lu_C"][index])
        floor = float(state["lu_floor"].reshape(-1)[0])
        self.factors.refactor(lambda: assemble_matrix(self.A, self.a, self.bcs), floor)

    def solve(self) -> SolveReport:
        """Assemble the active terms and solve for u; returns the solver diagnostics (finite
        kinematics: those of the worst linear solve; Newton's in ``newton_report``)."""
        self.loads.update_forces()
        if self.finite:
            self.newton_report = report = self._newton_solve()
            log_report("macro", report)
            return SolveReport(report.reason, report.linear_residual)
        report = self._linear_solve()
        if self.solver == "iterative":
            log.info(
                "macro solve: %d CG iterations, relative residual %.2g, preconditioner built %d "
                "times", report.iterations, report.residual, self.reuse.rebuilds,
            )  # fmt: skip
        return report

    def _newton_solve(self) -> NewtonReport:
        """Newton's solve (with turgor, ramped up if it fails: :mod:`plantgrowth.models.
        turgor_ramp`); with total forces, again until their tractions ``F / L`` hold at the
        solution's edge lengths (a few extra iterations: L moves by the last correction only)."""
        if self.P1 is None:
            report = self.newton.solve()
        else:
            report = solve_ramped(
                self.newton, lambda s: self.set_cell_values(self.P1, s * self.P1_cells)
            )
        for _ in range(MAX_FORCE_UPDATES):
            if self.loads.update_forces() <= FORCE_LENGTH_RTOL:
                return report
            again = self.newton.solve()
            report = replace(again, iterations=report.iterations + again.iterations)
        raise RunError(
            f"the total forces' tractions F / L did not settle in {MAX_FORCE_UPDATES} Newton "
            "solves: the loaded edges' lengths keep changing (loads too large?)"
        )

    def _linear_solve(self) -> SolveReport:
        """The linear-kinematics solve (docs/model.md section 4) into u (CG: from the projection
        onto the last solutions, with the kept or a rebuilt preconditioner)."""

        def solve() -> SolveReport:
            return assemble_and_solve(
                self.A, self.b, self.a, self.L, self.bcs, self.ksp, self.u, self.residual_bound,
                None if self.history is None else self.history.guess,
                None if self.factors is None else self.factors.solve,
            )  # fmt: skip

        if self.reuse is None:
            return solve()
        report = self.reuse.solve(solve, self._cold_start)
        if report.reason > 0:
            self.history.record(self.u.vector)
        return report

    def _cold_start(self) -> None:
        self.u.x.array[:] = 0.0
        self.history.clear()

    @property
    def residual_bound(self) -> float:
        """The true relative residual the linear solve may leave: TRUE_RESIDUAL_FACTOR times
        ``solver.macro_rtol`` for CG, diagnostics.RESIDUAL_BOUND for LU."""
        if self.solver == "iterative":
            return TRUE_RESIDUAL_FACTOR * self.rtol
        return RESIDUAL_BOUND

    def stability_values(
        self, grad_u: np.ndarray | None = None, screened: bool = True
    ) -> np.ndarray:
        """(n_cells,) the normalised smallest acoustic eigenvalue of each cell at the current u
        (plantgrowth.models.stability.normalised; ``screened``: exact in sign only) with the
        walls' stress ``S_w = E_hom Ee + K_hom P1`` (the lumens' follower pressure adds nothing
        to the acoustic tensor: docs/model.md section 10) at ``Fe = (I + grad u) Fg^-1``, or for
        linear kinematics at ``Ee = eps_el`` (``grad_u``: the current one if the caller has it)."""
        Fe, S, C = self.walls_state(grad_u)
        return stability.normalised(Fe, S, C, screened)

    def walls_state(
        self, grad_u: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Fe, S_w, C) per cell: the elastic deformation (linear kinematics: the stretch
        ``sqrt(I + 2 eps_el)``), the walls' stress ``E_hom Ee + K_hom P1`` and E_hom (Voigt)."""
        grad_u = self.grad_u() if grad_u is None else grad_u
        Fg = self.cell_values(self.Fg).reshape(-1, 2, 2)
        C = self.cell_values(self.C).reshape(-1, 3, 3)
        if self.finite:
            Fe = (np.eye(2) + grad_u) @ inv2(Fg)
            Ee = 0.5 * (np.swapaxes(Fe, 1, 2) @ Fe - np.eye(2))
        else:
            Ee = growth.elastic_strain(grad_u, Fg)
            Fe = stability.stretch_of_strain(Ee)
        K = None if self.K is None else self.cell_values(self.K).reshape(-1, 2, 2)
        return Fe, growth.homogenized_stress(C, Ee, K, self.P1_cells), C

    def smallest_stability(self) -> tuple[float, np.ndarray]:
        """Collective: the smallest :meth:`stability_values` of the owned cells and where."""
        values = self.stability_values()[: self.n_owned]
        return global_extreme(values, self.midpoints[: self.n_owned, :2], self.mesh.comm, np.argmin)

    def _newton_floor(self) -> float:
        """Collective: Newton's absolute floor, NEWTON_ATOL times the stiffest homogenized
        modulus times the square root of the tissue's area."""
        C = self.cell_values(self.C)[: self.n_owned].reshape(-1, 3, 3)
        stiffest = float(np.max(C[:, [0, 1], [0, 1]], initial=0.0))
        stiffest = self.mesh.comm.allreduce(stiffest, op=MPI.MAX)
        return NEWTON_ATOL * stiffest * np.sqrt(self.total_area)

    def grad_u(self) -> np.ndarray:
        """(n_cells, 2, 2) displacement gradient per cell."""
        self._grad_u.interpolate(self._grad_u_expr)
        return self.cell_values(self._grad_u).reshape(-1, 2, 2)
