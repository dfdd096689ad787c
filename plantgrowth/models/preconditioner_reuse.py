"""A Krylov solver's preconditioner kept across time steps, with the rule that rebuilds it.

The macro matrix changes slowly (growth moves E_hom and Fg by about 1% a step), so a multigrid
hierarchy built for an earlier step still preconditions the current one, at a few more
iterations. The rule: rebuild for the next solve once a solve needs more than ``growth`` times
the iterations of the solve right after the last rebuild, ``n_k > growth n_rebuild``; a solve
that fails with a kept preconditioner is repeated with a rebuilt one.
"""

from __future__ import annotations

from collections.abc import Callable

from petsc4py import PETSc

from plantgrowth.models.linear import SolveReport


class PreconditionerReuse:
    """Solves through ``ksp`` that keep its preconditioner until the rebuild rule fires.

    Args:
        ksp: the Krylov solver (its operator is re-assembled in place between solves).
        growth: the iteration growth that triggers a rebuild (``n_k > growth n_rebuild``);
            ``None``: rebuild before every solve (PETSc's default behaviour).
    """

    def __init__(self, ksp: PETSc.KSP, growth: float | None) -> None:
        self.ksp, self.growth = ksp, growth
        self.rebuild_next = True
        self.reference = 0  # iterations of the solve right after the last rebuild
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
        self.rebuild_next = (
            self.growth is not None and report.iterations > self.growth * self.reference
        )
        return report

    def _solve(self, solve: Callable[[], SolveReport], rebuild: bool) -> SolveReport:
        self.ksp.getPC().setReusePreconditioner(not rebuild)
        return solve()
