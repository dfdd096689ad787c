"""The micro model's step with water (docs/model.md, water fluxes, linear kinematics): the wall
displacement u and each cell's turgor P from the symmetric system

    [ K    -B    ] [u]   [ f                                            ]
    [ -B^T -dt H ] [P] = [ -(W^n - V0 + dt (H Pi + sum_s g_s psi_s))    ]

(K: the walls' stiffness with its Dirichlet rows; f: the growth load; B: one column per cell,
the membrane pressure load of that cell for P = 1, which is also the derivative of its lumen
area in u; H: the water network, plantgrowth/models/micro/water.py).

Solved as one bordered sparse system per step (plantgrowth/models/micro/bordered.py): one
factorization of K bordered by the cells' columns and -dt H. The first step (the given turgor)
solves K u = f + B P.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc
from scipy import sparse

from plantgrowth.models.linear import SolveReport, relative_residual
from plantgrowth.models.micro.bordered import BorderedSolve
from plantgrowth.models.micro.cell_columns import CellColumns
from plantgrowth.models.micro.water import CellWater, WaterState, lumen_offset
from plantgrowth.models.water_row import WaterLedger


@dataclass(frozen=True)
class ElasticParts:
    """The walls' linear problem as the micro model holds it.

    Attributes:
        assemble: assembles K into ``A`` and f into ``b`` (Dirichlet conditions applied).
        A, b, ksp, u: its matrix, right-hand side, solver and solution.
        Fg: the growth tensor (DG0); bcs: the Dirichlet conditions.
        set_cells: sets a DG0 function from values per biological cell.
        comm: the mesh's communicator.
    """

    assemble: Callable[[], None]
    A: PETSc.Mat
    b: PETSc.Vec
    ksp: PETSc.KSP
    u: fem.Function
    Fg: fem.Function
    bcs: list
    set_cells: Callable[[fem.Function, np.ndarray], None]
    comm: MPI.Comm


class WaterSteps:
    """The water held from step to step: :meth:`settle` records a solved step, :meth:`commit`
    makes its water the next step's W^n, :meth:`restore` continues a saved run. A step taken in
    sub-steps (the adaptive integrator): :meth:`substep` sets the next solve's dt and time,
    :meth:`keep` makes a kept sub-step's water the next solve's W^n (a rejected one is left)."""

    def __init__(self, water: CellWater, dt: float) -> None:
        self.water, self.dt = water, dt  # dt: the step the next solve advances the water by
        self.held: np.ndarray | None = None  # the water W^n of the last committed step
        self.t = 0.0  # the time of the next step to solve
        self.remaining = 0.0  # the next solve ends this long before t (a sub-step)
        self.last: WaterState | None = None
        self.P: np.ndarray | None = None  # the last step's turgor
        self.balance_error = 0.0
        self.ledger = WaterLedger()  # the step's sub-steps' water in

    @property
    def reach(self) -> float:
        """The time the next solve ends at."""
        return self.t - self.remaining

    def settle(self, P: np.ndarray, held: np.ndarray, Fg: np.ndarray) -> None:
        """Record a solved step: turgor P, water held; what came in over the step minus the
        change of the water held (0 at the initial state); the inflows over the step's kept
        sub-steps and this solve."""
        self.P, state = P, self.water.state(P, held, Fg, self.reach)
        dt = None if self.held is None else self.dt
        self.balance_error, supplied, inflow = self.ledger.record(
            dt, held.sum(), state.supplied, state.inflow
        )
        self.last = replace(state, inflow=inflow, supplied=supplied)

    def substep(self, dt: float, remaining: float) -> None:
        """The next solve advances the water by dt, to ``remaining`` before the step's end."""
        self.dt, self.remaining = dt, remaining

    def keep(self) -> None:
        """The last solve's water becomes the next solve's W^n (a kept sub-step)."""
        self.held = self.last.water
        self.ledger.keep()

    def commit(self, dt: float) -> None:
        """The step's water becomes the next step's W^n."""
        self.held = self.last.water
        self.t += dt
        self.dt, self.remaining = dt, 0.0
        self.ledger.close()

    def restore(self, held: np.ndarray, t: float, P: np.ndarray) -> None:
        """Continue from saved water at the time of the next step (P: the last turgor)."""
        self.held, self.t, self.P = held, t, P
        self.ledger.close(held.sum())


class TurgorSolve(WaterSteps):
    """One step of u and P with linear kinematics.

    Args:
        parts: the walls' problem.
        column: the form of the membrane pressure load of the cells ``columns``' indicator
            marks; columns: splits it into one column per cell.
        water: the water network; lumen_area: (n,) the cells' reference lumen areas.
        dt: the step.
    """

    def __init__(
        self, parts: ElasticParts, column: fem.Form, columns: CellColumns, water: CellWater,
        lumen_area: np.ndarray, dt: float,
    ) -> None:  # fmt: skip
        super().__init__(water, dt)
        self.parts, self.column, self.columns = parts, column, columns
        self.lumen_area = lumen_area
        self.bordered = BorderedSolve(parts.A, water.n, parts.comm, "plantgrowth_micro_water_")

    def _lumen_terms(self, B: sparse.csc_matrix) -> np.ndarray:
        """B^T u (collective)."""
        return self.parts.comm.allreduce(B.T @ self.parts.u.vector.array, op=MPI.SUM)

    def solve(self, Fg: np.ndarray) -> SolveReport:
        """u and P at ``Fg``: the first call is the initial equilibrium, P = Pi + psi_0
        (docs/model.md, water fluxes), each later one the backward Euler step from the water
        committed last."""
        parts, water = self.parts, self.water
        B = self.columns(self.column)
        parts.assemble()
        V0 = lumen_offset(self.lumen_area, Fg)
        if self.held is None:
            P = water.Pi + water.hydraulics.initial_potential
            report = self._given(B, P)
        else:
            H, h = water.step_terms(self.held, V0, Fg, self.reach, self.dt)
            P, report = self.bordered.solve(-B, -B, -self.dt * H, parts.b, -h, parts.u.vector)
        parts.u.x.scatter_forward()
        self.settle(P, V0 + self._lumen_terms(B), Fg)
        return report

    def _given(self, B: sparse.csc_matrix, P: np.ndarray) -> SolveReport:
        """u from ``K u = f + B P`` at the given turgor P."""
        parts = self.parts
        rhs = parts.b.copy()
        rhs.array[:] += B @ P
        parts.ksp.solve(rhs, parts.u.vector)
        report = SolveReport(
            parts.ksp.getConvergedReason(), relative_residual(parts.A, parts.u.vector, rhs)
        )
        rhs.destroy()
        return report
