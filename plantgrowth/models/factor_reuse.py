"""An LU factorization kept across time steps: the current matrix solved by iterative refinement
with the factors of an earlier one.

Each step re-assembles the macro matrix ``A_n``, which growth moves little (on the reference
scene by round-off only: ``Jg Fg^-1 E_hom Fg^-T`` with ``Fg = lambda I``). With the factors
``L U = A_k`` of an earlier step, ``x_0 = (LU)^-1 b``, ``x_{i+1} = x_i + (LU)^-1 (b - A_n x_i)``
converges as ``|I - A_k^-1 A_n|^i``. The solve is accepted once the true relative residual
``|b - A_n x| / |b|`` is at most ``rtol`` times the one the factorization left on its own system
(the round-off floor of a fresh LU solve: 4.6e-14 on the reference scene); ``A_n`` is factorized
when a correction gains less than ``contraction`` or ``max_it`` corrections do not get there. A
step then costs a triangular solve and a product (0.3 ms on the reference scene's 4,340 dofs)
instead of a numeric factorization (13 ms).

Exact resume: the coefficients the factorized matrix was assembled from and its floor are part
of the run's state (:meth:`FactorReuse.factorized`); a resumed run factorizes the same matrix
(:meth:`FactorReuse.refactor`) and repeats the straight run.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from dolfinx import fem
from petsc4py import PETSc

from plantgrowth.models.linear import relative_residual

REFINE_RTOL = 2.0
"""Accept a solve with kept factors at twice the relative residual a fresh factorization left:
the kept factors of a round-off-close matrix give 1.0-1.1 times it without a correction."""
REFINE_MAX_IT = 4
"""Corrections before factorizing afresh."""
CONTRACTION = 0.1
"""A correction must reduce the residual at least tenfold, else the matrix moved too far for the
kept factors and is factorized (a factor of a matrix within 1e-3 gains about three orders)."""


class FactorReuse:
    """Solves ``A x = b`` through a PREONLY + LU ``ksp`` whose factors are kept while they serve.

    Args:
        ksp: the direct solver; its operator is re-assembled in place between solves.
        coefficients: the functions the operator is assembled from (copied at a factorization:
            :meth:`factorized`).
    """

    def __init__(self, ksp: PETSc.KSP, coefficients: tuple[fem.Function, ...]) -> None:
        self.ksp, self.coefficients = ksp, coefficients
        self.floor: float | None = None  # relative residual of the last fresh solve
        self.snapshot: list[np.ndarray] = []
        self.factorizations = 0

    def solve(self, A: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec) -> None:
        """Solve into x with the kept factors (refined), or factorize A and solve. Serial runs
        only: under mpirun the distributed LU's round-off differs from run to run (its floor by
        about 1 %), so refactorization steps, and answers at 1e-12, would too."""
        if self.floor is not None and A.getComm().getSize() == 1 and self._refine(A, b, x):
            return
        self._factorize()
        self.ksp.solve(b, x)
        self.floor = relative_residual(A, x, b)

    def factorized(self) -> tuple[list[np.ndarray], float] | None:
        """The coefficients' arrays (local, dof order) the kept factors were made from and the
        floor, or None before the first factorization."""
        return None if self.floor is None else (self.snapshot, self.floor)

    def refactor(self, assemble: Callable[[], object], floor: float) -> None:
        """Factorize the solver's operator after ``assemble()`` (assembled from the coefficients as
        :meth:`factorized` gave them) and keep ``floor`` (a resumed run)."""
        assemble()
        self._factorize()
        self.floor = floor

    def _factorize(self) -> None:
        pc = self.ksp.getPC()
        pc.setReusePreconditioner(False)
        pc.setUp()  # the numeric factorization of A's values (KSPSetUp would not redo it)
        pc.setReusePreconditioner(True)
        self.snapshot = [f.x.array.copy() for f in self.coefficients]
        self.factorizations += 1

    def _refine(self, A: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec) -> bool:
        """x from the kept factors, corrected until its residual is within REFINE_RTOL of the
        floor; False when a correction contracts too little or REFINE_MAX_IT do not suffice."""
        self.ksp.solve(b, x)
        r, d = b.duplicate(), b.duplicate()
        scale = b.norm()
        target = REFINE_RTOL * self.floor * scale
        try:
            previous = np.inf
            for _ in range(REFINE_MAX_IT + 1):
                A.mult(x, r)
                r.aypx(-1.0, b)
                norm = r.norm()
                if norm <= target:
                    return True
                if norm > CONTRACTION * previous:
                    return False
                previous = norm
                self.ksp.solve(r, d)
                x.axpy(1.0, d)
            return False
        finally:
            r.destroy()
            d.destroy()

