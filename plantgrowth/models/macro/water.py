"""The macro model's coupled (u, P) step with water fluxes, linear kinematics (docs/model.md,
"Water fluxes", macro model).

P is a P1 field solved with the P1 displacement of :class:`MacroProblem` in one symmetric saddle
point per step (forms/hydraulics.py); the water held per unit reference area, m, is the state
carried between steps: with cell-wise constant coefficients and P1 fields, m is linear on every
fine cell, so it is stored exactly in DG1 and the water balance closes to round-off. The
P1-P1 pair is stabilised by ``D(P^{n+1} - P^n, q)`` with ``beta = h^2 |b|^2 / (4 E_min)`` per
cell (``STABILISATION``): without it the pair is not inf-sup stable and P wiggles next to a
supplied edge at small time steps (docs/model.md, "Water fluxes").
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.base.errors import InputError, RunError
from plantgrowth.forms import hydraulics as water
from plantgrowth.forms.elasticity import boundary_traction
from plantgrowth.forms.macro import macro_bilinear_form, macro_growth_rhs
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.models.linear import (
    SolveReport,
    assemble_system,
    lu_solver,
    relative_residual,
    saddle_point_solver,
)
from plantgrowth.models.macro.hydraulics import MacroHydraulics, at_time, sample
from plantgrowth.models.macro.problem import MacroProblem
from plantgrowth.unitcell.homogenization import NodeTensors

log = logging.getLogger("plantgrowth")

PREFIX = "plantgrowth_macro_water_"
MAX_IT = 2000
"""MINRES's iteration limit on the iterative path: 15-28 iterations on the consolidation strip
(3,000 dofs, rtol 1e-10, dt 1e-4 to 0.1 of the diffusion time), 25 on the apex scene at 25,620
and 100,914 dofs (rtol 1e-8); a solve that needs more is reported by its converged reason."""
STABILISATION = 0.25
"""beta = STABILISATION h^2 |b|^2 / E_min, with h the fine cell's longest edge, |b| b's largest
eigenvalue and E_min = min(E_hom_1111, E_hom_2222). In 1D, ``h^2 b^2 / (4 E)`` makes the P1-P1
Biot scheme monotone at every time step (Rodrigo, Gaspar, Hu, Zikatanov, CMAME 298, 2016); on
the fine meshes' right-angled triangles h is the hypotenuse, so beta is twice that. Measured on the
consolidation strip (tests/test_macro_hydraulics.py): after a step change of psi_s at dt = 1e-4
and 1e-6 of the diffusion time, P leaves the range of its old and new values by 3e-4 of the jump
(0.32 and 0.96 unstabilised)."""


def unit_conductivities(cells: Sequence[HoneycombCell], Fg: np.ndarray) -> np.ndarray:
    """(n, 2, 2) ``kappa / L`` of each fine cell's unit cell at its Fg (det > 0; docs/model.md,
    "The unit cell's coefficients"): :func:`~plantgrowth.unitcell.hydraulic_coefficients.
    conductivity`'s sum over the three wall families, for all the fine cells of one unit cell
    at once (one call per fine cell took 0.1 ms: 6x a given-turgor step's time, issue 35)."""
    out = np.empty((len(cells), 2, 2))
    groups: dict[HoneycombCell, list[int]] = {}
    for k, cell in enumerate(cells):
        groups.setdefault(cell, []).append(k)
    for cell, index in groups.items():
        F = Fg[index]
        vertical, rising, falling = cell.wall_tangents()
        kappa = np.zeros_like(F)
        for d, t, length in ((cell.b1, vertical, cell.l1), (cell.b2, falling, cell.l2),
                             (cell.b2 - cell.b1, rising, cell.l2)):  # fmt: skip
            Fd = F @ d
            kappa += (length * np.linalg.norm(F @ t, axis=1))[:, None, None] * (
                Fd[:, :, None] * Fd[:, None, :]
            )
        out[index] = kappa / (np.linalg.det(F) * cell.area)[:, None, None]
    return out


def longest_edges(problem: MacroProblem) -> np.ndarray:
    """(n_cells,) the longest edge of each fine cell (reference configuration)."""
    msh = problem.mesh
    x = msh.geometry.x[msh.geometry.dofmap.array.reshape(-1, 3)[: problem.n_cells], :2]
    edges = x - np.roll(x, 1, axis=1)
    return np.linalg.norm(edges, axis=2).max(axis=1)


def supplied_edge_tag(problem: MacroProblem, edge: str) -> int:
    """The facet tag of a supplied edge; InputError for an unknown edge or the symmetry plane
    x2 = 0 (a mirror: no water crosses it)."""
    edges = problem.boundary.edges
    if edge not in edges:
        raise InputError(f"supply on {edge!r}: the tissue's edges are {sorted(edges)}")
    if edges[edge] in problem.boundary.symmetry:
        raise InputError(f"supply on {edge!r}: the symmetry plane x2 = 0 is a mirror, not an edge")
    return edges[edge]


class MacroWater:
    """The (u, P) step of the macro model with water, on a :class:`MacroProblem` (its mesh, u,
    Fg, E_hom, phi_w, boundary conditions and loads).

    Args:
        problem: the macro problem (linear kinematics).
        inputs: the water's inputs.
        stabilisation: beta's factor (``STABILISATION``; 0: the unstabilised pair, for checks).
    """

    finite = False
    """The kinematics this class solves (:class:`plantgrowth.models.macro.water_finite.
    MacroWaterFinite`: finite)."""

    def __init__(
        self, problem: MacroProblem, inputs: MacroHydraulics, stabilisation: float = STABILISATION
    ) -> None:
        if problem.finite != self.finite:
            raise InputError(
                f"water fluxes: {type(self).__name__} solves "
                f"{'finite' if self.finite else 'linear'} kinematics only"
            )
        self.problem, self.inputs, self.stabilisation = problem, inputs, stabilisation
        msh = problem.mesh
        self.Q = fem.FunctionSpace(msh, ("Lagrange", 1))
        self.P, self.P_old, self.Pi = (fem.Function(self.Q, name=n) for n in ("P", "P_old", "Pi"))
        self.Pi.interpolate(lambda x: sample(inputs.osmotic, x[0], x[1]))
        self.m = fem.Function(fem.FunctionSpace(msh, ("DG", 1)), name="m")
        # the turgor is this class's from now on: the problem's walls_state (the stability
        # check) reads K and P1_cells, which the solves below set
        if problem.K is None:
            problem.K = fem.Function(problem.T0, name="K")
        self.K = problem.K
        self.inv_M, self.beta, self.L_r, self.Lr_psi_r, self.b2_E = (
            fem.Function(problem.Q0) for _ in range(5)
        )
        self.kappa = fem.Function(problem.T0, name="kappa")
        self.L_cells = sample(inputs.conductivity, *problem.midpoints[:, :2].T)
        self._regions(0.0)
        self.dt = fem.Constant(msh, PETSc.ScalarType(1.0))
        ds = ufl.Measure("ds", domain=msh, subdomain_data=problem.boundary.facets)
        self.edges = {
            s.edge: (
                fem.Constant(msh, PETSc.ScalarType(s.conductance)),
                fem.Constant(msh, PETSc.ScalarType(at_time(s.potential, 0.0))),
                ds(supplied_edge_tag(problem, s.edge)),
            )
            for s in inputs.edges
        }
        self._forms()
        self._integrals: dict[object, fem.FormMetaClass] = {}  # key -> compiled (_integral)
        self.A = fem.petsc.create_matrix_block(self.a)
        self.b = fem.petsc.create_vector_block(self.L)
        self.x = fem.petsc.create_vector_block(self.L)  # ghosted: Newton's x0 (finite)
        self.schur = None  # the iterative path's Schur preconditioner matrix
        self.ksp = self._solver()
        self._m_expr = fem.Expression(
            self._water_held(), self.m.function_space.element.interpolation_points()
        )

    def _water_held(self) -> ufl.core.expr.Expr:
        """m(u, P), linear kinematics."""
        pr = self.problem
        return water.water_held(pr.u, self.P, pr.Fg, self.K, pr.phi_w, self.inv_M)

    def _solver(self) -> PETSc.KSP:
        """LU (MUMPS on any number of ranks), or for the problem's iterative kind MINRES with
        the block preconditioner of :func:`saddle_point_solver`, to ``solver.macro_rtol``."""
        pr = self.problem
        if pr.solver != "iterative":
            return lu_solver(self.A, pr.mesh.comm, PREFIX, serial="mumps")
        start = self.A.getOwnershipRange()[0]
        n_u = pr.V.dofmap.index_map.size_local * pr.V.dofmap.index_map_bs
        n_P = self.Q.dofmap.index_map.size_local
        fields = tuple(
            PETSc.IS().createGeneral(np.arange(a, b, dtype=np.int32), comm=pr.mesh.comm)
            for a, b in ((start, start + n_u), (start + n_u, start + n_u + n_P))
        )
        self.schur = fem.petsc.create_matrix(self.a_schur)
        return saddle_point_solver(
            self.A, fields, self.schur, pr.mesh.comm, PREFIX, pr.rtol, MAX_IT
        )

    def _regions(self, t: float) -> None:
        """L_r and L_r psi_r(t) per fine cell (zero outside the supplied regions)."""
        at = self.problem.midpoints[:, :2].T
        L_r, Lr_psi_r = np.zeros(self.problem.n_cells), np.zeros(self.problem.n_cells)
        for region in self.inputs.regions:
            inside = np.asarray(region.inside(*at), dtype=bool)
            L_r[inside] += region.conductance
            Lr_psi_r[inside] += region.conductance * at_time(region.potential, t)
        self.problem.set_cell_values(self.L_r, L_r)
        self.problem.set_cell_values(self.Lr_psi_r, Lr_psi_r)

    def _pressure_terms(self, p, q) -> tuple[ufl.Form, ufl.Form, ufl.Form]:
        """The water rows' terms in p: storage ``S(p, q)``, stabilisation ``D(p, q)`` and
        ``dt H(p, q)``."""
        pr, dx = self.problem, ufl.dx
        edges = [(L_s, ds) for L_s, _, ds in self.edges.values()]
        storage = water.storage_form(p, q, pr.Fg, self.inv_M, dx)
        stabilised = water.grown_gradient_form(p, q, pr.Fg, self.beta, dx)
        H = water.conductance_form(p, q, pr.Fg, self.kappa, self.L_r, dx, edges)
        return storage, stabilised, self.dt * H

    def _known_water(self, q) -> ufl.Form:
        """The water rows' known part, ``D(P^n, q) + dt [H(Pi, q) + int Jg L_r psi_r q + sum_s
        int L_s |cof(Fg) N| psi_s q]``: the stabilisation's old P and what the supplies bring."""
        pr, dx = self.problem, ufl.dx
        supplied = self.Lr_psi_r * ufl.det(pr.Fg) * q * dx
        n = ufl.FacetNormal(pr.mesh)
        for L_s, psi_s, ds in self.edges.values():
            supplied += water.edge_supply_form(psi_s, q, pr.Fg, L_s, n, ds)
        D_old = self._pressure_terms(self.P_old, q)[1]
        return D_old + self._pressure_terms(self.Pi, q)[2] + self.dt * supplied

    def _forms(self) -> None:
        """The step's block forms ``[K  -B; -B^T  -(S + D + dt H)]`` and right-hand side."""
        pr, dx = self.problem, ufl.dx
        Fg, C, K, phi_w = pr.Fg, pr.C, self.K, pr.phi_w
        u, v = ufl.TrialFunction(pr.V), ufl.TestFunction(pr.V)
        P, q = ufl.TrialFunction(self.Q), ufl.TestFunction(self.Q)
        S, D, dtH = self._pressure_terms(P, q)
        if pr.solver == "iterative":  # its Schur preconditioner: the P block with the fixed-
            # stress term |b|^2 / E_min in place of B^T K^-1 B (docs/large_tissues.md, "Water
            # fluxes"): 25 MINRES iterations at 25,620 and 100,914 dofs, 46 with B^T diag(K)^-1 B
            self.a_schur = fem.form(-(S + D + dtH + self.b2_E * ufl.det(Fg) * P * q * dx))
        a = [
            [macro_bilinear_form(u, v, Fg, C, dx), -water.turgor_coupling(P, v, Fg, K, phi_w, dx)],
            [-water.turgor_coupling(q, u, Fg, K, phi_w, dx), -(S + D + dtH)],
        ]
        rhs_p = water.water_at_rest(q, Fg, K, phi_w, dx) - self.m * q * dx - self._known_water(q)
        rhs_u = macro_growth_rhs(v, Fg, C, dx)
        rhs_u += pr.loads.terms(lambda f, nn, ds: boundary_traction(f, v, Fg, nn, ds))
        self.a, self.L = fem.form(a), fem.form([rhs_u, rhs_p])
        # the held edges' reaction: the mechanics' residual at the solved (u, P)
        turgor = water.turgor_coupling(self.P, v, Fg, K, phi_w, dx)
        pr.held.set_residual(lambda: ufl.action(a[0][0], pr.u) - turgor - rhs_u)
        # the mechanics alone at a given P: the initial equilibrium
        self._a_u = fem.form(a[0][0])
        self._L_u = fem.form(rhs_u + turgor)

    def set_coefficients(
        self, Fg: np.ndarray, tensors: NodeTensors, cells: Sequence[HoneycombCell],
        shape: np.ndarray | None = None,
    ) -> None:  # fmt: skip
        """Fg, E_hom, phi_w, K_hom, 1/M = -tr dbar[v], kappa and beta per fine cell (n_cells,
        ...); ``cells``: each fine cell's unit cell, for kappa; ``shape``: a tissue given as
        cells, each fine cell's Fs, kappa then that of the hexagon grown by ``Fg Fs`` (the
        grown frame's unit cell; Darcy's pull-back stays by Fg, the measured cells being the
        reference)."""
        if tensors.K is None or tensors.dbar_v is None:
            raise ValueError("water fluxes need K_hom and dbar[v] (pressure and strain averages)")
        pr = self.problem
        for function, values in ((pr.Fg, Fg), (pr.C, tensors.C), (pr.phi_w, tensors.phi_w),
                                 (self.K, tensors.K)):  # fmt: skip
            pr.set_cell_values(function, values)
        pr.set_cell_values(self.inv_M, -np.trace(tensors.dbar_v, axis1=1, axis2=2))
        kappa = self.inputs.cell_scale * self.L_cells[:, None, None]
        grown = Fg if shape is None else Fg @ shape
        pr.set_cell_values(self.kappa, kappa * unit_conductivities(cells, grown))
        b = (1.0 - tensors.phi_w)[:, None, None] * np.eye(2) - tensors.K
        b_max = np.abs(np.linalg.eigvalsh(b)).max(axis=1)
        E_min = np.minimum(tensors.C[:, 0, 0], tensors.C[:, 1, 1])
        beta = self.stabilisation * longest_edges(pr) ** 2 * b_max**2 / E_min
        pr.set_cell_values(self.b2_E, b_max**2 / E_min)
        pr.set_cell_values(self.beta, beta)

    def set_edge_potential(self, edge: str, potential: float) -> None:
        """psi_s of a supplied edge from now on (until :meth:`set_time`)."""
        self.edges[edge][1].value = potential

    def set_time(self, t: float) -> None:
        """Every supply's potential at time t."""
        for supply in self.inputs.edges:
            self.set_edge_potential(supply.edge, at_time(supply.potential, t))
        if any(callable(region.potential) for region in self.inputs.regions):
            self._regions(t)

    def start(self) -> SolveReport:
        """Equilibrium at ``P = Pi + psi_0`` (u from the mechanics alone) and the water it holds,
        ``m = m(u, P)``: the initial state."""
        pr = self.problem
        self.P.x.array[:] = self.Pi.x.array + self.inputs.initial_potential
        A, b = fem.petsc.create_matrix(self._a_u), fem.petsc.create_vector(self._L_u)
        assemble_system(A, b, self._a_u, self._L_u, pr.bcs)
        ksp = lu_solver(A, pr.mesh.comm, PREFIX + "start_")
        ksp.solve(b, pr.u.vector)
        pr.u.x.scatter_forward()
        report = SolveReport(ksp.getConvergedReason(), relative_residual(A, pr.u.vector, b))
        ksp.destroy()
        A.destroy()
        b.destroy()
        self._solved()
        return report

    def step(self, dt: float, t: float | None = None) -> SolveReport:
        """One backward-Euler step of length dt ending at time t (the supplies' potentials are
        read there; None: as they are): solve (u, P), then m <- m(u, P)."""
        pr = self.problem
        if t is not None:
            self.set_time(t)
        self.dt.value = dt
        self.P_old.x.array[:] = self.P.x.array
        self.A.zeroEntries()
        fem.petsc.assemble_matrix_block(self.A, self.a, bcs=pr.bcs)
        self.A.assemble()
        if self.schur is not None:
            self.schur.zeroEntries()
            fem.petsc.assemble_matrix(self.schur, self.a_schur)
            self.schur.assemble()
        with self.b.localForm() as local:
            local.set(0.0)
        fem.petsc.assemble_vector_block(self.b, self.L, self.a, bcs=pr.bcs)
        self.ksp.solve(self.b, self.x)
        offset = pr.V.dofmap.index_map.size_local * pr.V.dofmap.index_map_bs
        pr.u.x.array[:offset] = self.x.array_r[:offset]
        owned_P = self.Q.dofmap.index_map.size_local
        self.P.x.array[:owned_P] = self.x.array_r[offset:]
        pr.u.x.scatter_forward()
        self.P.x.scatter_forward()
        self._solved()
        residual = relative_residual(self.A, self.x, self.b)
        iterations = 0 if self.ksp.getType() == "preonly" else self.ksp.getIterationNumber()
        if iterations:
            log.info("macro water solve: %d MINRES iterations, relative residual %.2g",
                     iterations, residual)  # fmt: skip
        return SolveReport(self.ksp.getConvergedReason(), residual, iterations, pr.residual_bound)

    def _solved(self) -> None:
        """After a solve: the water held, m = m(u, P), and the problem's turgor per cell."""
        self.m.interpolate(self._m_expr)
        self.problem.P1_cells = self.cell_pressure()

    def mark(self) -> None:
        """Remember the water's state, m and P (the stabilisation's P^n), for :meth:`revert`."""
        self._marked = (self.m.x.array.copy(), self.P.x.array.copy())

    def revert(self) -> None:
        """Back to the state :meth:`mark` remembered (a rejected sub-step of the adaptive
        integrator leaves the water as it was)."""
        self.m.x.array[:], self.P.x.array[:] = self._marked

    def _cell_dofs(self, f: fem.Function, n: int) -> tuple[np.ndarray, np.ndarray]:
        """(n, 3) the dofs of f (DG1 or P1) on the first n fine cells and (n, 12) their keys:
        the cell's midpoint and the dof's point, three times."""
        dofs = f.function_space.dofmap.list.array.reshape(-1, 3)[:n]
        points = f.function_space.tabulate_dof_coordinates()[:, :2][dofs]
        midpoints = np.repeat(self.problem.midpoints[:n, None, :2], 3, axis=1)
        return dofs, np.concatenate([midpoints, points], axis=2).reshape(n, 12)

    def state(self) -> dict[str, np.ndarray]:
        """This rank's part of the water's state, a row per owned fine cell: ``water_m`` (n, 3)
        its DG1 dofs of m, ``water_P`` (n, 3) its P1 dofs of P (the stabilisation's P^n), and
        ``water_m_at``, ``water_P_at`` (n, 12) their keys (:meth:`_cell_dofs`)."""
        parts = {}
        for name, f in (("m", self.m), ("P", self.P)):
            dofs, keys = self._cell_dofs(f, self.problem.n_owned)
            parts[f"water_{name}_at"], parts[f"water_{name}"] = keys, f.x.array[dofs]
        return parts

    def restore(self, state: dict[str, np.ndarray]) -> None:
        """m and P from a state (every rank's :meth:`state` joined), matched by cell midpoint
        and dof point; RunError if the state does not cover this mesh."""
        from scipy.spatial import cKDTree  # here: a run that does not resume never loads it

        tolerance = 1e-9 * max(self.problem.bounding_box)
        for name, f in (("m", self.m), ("P", self.P)):
            dofs, keys = self._cell_dofs(f, self.problem.n_cells)
            saved = cKDTree(np.asarray(state[f"water_{name}_at"]).reshape(-1, 4))
            distance, index = saved.query(keys.reshape(-1, 4))
            if np.max(distance, initial=0.0) > tolerance:
                raise RunError("the saved water state does not match this mesh")
            f.x.array[dofs.reshape(-1)] = np.asarray(state[f"water_{name}"]).reshape(-1)[index]
            f.x.scatter_forward()

    def cell_pressure(self) -> np.ndarray:
        """(n_cells,) P at the fine cells' midpoints (the mean of its vertex values)."""
        dofs = self.Q.dofmap.list.array.reshape(-1, 3)[: self.problem.n_cells]
        return self.P.x.array[dofs].mean(axis=1)

    def water_content(self) -> float:
        """Collective: ``int m dx``, the water the tissue holds."""
        return self._integral("water", lambda: self.m * ufl.dx)

    def inflow(self, edge: str | None = None) -> float:
        """Collective: the water entering per unit time at the current state through a supplied
        ``edge`` (``int L_s |cof(Fg) N| (psi_s - psi) ds``), or through every supply (the edges
        and ``int Jg L_r (psi_r - psi) dx``)."""
        return self._integral(("inflow", edge), lambda: self._inflow_form(edge))

    def _inflow_form(self, edge: str | None) -> ufl.Form:
        pr, psi = self.problem, self.P - self.Pi
        n = ufl.FacetNormal(pr.mesh)
        one = fem.Constant(pr.mesh, PETSc.ScalarType(1.0))
        total = 0
        if edge is None:
            total = self.Lr_psi_r * ufl.det(pr.Fg) * ufl.dx
            total -= water.region_supply_form(psi, one, pr.Fg, self.L_r, ufl.dx)
        for name, (L_s, psi_s, ds) in self.edges.items():
            if edge in (None, name):
                total += water.edge_supply_form(psi_s - psi, one, pr.Fg, L_s, n, ds)
        return total

    def _integral(self, key: object, form: Callable[[], ufl.Form]) -> float:
        """Collective: the integral of a form, compiled on its key's first use (each step
        integrates the same forms: compiling them every time took 30 ms a step, issue 35)."""
        if key not in self._integrals:
            self._integrals[key] = fem.form(form())
        value = fem.assemble_scalar(self._integrals[key])
        return self.problem.mesh.comm.allreduce(value, op=MPI.SUM)
