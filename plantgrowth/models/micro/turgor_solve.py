"""The micro model's step with water (docs/model.md, water fluxes, linear kinematics): the wall
displacement u and each cell's turgor P from the symmetric system

    [ K    -B    ] [u]   [ f                                            ]
    [ -B^T -dt H ] [P] = [ -(W^n - V0 + dt (H Pi + sum_s g_s psi_s))    ]

(K: the walls' stiffness with its Dirichlet rows; f: the growth load; B: one column per cell,
the membrane pressure load of that cell for P = 1, which is also the derivative of its lumen
area in u; H: the water network, plantgrowth/models/micro/water.py).

Solved by its Schur complement: the columns K^{-1} B_c are one back-solve each with the
factorization the step's elasticity solve made anyway, so S = B^T K^{-1} B (n x n, dense,
reduced over the ranks) costs n back-solves, then ``(S + dt H) P = ...`` is solved by every
rank alike and u by one more back-solve. Fine for up to a few hundred cells (the cost grows as
n back-solves per step); a bordered matrix for PETSc would be the way beyond.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc
from scipy import sparse

from plantgrowth.models.linear import SolveReport, relative_residual
from plantgrowth.models.micro.water import CellWater, WaterState, lumen_offset


@dataclass(frozen=True)
class ElasticParts:
    """The walls' linear problem as the micro model holds it.

    Attributes:
        solve: solves K u = f into u (assembling K and f, factorizing K), leaving the assembled
            K in ``A`` and f in ``b``.
        A, b, ksp, u: its matrix, right-hand side, solver and solution.
        Fg: the growth tensor (DG0); bcs: the Dirichlet conditions.
        set_cells: sets a DG0 function from values per biological cell.
        comm: the mesh's communicator.
    """

    solve: Callable[[], SolveReport]
    A: PETSc.Mat
    b: PETSc.Vec
    ksp: PETSc.KSP
    u: fem.Function
    Fg: fem.Function
    bcs: list
    set_cells: Callable[[fem.Function, np.ndarray], None]
    comm: MPI.Comm


class TurgorSolve:
    """One step of u and P; the water held is committed by :meth:`commit`.

    Args:
        parts: the walls' problem.
        column: the form of one cell's membrane pressure load, ``indicator`` its cell's DG0
            indicator (the columns are zero on the Dirichlet dofs).
        water: the water network; lumen_area: (n,) the cells' reference lumen areas.
        dt: the step.
    """

    def __init__(
        self, parts: ElasticParts, column: fem.Form, indicator: fem.Function, water: CellWater,
        lumen_area: np.ndarray, dt: float,
    ) -> None:  # fmt: skip
        self.parts, self.column, self.indicator = parts, column, indicator
        self.water, self.lumen_area, self.dt = water, lumen_area, dt
        self.vector = fem.petsc.create_vector(column)
        self.held: np.ndarray | None = None  # the water W^n of the last committed step
        self.t = 0.0  # the time of the next step to solve
        self.last: WaterState | None = None
        self.balance_error = 0.0

    def _columns(self) -> sparse.csc_matrix:
        """B: (owned dofs, cells), this rank's rows of each cell's pressure load for P = 1."""
        n = self.water.n
        rows, cols, values = [], [], []
        for c in range(n):
            self.parts.set_cells(self.indicator, np.eye(1, n, c)[0])
            with self.vector.localForm() as local:
                local.set(0.0)
            fem.petsc.assemble_vector(self.vector, self.column)
            # membrane facets next to a ghost cell: their share goes to the owner
            self.vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            fem.petsc.set_bc(self.vector, self.parts.bcs)
            nonzero = np.flatnonzero(self.vector.array)
            rows.append(nonzero)
            cols.append(np.full(len(nonzero), c))
            values.append(self.vector.array[nonzero])
        shape = (len(self.vector.array), n)
        return sparse.csc_matrix(
            (np.concatenate(values), (np.concatenate(rows), np.concatenate(cols))), shape
        )

    def _schur(self, B: sparse.csc_matrix) -> np.ndarray:
        """S = B^T K^{-1} B (collective; K factorized), symmetric to round-off."""
        S = np.empty((B.shape[1], B.shape[1]))
        z = self.vector.duplicate()
        for c in range(B.shape[1]):
            self.vector.array[:] = B[:, c].toarray().ravel()
            self.parts.ksp.solve(self.vector, z)
            S[:, c] = B.T @ z.array
        z.destroy()
        S = self.parts.comm.allreduce(S, op=MPI.SUM)
        return 0.5 * (S + S.T)

    def _lumen_terms(self, B: sparse.csc_matrix) -> np.ndarray:
        """B^T u (collective)."""
        return self.parts.comm.allreduce(B.T @ self.parts.u.vector.array, op=MPI.SUM)

    def solve(self, Fg: np.ndarray) -> SolveReport:
        """u and P at ``Fg``: the first call is the initial equilibrium, P = Pi + psi_0
        (docs/model.md, water fluxes), each later one the backward Euler step from the water
        committed last."""
        B = self._columns()
        parts = self.parts
        parts.solve()  # u = u_f = K^{-1} f, K factorized, b = f
        V0 = lumen_offset(self.lumen_area, Fg)
        water = self.water
        if self.held is None:
            P = water.Pi + water.hydraulics.initial_potential
        else:
            S = self._schur(B)
            P = water.turgor(S, self._lumen_terms(B), self.held, V0, Fg, self.t, self.dt)
        rhs = parts.b.copy()
        rhs.array[:] += B @ P
        parts.ksp.solve(rhs, parts.u.vector)
        parts.u.x.scatter_forward()
        residual = relative_residual(parts.A, parts.u.vector, rhs)
        report = SolveReport(parts.ksp.getConvergedReason(), residual)
        rhs.destroy()
        held = V0 + self._lumen_terms(B)
        self.last = water.state(P, held, Fg, self.t)
        if self.held is not None:  # what came in minus the change of the water held
            gained = self.dt * sum(self.last.supplied.values())
            self.balance_error = gained - (held.sum() - self.held.sum())
        return report

    def commit(self, dt: float) -> None:
        """The step's water becomes the next step's W^n."""
        self.held = self.last.water
        self.t += dt

    def restore(self, held: np.ndarray, t: float) -> None:
        """Continue from saved water at the time of the next step."""
        self.held, self.t = held, t
