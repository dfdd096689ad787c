"""Newton's method with a backtracking line search for the finite-kinematics problems
(docs/model.md section 10), with the exact UFL-derived Jacobian.

Iteration k: assemble ``R(u_k)`` and ``J(u_k) = dR/du``, solve ``J du = R`` with the problem's
linear solver (LU, or GMRES + GAMG with LU as fallback: :mod:`plantgrowth.models.linear`), then
``u_{k+1} = u_k - alpha du`` with alpha = 1, 1/2, 1/4, ... until the residual norm decreases
(Armijo) and no element inverts (``det F > 0`` in every cell). The initial guess is whatever u
holds: the previous step's solution. Dirichlet conditions are homogeneous, so every iterate
satisfies them and the residual is zeroed on their dofs (no lifting is needed).

Convergence: ``|R(u)| <= NEWTON_RTOL * |R_load| + floor``: ``R_load`` is the step's external
load (turgor and tractions, assembled at the initial guess), ``floor`` an absolute residual the
model gives (:data:`NEWTON_ATOL` times its stiffness times the square root of its area). Neither
grows with the growth mismatch that accumulates in ``R(0)`` (the residual at u = 0), against
which the test was once relative (issue 20: ``|R(0)|`` grew 3.4x by t = 5 on a homogeneous run).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.base.errors import RunError
from plantgrowth.base.mesh_samples import MeshSamples, det_degree
from plantgrowth.forms.finite import deformation_gradient, jacobian
from plantgrowth.models import diagnostics
from plantgrowth.models.linear import relative_residual

log = logging.getLogger("plantgrowth")

NEWTON_RTOL = 1e-10
"""Residual at convergence relative to the external load: the tolerance of its GMRES solves
(problem.NEWTON_KRYLOV_RTOL), 100 times below the time loop's residual bound
(diagnostics.RESIDUAL_BOUND), so a converged Newton solve is as accurate as a linear one."""
NEWTON_ATOL = 1e-11
"""The absolute floor's strain: ``floor = NEWTON_ATOL * stiffness * sqrt(area)`` is the residual
norm of a uniform stress error of 1e-11 times the stiffest modulus (``int P : grad psi_i`` is
about ``P h`` per node, over ``area / h^2`` nodes). It is what a step without loads (growth
mismatch only) converges to; 25 times the round-off of the assembled residual measured on
gradient_E_strain with finite kinematics at t = 60 (|R| = 6.4e-14 at convergence)."""
NEWTON_MAX_IT = 25
"""Newton iterations before a step fails (the reference scenes need 2-4)."""
LINE_SEARCH_HALVINGS = 10
"""Backtracking steps alpha = 1 ... 2^-10 before a step fails."""
ARMIJO = 1e-4
"""Sufficient decrease ``|R(u - alpha du)| <= (1 - ARMIJO alpha) |R(u)|``."""


@dataclass(frozen=True)
class NewtonReport:
    """Outcome of a converged Newton solve.

    reason: PETSc converged reason of the last linear solve (> 0); residual: final ``|R|``
    relative to the scale ``|R_load| + floor / NEWTON_RTOL`` (at most NEWTON_RTOL); iterations:
    Newton iterations; history: ``|R|`` (absolute) at each iterate, the first being the initial
    guess; linear_residual: worst true relative residual of the linear
    solves.
    """

    reason: int
    residual: float
    iterations: int
    history: tuple[float, ...]
    linear_residual: float


class NewtonSolver:
    """Solve ``R(u; psi) = 0`` for ``u`` (in place).

    Args:
        residual: the residual, a linear form in the test function, nonlinear in ``u``.
        u: the unknown; its values are the initial guess.
        bcs: homogeneous Dirichlet conditions.
        make_ksp: the linear solver for the Jacobian matrix (called once with it).
        load: the external-load part of the residual (turgor, tractions), whose norm at the
            initial guess the relative test is taken against (None: no external load).
        floor: the absolute residual floor of the current step (see :data:`NEWTON_ATOL`).
        stability: the smallest normalised acoustic eigenvalue over the tissue at the current
            u, and where (plantgrowth.models.stability); it ranks the initial guesses.
        fallback: a direct solver for it, made when a (Krylov) solve of make_ksp's fails: a
            Jacobian of finite kinematics can be indefinite (strong compression, follower
            loads), where GMRES + GAMG stagnates (it did on the L-shaped tissue pulled by
            3e-4 per length, which LU solves).
        predictor: writes the linear-kinematics solution at the current Fg into u (one linear
            solve). The initial guess is then the better of the previous solution and
            ``u_linear + offset``, offset = u_finite - u_linear of the previous solve (0 at
            first), which follows the growth of Fg to O(strain^2): the one where the law is
            strongly elliptic, else the more stable one, then the smaller residual (the
            residual norm of a collapsed state is small: ``Fe S`` vanishes with Fe, where the
            law is far from elliptic). Why a predictor: a turgor prestress ``(K_hom + (phi_w -
            1) I) P1`` that the elastic strain does not yet balance is compressive and, with
            the honeycomb's small shear modulus (nu12 ~ 0.96), makes the Jacobian nearly
            singular: from u = 0 Newton fails on the P1-gradient scenes, and from the previous
            step's u it needs 10 iterations instead of 3.
    """

    def __init__(
        self,
        residual: ufl.Form,
        u: fem.Function,
        bcs: list,
        make_ksp: Callable[[PETSc.Mat], PETSc.KSP],
        load: ufl.Form | None,
        floor: Callable[[], float],
        stability: Callable[[], tuple[float, np.ndarray]],
        predictor: Callable[[], object] | None = None,
        fallback: Callable[[PETSc.Mat], PETSc.KSP] | None = None,
    ) -> None:
        self.u, self.bcs, self.predictor, self.fallback = u, bcs, predictor, fallback
        self.floor, self.stability = floor, stability
        self.offset = fem.Function(u.function_space, name="u_offset")  # u_finite - u_linear
        self.comm = u.function_space.mesh.comm
        self.F = fem.form(residual)
        self.load = None if load is None else fem.form(load)
        self.J = fem.form(jacobian(residual, u))
        self.A = fem.petsc.create_matrix(self.J)
        self.b = fem.petsc.create_vector(self.F)
        self.du = self.A.createVecRight()
        self.ksp = make_ksp(self.A)
        msh, degree = u.function_space.mesh, det_degree(u)
        self._det = MeshSamples(ufl.det(deformation_gradient(u)), msh, degree)
        V = u.function_space
        n_nodes = V.dofmap.index_map.size_local
        self._node_points = V.tabulate_dof_coordinates()[:n_nodes, :2]

    @property
    def guess_functions(self) -> list[fem.Function]:
        """What the next initial guess is made of (u and the offset): a resume state."""
        return [self.u, self.offset]

    def residual_norm(self, form: fem.Form | None = None) -> float:
        """Assemble ``R(u)`` (or ``form``) into ``self.b`` (zero on Dirichlet dofs) and return
        its norm."""
        with self.b.localForm() as local:
            local.set(0.0)
        fem.petsc.assemble_vector(self.b, form or self.F)
        self.b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem.petsc.set_bc(self.b, self.bcs, self.u.vector, -1.0)
        return self.b.norm()

    def tolerance(self) -> float:
        """``NEWTON_RTOL |R_load| + floor`` at the current u (the step's initial guess)."""
        load = 0.0 if self.load is None else self.residual_norm(self.load)
        return NEWTON_RTOL * load + self.floor()

    def min_det(self) -> tuple[float, np.ndarray]:
        """Smallest ``det F`` over all cells (the exact minimum of its polynomial on each cell:
        :meth:`plantgrowth.base.mesh_samples.MeshSamples.cell_minima`) and where it is."""
        return global_extreme(*self._det.cell_minima(), self.comm, np.argmin)

    def _rank(self, r: float) -> tuple:
        """Order of initial guesses: not inverted, then strongly elliptic, then (if not) the
        more stable, then the smaller residual norm r."""
        if not (np.isfinite(r) and self.min_det()[0] > 0.0):
            return (False,)
        stable = self.stability()[0]
        return (True, stable >= 0.0, min(stable, 0.0), -r)

    def solve(self) -> NewtonReport:
        """Newton iterations from the initial guess; raises RunError (collectively) on failure."""
        du = self.du
        tol = self.tolerance()
        r, linear_u = self._predict(self.residual_norm(), tol)
        history, reason, worst_linear = [r], 1, 0.0
        for k in range(NEWTON_MAX_IT + 1):
            if r <= tol:
                if linear_u is not None:
                    self.offset.x.array[:] = self.u.x.array - linear_u
                return NewtonReport(reason, r / tol * NEWTON_RTOL, k, tuple(history), worst_linear)
            if k == NEWTON_MAX_IT or not np.isfinite(r):
                break
            self.A.zeroEntries()
            fem.petsc.assemble_matrix(self.A, self.J, bcs=self.bcs)
            self.A.assemble()
            reason, linear = self._solve_linear(du)
            worst_linear = max(worst_linear, linear)
            r = self._line_search(r, tol, k)
            history.append(r)
        raise RunError(
            f"Newton did not converge: residual {r / tol:.3g} times the tolerance after {k} "
            f"iterations, largest at x = {self._largest_residual_place()}; likely cause: loads "
            f"or growth contrast too strong for the elastic tissue, {diagnostics.RATE_HINT}"
        )

    def _solve_linear(self, x: PETSc.Vec) -> tuple[int, float]:
        """``J x = b`` (b: the assembled residual): PETSc's reason and the true relative
        residual; a failed Krylov solve is repeated with ``fallback``, which solves from then
        on; a failed solve without one stops the run (collectively)."""
        while True:
            self.ksp.solve(self.b, x)
            reason = self.ksp.getConvergedReason()
            linear = relative_residual(self.A, x, self.b)
            krylov = self.ksp.getType() != "preonly"
            iterations = self.ksp.getIterationNumber() if krylov else 0
            problems = diagnostics.solve_problems(reason, linear, iterations, self.ksp.getType())
            if not problems or self.fallback is None:  # reason, residual: the same on all ranks
                diagnostics.stop_if(problems, self.comm)
                return reason, linear
            log.warning(
                "warning: Newton: %s + GAMG stopped (PETSc reason %d, relative residual %.3g "
                "after %d iterations): the Jacobian is indefinite or far from symmetric here; "
                "LU solves it from now on", self.ksp.getType().upper(), reason, linear, iterations,
            )  # fmt: skip
            self.ksp.destroy()
            self.ksp, self.fallback = self.fallback(self.A), None

    def _predict(self, r: float, tol: float) -> tuple[float, np.ndarray | None]:
        """The initial guess (see the class doc) unless u already solves the problem: the
        residual norm there and the linear solution (None: no prediction)."""
        if self.predictor is None or r <= tol:
            return r, None
        previous = self.u.x.array.copy()
        rank_previous = self._rank(r)
        self.predictor()
        linear_u = self.u.x.array.copy()
        self.u.x.array[:] = linear_u + self.offset.x.array
        predicted = self.residual_norm()
        if self._rank(predicted) > rank_previous:
            return predicted, linear_u
        self.u.x.array[:] = previous
        return self.residual_norm(), linear_u

    def _line_search(self, r: float, tol: float, k: int) -> float:
        """``u <- u - alpha du`` for the first alpha = 2^-j that leaves no element inverted and
        either meets the tolerance or passes a decrease test; returns the new residual norm
        (``self.b`` holds the residual).

        Decrease: the residual norm's (Armijo, ``|R_trial| <= (1 - ARMIJO alpha) |R|``), or,
        when that fails, Deuflhard's natural monotonicity ``|J^{-1} R_trial| <= (1 - alpha / 4)
        |du|`` (one more solve with the current Jacobian, its convergence checked like every
        other). The second, affine-invariant test accepts the full steps of thin walls that
        bend and rotate, where the residual norm first grows a hundredfold before Newton
        converges quadratically (micro model)."""
        start = self.u.vector.copy()
        natural = self.du.duplicate()
        du_norm = self.du.norm()
        alpha, det_min, where = 1.0, 1.0, None
        try:
            for _ in range(LINE_SEARCH_HALVINGS + 1):
                self.u.vector.waxpy(-alpha, self.du, start)
                self.u.x.scatter_forward()
                det_min, where = self.min_det()
                trial = self.residual_norm() if det_min > 0.0 else np.inf
                if trial <= tol or trial <= (1.0 - ARMIJO * alpha) * r:
                    return trial
                if np.isfinite(trial):
                    self._solve_linear(natural)
                    accepted = natural.norm() <= (1.0 - 0.25 * alpha) * du_norm
                    self.residual_norm()  # b again holds the residual
                    if accepted:
                        return trial
                alpha *= 0.5
            self.u.vector.array[:] = start.array
            self.u.x.scatter_forward()
            self.residual_norm()
        finally:
            start.destroy()
            natural.destroy()
        if det_min <= 0.0:
            raise RunError(
                f"Newton iteration {k + 1}: inverted element (det F = {det_min:.3g} <= 0) at x = "
                f"({where[0]:.4g}, {where[1]:.4g}) even after {LINE_SEARCH_HALVINGS} step "
                "halvings; likely cause: loads or growth contrast too strong for the tissue, "
                + diagnostics.RATE_HINT
            )
        raise RunError(
            f"Newton did not converge: the line search found no decrease of the residual "
            f"({r / tol:.3g} times the tolerance) at iteration {k + 1}, largest at x = "
            f"{self._largest_residual_place()}; likely cause: loads or growth contrast too "
            f"strong for the elastic tissue, {diagnostics.RATE_HINT}"
        )

    def _largest_residual_place(self) -> str:
        """Where ``|R|`` is largest (a node, over all ranks), as "(x1, x2)"; b holds R."""
        bs = self.u.function_space.dofmap.index_map_bs
        local = np.abs(self.b.array).reshape(-1, bs).max(axis=1)
        x = global_extreme(local, self._node_points, self.comm, np.argmax)[1]
        return f"({x[0]:.4g}, {x[1]:.4g})"


def global_extreme(
    values: np.ndarray, points: np.ndarray, comm: MPI.Comm, pick
) -> tuple[float, np.ndarray]:
    """(value, point) of the smallest (pick = np.argmin) or largest (np.argmax) value, all ranks."""
    i = int(pick(values)) if len(values) else None
    mine = (float(values[i]), points[i]) if i is not None else None
    found = [x for x in comm.allgather(mine) if x is not None]
    index = int(pick([v for v, _ in found]))
    return found[index]


def log_report(name: str, report: NewtonReport) -> None:
    """One log line per solve: iterations, relative residual and the residual sequence."""
    log.info(
        "%s Newton: %d iterations, relative residual %.2g (|R|: %s)",
        name, report.iterations, report.residual,
        " ".join(f"{r:.2e}" for r in report.history),
    )  # fmt: skip
