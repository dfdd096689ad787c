"""The initial guess of the micro model's finite water step (docs/model.md, water fluxes): the
walls' predictor at the last step's turgor, with its offset kept at the solved turgor.

The walls' Newton predicts u by ``u_lin + e`` (plantgrowth/models/newton.py): u_lin the linear
kinematics' solution at the step's Fg, ``K u_lin = f + B P``, and the offset ``e = u^n -
u_lin^n`` of the last solved step, the linear solution at that step's Fg and the SAME turgor.
With water, P changes from step to step (by a third a step in the water-limited transient of
the benchmark) and the offset with it (finite walls stiffen under turgor: |e| falls 20.6 ->
11.7 -> 7.4 as P falls 1e-3 -> 5.8e-4 -> 3.6e-4), so the guess is (u_lin(P^n) + e^n, P^n):
walls in equilibrium at the last turgor and the new Fg, from which Newton's first iteration
moves P along the exact tangent. After the step converges at P^{n+1}, the offset is renewed at
that turgor, ``u_lin(P^{n+1}) = u_lin(P^n) + K^{-1} B (P^{n+1} - P^n)`` (the factorization of K
reused). Measured (Nx = 8, the benchmark's scene): 4, 4, 4 Newton iterations a step against
7, 5, 5 from (u^n, P^n); the guess (u_lin(P^{n+1}) + e^n, P^{n+1}) with the solved turgor
inverts elements, e being a turgor's. Sub-steps of the adaptive integrator predict from the last
solve, kept or rejected, as the walls' Newton does: its u, P and e belong together.
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem
from petsc4py import PETSc

from plantgrowth.models.linear import SolveReport, relative_residual
from plantgrowth.models.micro.cell_columns import CellColumns
from plantgrowth.models.micro.turgor_solve import ElasticParts


class WaterPredictor:
    """u at the start of a finite water step, and the offset e after it.

    Args:
        parts: the walls' linear problem (K, and b = f + B P with the turgor the residual reads).
        column: the membrane pressure load of the cells ``columns``' indicator marks (B's form).
        columns: splits it into one column per cell.
        offset: e (the walls' Newton's, which sets it at the initial equilibrium; saved with u
            in the run's state, so a resumed run predicts as the straight one).
    """

    def __init__(self, parts: ElasticParts, column: fem.Form, columns: CellColumns,
                 offset: fem.Function) -> None:  # fmt: skip
        self.parts, self.column, self.columns, self.offset = parts, column, columns, offset
        self.u_lin: PETSc.Vec = parts.u.vector.duplicate()
        self.P: np.ndarray | None = None  # the turgor u_lin is at

    def _solve(self, rhs: PETSc.Vec, x: PETSc.Vec) -> SolveReport:
        """``K x = rhs`` with the walls' solver (collective)."""
        parts = self.parts
        parts.ksp.solve(rhs, x)
        return SolveReport(parts.ksp.getConvergedReason(), relative_residual(parts.A, x, rhs))

    def predict(self, P: np.ndarray) -> SolveReport:
        """u = u_lin + e at the turgor P the walls' load holds and the Fg the walls' problem
        holds (collective); the linear solve's report."""
        parts = self.parts
        parts.assemble()
        report = self._solve(parts.b, self.u_lin)
        self.P = P.copy()
        parts.u.vector.waxpy(1.0, self.u_lin, self.offset.vector)
        parts.u.x.scatter_forward()
        return report

    def settle(self, P: np.ndarray) -> SolveReport:
        """e = u - u_lin(P) for the solved u and turgor P, u_lin(P) from the prediction's by
        one more solve with K's factorization (collective); that solve's report."""
        parts = self.parts
        rhs, x = self.u_lin.duplicate(), self.u_lin.duplicate()
        rhs.array[:] = self.columns(self.column) @ (P - self.P)
        report = self._solve(rhs, x)
        self.u_lin.axpy(1.0, x)
        self.offset.vector.waxpy(-1.0, self.u_lin, parts.u.vector)
        self.offset.x.scatter_forward()
        rhs.destroy()
        x.destroy()
        return report
