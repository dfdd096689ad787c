"""A Krylov solver's preconditioner kept across time steps, with the rule that rebuilds it.

The macro matrix changes slowly (growth moves E_hom and Fg by about 1% a step), so a multigrid
hierarchy built for an earlier step still preconditions the current one, at a few more
iterations. The rule: rebuild for the next solve once a solve needs more than both ``growth``
times and ``setup`` more than the fewest iterations any solve took since the last rebuild,
``n_k > max(growth n_best, n_best + setup)``; a solve that fails with a kept preconditioner is
repeated with a rebuilt one. The fewest, not the first: the solve right after a rebuild may
start cold (step 0, a resumed run: 26-30 on the organ scene) while the later ones start from
earlier solutions (2-5), and measured against the cold count the rule could never fire (the
organ scene's 60 steps built one hierarchy). On the 1e5-dof tissue of the scaling study (40
steps, 1 rank) it now rebuilds 3 times, for 289 CG iterations against 302; its 7-9 a step
from step 26 on stay with a fresh hierarchy, so they are not the hierarchy's age.
"""

from __future__ import annotations

from collections.abc import Callable

from petsc4py import PETSc

from plantgrowth.models.linear import SolveReport


class PreconditionerReuse:
    """Solves through ``ksp`` that keep its preconditioner until the rebuild rule fires.

    Args:
        ksp: the Krylov solver (its operator is re-assembled in place between solves).
        growth: the iteration growth that triggers a rebuild; ``None``: rebuild before every
            solve (PETSc's default behaviour).
        setup: a rebuild's cost in iterations: the excess that triggers one.
    """

    def __init__(self, ksp: PETSc.KSP, growth: float | None, setup: int = 0) -> None:
        self.ksp, self.growth, self.setup = ksp, growth, setup
        self.rebuild_next = True
        self.reference = 0  # the fewest iterations of a solve since the last rebuild
        self.rebuilds = 0

    def solve(self, solve: Callable[[], SolveReport], restart: Callable[[], None]) -> SolveReport:
        """``solve()`` (assemble and solve) with the kept or a rebuilt preconditioner;
        ``restart()`` resets the initial guess before a failed solve is repeated."""
        rebuild = self.rebuild_next or self.growth is None
        report = self._solve(solve, rebuild)
        if not rebuild and (report.reason <= 0 or report.residual > report.bound):
            restart()
            report, rebuild = self._solve(solve, True), True
        self.rebuilds += rebuild
        # a solve whose initial guess met the tolerance (0 iterations) sets no reference
        if report.iterations > 0 and (rebuild or self.reference == 0):
            self.reference = report.iterations
        elif report.iterations > 0:
            self.reference = min(self.reference, report.iterations)
        threshold = max((self.growth or 0.0) * self.reference, self.reference + self.setup)
        self.rebuild_next = self.growth is not None and report.iterations > threshold
        return report

    def _solve(self, solve: Callable[[], SolveReport], rebuild: bool) -> SolveReport:
        self.ksp.getPC().setReusePreconditioner(not rebuild)
        return solve()
