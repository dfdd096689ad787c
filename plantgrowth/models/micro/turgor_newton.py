"""The micro model's step with water and finite kinematics (docs/model.md, water fluxes): the
wall displacement u and each cell's turgor P by Newton's method on

    R_u(u, P) = R_walls(u) + sum_c P_c int_Gamma_c cof(F) n . psi dS = 0
    R_c(u, P) = V_c(u) - W_c^n - dt [ sum_s g_sc psi_s - (H (P - Pi))_c ] = 0

with V_c the exact area the deformed membrane of cell c encloses (forms/finite.py
``lumen_area``). Each iteration solves the Jacobian system

    [ J    F    ] [du]     [R_u]
    [ D^T  dt H ] [dP] = - [R_w]

(J = dR_u/du, F_c = dR_u/dP_c, D_c = dV_c/du; J is not symmetric: follower loads) by one LU
factorization of the bordered matrix (plantgrowth/models/micro/bordered.py).
Full Newton steps from the walls' predictor at the last step's turgor (water_predictor.py);
an inverted element or no convergence in NEWTON_MAX_IT iterations stops the run.
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.base.errors import RunError
from plantgrowth.models import diagnostics
from plantgrowth.models.linear import SolveReport
from plantgrowth.models.micro.bordered import BorderedSolve
from plantgrowth.models.micro.cell_columns import CellColumns
from plantgrowth.models.micro.turgor_solve import ElasticParts, WaterSteps
from plantgrowth.models.micro.water import CellWater
from plantgrowth.models.micro.water_predictor import WaterPredictor
from plantgrowth.models.newton import NEWTON_MAX_IT, NEWTON_RTOL, NewtonReport, NewtonSolver

WATER_RTOL = 1e-12
"""Convergence of the water equations: ``max_c |R_c| <= WATER_RTOL max_c W_c``, the water
balance of every step closed to 1e-12 of the water a cell holds."""


class TurgorNewton(WaterSteps):
    """One step of u and P with finite kinematics.

    Args:
        newton: the walls' Newton solver (residual with the turgor ``P`` on the membranes);
            it solves the initial equilibrium, and lends its matrix, residual and solver.
        parts: the walls' problem (u, Dirichlet conditions, per-cell setter, communicator).
        P: the turgor per cell (DG0) the residual reads.
        load_column, area_column: one cell's ``F_c`` and ``D_c`` (cell given by ``indicator``);
        areas: each mesh cell's share of its cell's enclosed area V_c (a form in a DG0 test
            function of ``indicator``'s space).
        columns: splits a form in ``indicator`` into one column per cell.
        water: the water network; dt: the step; predictor: the steps' initial guess.
    """

    def __init__(
        self, newton: NewtonSolver, parts: ElasticParts, P: fem.Function, load_column: fem.Form,
        area_column: fem.Form, areas: fem.Form, indicator: fem.Function, columns: CellColumns,
        water: CellWater, dt: float, predictor: WaterPredictor,
    ) -> None:  # fmt: skip
        super().__init__(water, dt)
        self.newton, self.parts, self.P_function = newton, parts, P
        self.load_column, self.area_column, self.areas = load_column, area_column, areas
        self.indicator, self.columns, self.predictor = indicator, columns, predictor
        self.bordered = BorderedSolve(newton.A, water.n, parts.comm, "plantgrowth_micro_water_")
        parts.set_cells(indicator, np.arange(water.n))  # each DG0 dof's cell
        self.area_vector = fem.petsc.create_vector(areas)
        self.dof_cells = indicator.x.array[: self.area_vector.getLocalSize()].astype(np.intp)

    def _areas(self) -> np.ndarray:
        """(n,) V_c(u), the areas the deformed membranes enclose: the membranes' integrals per
        mesh cell (one assembly), summed per biological cell (collective)."""
        vector = self.area_vector
        with vector.localForm() as local:
            local.set(0.0)
        fem.petsc.assemble_vector(vector, self.areas)
        vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        local = np.bincount(self.dof_cells, vector.array, self.water.n)
        return self.parts.comm.allreduce(local, op=MPI.SUM)

    def _set_turgor(self, P: np.ndarray) -> None:
        self.parts.set_cells(self.P_function, P)

    def solve(self, Fg: np.ndarray) -> NewtonReport:
        """u and P at ``Fg`` (in place): the first call is the initial equilibrium, P = Pi +
        psi_0, each later one the backward Euler step from the water committed last."""
        water, newton = self.water, self.newton
        if self.held is None:
            P = water.Pi + water.hydraulics.initial_potential
            self._set_turgor(P)
            report = newton.solve()
            self.settle(P, self._areas(), Fg)
            return report
        P = self.P.copy()
        self._set_turgor(P)
        tol_u = newton.tolerance()
        self._predict(P)
        tol_w = WATER_RTOL * np.abs(self.held).max()
        H, weights = water.conductance(Fg)
        supplied = water.supply_terms(weights, self.reach)
        history, worst = [], 0.0
        for k in range(NEWTON_MAX_IT + 1):
            r_u = newton.residual_norm()  # newton.b holds R_u
            V = self._areas()
            R_w = V - self.held - self.dt * (supplied - H @ (P - water.Pi))
            r_w = float(np.abs(R_w).max())
            history.append(r_u)
            if r_u <= tol_u and r_w <= tol_w:
                self._check(self.predictor.settle(P))
                self.settle(P, V, Fg)
                return NewtonReport(1, r_u / tol_u * NEWTON_RTOL, k, tuple(history), worst)
            if k == NEWTON_MAX_IT or not np.isfinite(r_u + r_w):
                break
            worst = max(worst, self._newton_step(P, R_w, H))
            diagnostics.stop_if(self._inverted(k), self.parts.comm)
        raise RunError(
            f"Newton (walls and water) did not converge: residuals {r_u / tol_u:.3g} and "
            f"{r_w / tol_w:.3g} times their tolerances after {k} iterations; likely cause: "
            f"growth too fast for the water to follow, {diagnostics.RATE_HINT}"
        )

    def _predict(self, P: np.ndarray) -> None:
        """u from the predictor (plantgrowth/models/micro/water_predictor.py) at the last turgor
        P, unless it inverts an element: then the last step's u."""
        previous = self.parts.u.x.array.copy()
        self._check(self.predictor.predict(P))
        if self.newton.min_det()[0] <= 0.0:
            self.parts.u.x.array[:] = previous

    def _check(self, report: SolveReport) -> None:
        """A failed or inaccurate linear solve stops the run (collectively)."""
        problems = diagnostics.solve_problems(report.reason, report.residual)
        diagnostics.stop_if(problems, self.parts.comm)

    def _newton_step(self, P: np.ndarray, R_w: np.ndarray, H: np.ndarray) -> float:
        """One Newton update of u and P (in place) from the residuals (``newton.b``: R_u) and
        the conductance matrix H; returns the true relative residual of its linear solve (a failed
        or inaccurate solve stops the run)."""
        newton, parts = self.newton, self.parts
        newton.A.zeroEntries()
        fem.petsc.assemble_matrix(newton.A, newton.J, bcs=parts.bcs)
        newton.A.assemble()
        F, D = self.columns(self.load_column), self.columns(self.area_column)
        du = newton.du
        dP, report = self.bordered.solve(F, D, self.dt * H, newton.b, R_w, du)
        self._check(report)
        parts.u.vector.axpy(-1.0, du)
        parts.u.x.scatter_forward()
        P -= dP
        self._set_turgor(P)
        return report.residual

    def _inverted(self, k: int) -> list[str]:
        det_min, where = self.newton.min_det()
        if det_min > 0.0:
            return []
        return [f"Newton (walls and water) iteration {k + 1}: inverted element (det F = "
                f"{det_min:.3g}) at x = ({where[0]:.4g}, {where[1]:.4g})"]  # fmt: skip
