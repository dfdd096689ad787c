"""Iterative refinement of a factorized solve with the residual in extended precision.

One step: ``r = b - A x`` with products and sums in long double (64-bit mantissa on x86-64),
rounded to double, ``A d = r`` with the same factors, ``x <- x + d``. An LU solve is backward
stable (MUMPS: componentwise backward error ~2 eps), so its forward error is up to ``kappa eps``:
kappa = 6e7 on the micro walls of an Nx = 8 irregular tissue (MUMPS's RINFOG(10)), and two LU
orderings of the same system differ by 1e-10 relative in u. A residual in double cannot see
that error: ``|A| |x|`` is 8e4 times ``|b|`` there (the thin walls' bending cancels), so its
round-off floor is ``1.7e-11 |b|``, the relative residual the LU already reaches, and
refinement in double stalls there. With the residual in long double one step brings the two
orderings to 4e-14 of each other (tests/test_micro_cells.py; a second step's correction: 1e-14
relative). Serial and 2-rank answers still differ by kappa times the assembly's rounding (A and
b summed in another order): docs/real_tissues.md, "Serial against two ranks".
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from dolfinx import fem
from petsc4py import PETSc

from plantgrowth.models.linear import SolveReport, relative_residual

EXTENDED = np.longdouble


class ExtendedRefinement:
    """Refinement steps for the solves of matrices of one sparsity pattern (distributed by
    rows: a row's columns may lie on any rank, so ``x`` is gathered by a PETSc scatter)."""

    def __init__(self) -> None:
        self._scatter: tuple[PETSc.Scatter, PETSc.Vec, np.ndarray] | None = None

    def _gathered(self, x: PETSc.Vec, columns: np.ndarray) -> np.ndarray:
        """``x`` at each stored entry's (global) column: a scatter of the columns this rank's
        rows use, made at the first call (the pattern is fixed)."""
        if self._scatter is None:
            needed, where = np.unique(columns, return_inverse=True)
            into = PETSc.Vec().createSeq(len(needed), comm=PETSc.COMM_SELF)
            index = PETSc.IS().createGeneral(needed.astype(PETSc.IntType), comm=PETSc.COMM_SELF)
            self._scatter = (PETSc.Scatter().create(x, index, into, None), into, where)
        scatter, into, where = self._scatter
        scatter.scatter(x, into, addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        return into.array_r[where]

    def residual(self, A: PETSc.Mat, x: PETSc.Vec, b: PETSc.Vec) -> np.ndarray:
        """This rank's owned rows of ``b - A x``, products and sums in long double. Every row of
        a finite element matrix holds its diagonal, so none is empty (``reduceat``)."""
        rows, columns, values = A.getValuesCSR()
        products = values.astype(EXTENDED) * self._gathered(x, columns).astype(EXTENDED)
        return b.array_r.astype(EXTENDED) - np.add.reduceat(products, rows[:-1])

    def refine(
        self, report: SolveReport, ksp: PETSc.KSP, A: PETSc.Mat, b: PETSc.Vec, u: fem.Function
    ) -> SolveReport:
        """One refinement step of ``u``, solved by ``ksp`` from ``A u = b`` with ``report``, in
        place: the refined solve's report (its residual recomputed)."""
        r, d = b.duplicate(), b.duplicate()
        r.array[:] = self.residual(A, u.vector, b)
        ksp.solve(r, d)
        u.vector.axpy(1.0, d)
        u.x.scatter_forward()
        for vector in (r, d):
            vector.destroy()
        return replace(report, residual=relative_residual(A, u.vector, b))
