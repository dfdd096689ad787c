"""The macro model's coupled (u, P) step with water fluxes, finite kinematics (docs/model.md,
"Water fluxes", macro model, and section 10).

The step solves, for the P1 pair (u, P), the residuals

- mechanics: ``R_u = int Jg (Fe S_w + P_l) : grad(v) Fg^{-1} dx - int |cof(F) N| f . v ds``
  with ``S_w = E_hom Ee + K_hom P`` and ``P_l = -(1 - phi_w) P cof(Fe)`` (forms/finite.py, P1 := P);
- water, backward Euler: ``R_P = -[int (m(u, P) - m^n) q dx + D(P - P^n, q) + dt H(P - Pi, q)
  - dt (supplies)]`` with ``m = Jg [(1 - phi_w) det(Fe) - K_hom : Ee + P / M]``,

by Newton with the exact UFL Jacobian (symmetric without follower tractions, like the linear
step's saddle point, which it equals at u = 0, Fg = I). The supplies, Darcy's conductance, the
stabilisation D and the state m (DG1: with P1 u, Fe is constant on a fine cell and m linear, so
DG1 holds it exactly) are the linear step's (:class:`plantgrowth.models.macro.water.MacroWater`).
Tested with q = 1, ``R_P`` is ``dt (inflow) - (int m^{n+1} - int m^n)``: the water balance
closes to Newton's tolerance.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.base.errors import RunError
from plantgrowth.base.tensors import det2
from plantgrowth.forms import finite
from plantgrowth.forms import hydraulics as water
from plantgrowth.models import diagnostics
from plantgrowth.models.linear import SolveReport, lu_solver, relative_residual
from plantgrowth.models.macro.edge_loads import FORCE_LENGTH_RTOL
from plantgrowth.models.macro.problem import MAX_FORCE_UPDATES
from plantgrowth.models.macro.water import PREFIX, MacroWater
from plantgrowth.models.newton import (
    ARMIJO,
    LINE_SEARCH_HALVINGS,
    NEWTON_MAX_IT,
    NEWTON_RTOL,
    NewtonReport,
    log_report,
)


class MacroWaterFinite(MacroWater):
    """The (u, P) step of the macro model with water, finite kinematics (Newton on (u, P); the
    initial equilibrium: Newton on u at P = Pi + psi_0 from the linear one)."""

    finite = True

    def _water_held(self) -> ufl.core.expr.Expr:
        """m(u, P), finite kinematics."""
        pr = self.problem
        return water.water_held_finite(pr.u, self.P, pr.Fg, self.K, pr.phi_w, self.inv_M)

    def _solver(self) -> PETSc.KSP:
        """LU (MUMPS on any number of ranks) for every Jacobian: it is indefinite (a saddle
        point) and, with follower tractions, not symmetric."""
        return lu_solver(self.A, self.problem.mesh.comm, PREFIX + "newton_", serial="mumps")

    def _forms(self) -> None:
        """The linear step's forms (its mechanics at a given P: the start's predictor), then
        ``a`` the Jacobian and ``L`` the residual ``[R_u, R_P]`` of the finite step."""
        super()._forms()
        pr, dx = self.problem, ufl.dx
        u, P = pr.u, self.P
        v, q = ufl.TestFunction(pr.V), ufl.TestFunction(self.Q)
        Fg, C, K, phi_w = pr.Fg, pr.C, self.K, pr.phi_w
        tractions = pr.loads.terms(lambda f, n, ds: finite.follower_traction(u, f, v, n, ds))
        R_u = finite.macro_residual(u, v, Fg, C, K, phi_w, P, dx)
        load_u = finite.macro_prestress_work(u, v, Fg, K, phi_w, P, dx)
        if tractions:
            R_u -= tractions
            load_u -= tractions
        m = water.water_held_finite(u, P, Fg, K, phi_w, self.inv_M)
        _, D, dtH = self._pressure_terms(P, q)
        R_P = -((m - self.m) * q * dx + D + dtH - self._known_water(q))
        trial = ufl.TrialFunction(pr.V), ufl.TrialFunction(self.Q)
        a = [[ufl.derivative(R, f, du) for f, du in zip((u, P), trial, strict=True)]
             for R in (R_u, R_P)]  # fmt: skip
        self.a, self.L = fem.form(a), fem.form([R_u, R_P])
        pr.held.set_residual(lambda: R_u)
        # the tolerance's scales: the turgor and tractions' work, the water held
        self._load_u, self._held_q = fem.form(load_u), fem.form(self.m * q * dx)

    def start(self) -> SolveReport:
        """Equilibrium at ``P = Pi + psi_0``: the linear one, then Newton on u alone (P held
        by a zero Newton correction: the water rows are not solved), and m = m(u, P)."""
        linear = super().start()
        diagnostics.stop_if(
            diagnostics.solve_problems(linear.reason, linear.residual), self.problem.mesh.comm
        )
        return self._newton(water_rows=False)

    def step(self, dt: float, t: float | None = None) -> SolveReport:
        """One backward-Euler step of length dt ending at time t (the supplies' potentials are
        read there; None: as they are): Newton on (u, P) from the last (u, P), then m <- m(u, P)."""
        if t is not None:
            self.set_time(t)
        self.dt.value = dt
        self.P_old.x.array[:] = self.P.x.array
        return self._newton(water_rows=True)

    def _newton(self, water_rows: bool) -> SolveReport:
        """Newton (with tractions given as total forces, again until their ``F / L`` settle,
        as plantgrowth.models.macro.problem does), then :meth:`_solved`."""
        pr = self.problem
        report = self._newton_solve(water_rows)
        for _ in range(MAX_FORCE_UPDATES):
            if pr.loads.update_forces() <= FORCE_LENGTH_RTOL:
                break
            again = self._newton_solve(water_rows)
            report = replace(again, iterations=report.iterations + again.iterations)
        else:
            raise RunError(
                f"the total forces' tractions F / L did not settle in {MAX_FORCE_UPDATES} Newton "
                "solves: the loaded edges' lengths keep changing (loads too large?)"
            )
        pr.newton_report = report
        log_report("macro water", report)
        self._solved()
        return SolveReport(report.reason, report.linear_residual)

    def _sizes(self) -> tuple[int, int]:
        """The owned entries of u and P in the block vectors."""
        pr = self.problem
        return pr.V.dofmap.index_map.size_local * pr.V.dofmap.index_map_bs, (
            self.Q.dofmap.index_map.size_local
        )

    def _gather(self) -> None:
        """x <- (u, P)."""
        n_u, _ = self._sizes()
        self.x.array[:n_u] = self.problem.u.x.array[:n_u]
        self.x.array[n_u:] = self.P.x.array[: len(self.x.array) - n_u]
        self.x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)

    def _scatter(self) -> None:
        """(u, P) <- x, ghosts updated."""
        self.x.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        pr = self.problem
        n_u, n_P = self._sizes()
        pr.u.x.array[:n_u] = self.x.array_r[:n_u]
        self.P.x.array[:n_P] = self.x.array_r[n_u:]
        pr.u.x.scatter_forward()
        self.P.x.scatter_forward()

    def _norms(self, water_rows: bool) -> tuple[float, float]:
        """Collective: assemble the residual into b (zero on Dirichlet dofs; the water rows too
        unless ``water_rows``) and return the norms of its mechanics and water parts."""
        with self.b.localForm() as local:
            local.set(0.0)
        fem.petsc.assemble_vector_block(
            self.b, self.L, self.a, bcs=self.problem.bcs, x0=self.x, scale=-1.0
        )
        n_u, _ = self._sizes()
        if not water_rows:
            self.b.array[n_u:] = 0.0
        parts = np.array([np.sum(self.b.array_r[:n_u] ** 2), np.sum(self.b.array_r[n_u:] ** 2)])
        return tuple(np.sqrt(self.problem.mesh.comm.allreduce(parts, op=MPI.SUM)))

    def _scales(self) -> np.ndarray:
        """Collective: each part's tolerance, ``NEWTON_RTOL`` times the norm of the turgor and
        tractions' work plus the problem's floor (plantgrowth.models.newton.NEWTON_ATOL), and
        ``NEWTON_RTOL`` times the norm of ``int m^n q`` (the water held)."""
        norms = []
        for form in (self._load_u, self._held_q):
            vector = fem.petsc.assemble_vector(form)
            vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            fem.petsc.set_bc(vector, self.problem.bcs if form is self._load_u else [])
            norms.append(vector.norm())
            vector.destroy()
        floor = self.problem._newton_floor()  # the dry Newton's absolute floor
        return np.array([NEWTON_RTOL * norms[0] + floor, NEWTON_RTOL * norms[1]])

    def _min_det(self) -> float:
        """Collective: the smallest det F over the owned fine cells (constant on each: P1 u)."""
        pr = self.problem
        local = det2(np.eye(2) + pr.grad_u()[: pr.n_owned]).min(initial=np.inf)
        return pr.mesh.comm.allreduce(float(local), op=MPI.MIN)

    def _newton_solve(self, water_rows: bool) -> NewtonReport:
        """Newton from the current (u, P) until each part of the residual meets its tolerance
        (:meth:`_scales`), with the backtracking of plantgrowth.models.newton (Armijo on the
        residual scaled by the tolerances, no inverted element); RunError on failure."""
        scales = self._scales()
        self._gather()

        parts = 2 if water_rows else 1  # the start: m^n is not yet held (scale 0)

        def scaled(water_rows: bool) -> float:
            norms = np.array(self._norms(water_rows))
            return float(np.linalg.norm(norms[:parts] / scales[:parts]))

        r = scaled(water_rows)
        history, reason, worst, dx = [r], 1, 0.0, self.x.duplicate()
        try:
            for k in range(NEWTON_MAX_IT + 1):
                if r <= 1.0:
                    residual = NEWTON_RTOL * r
                    return NewtonReport(reason, residual, k, tuple(history), worst)
                if k == NEWTON_MAX_IT or not np.isfinite(r):
                    break
                self.A.zeroEntries()
                fem.petsc.assemble_matrix_block(self.A, self.a, bcs=self.problem.bcs)
                self.A.assemble()
                if not water_rows:  # P held: its rows the identity, its columns unused
                    self._hold_pressure()
                self.ksp.solve(self.b, dx)
                reason = self.ksp.getConvergedReason()
                worst = max(worst, relative_residual(self.A, dx, self.b))
                diagnostics.stop_if(
                    diagnostics.solve_problems(reason, worst), self.problem.mesh.comm
                )
                r = self._line_search(dx, r, water_rows, scaled)
                history.append(r)
        finally:
            dx.destroy()
        raise RunError(
            f"Newton (u, P) did not converge: residual {r:.3g} times the tolerance after "
            f"{NEWTON_MAX_IT} iterations; likely cause: loads or growth contrast too strong "
            f"for the elastic tissue, {diagnostics.RATE_HINT}"
        )

    def _hold_pressure(self) -> None:
        """Make the water rows of A the identity (the start: u alone at a given P)."""
        n_u, n_P = self._sizes()
        start = self.A.getOwnershipRange()[0]
        rows = np.arange(start + n_u, start + n_u + n_P, dtype=np.int32)
        self.A.zeroRows(rows, diag=1.0)

    def _line_search(self, dx: PETSc.Vec, r: float, water_rows: bool, scaled) -> float:
        """x <- x - alpha dx for the first alpha = 2^-j that inverts no element and meets the
        tolerance or decreases the scaled residual (Armijo); returns it (b holds the residual)."""
        start = self.x.copy()
        alpha = 1.0
        try:
            for _ in range(LINE_SEARCH_HALVINGS + 1):
                self.x.waxpy(-alpha, dx, start)
                self._scatter()
                trial = scaled(water_rows) if self._min_det() > 0.0 else np.inf
                if trial <= 1.0 or trial <= (1.0 - ARMIJO * alpha) * r:
                    return trial
                alpha *= 0.5
        finally:
            start.destroy()
        raise RunError(
            f"Newton (u, P): the line search found no decrease of the residual ({r:.3g} times "
            f"the tolerance) or inverted an element; likely cause: loads or growth contrast too "
            f"strong for the elastic tissue, {diagnostics.RATE_HINT}"
        )
