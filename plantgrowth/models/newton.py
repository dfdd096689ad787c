"""Newton's method with a backtracking line search for the finite-kinematics problems
(docs/model.md section 10), with the exact UFL-derived Jacobian.

Iteration k: assemble ``R(u_k)`` and ``J(u_k) = dR/du``, solve ``J du = R`` with the problem's
linear solver (LU, or GMRES + GAMG with LU as fallback: :mod:`plantgrowth.models.linear`), then
``u_{k+1} = u_k - alpha du`` with alpha = 1, 1/2, 1/4, ... until the residual norm decreases
(Armijo) and no element inverts (``det F > 0`` in every cell). The initial guess is whatever u
holds: the previous step's solution. Dirichlet conditions are homogeneous, so every iterate
satisfies them and the residual is zeroed on their dofs (no lifting is needed).

Convergence: ``|R(u)| <= NEWTON_RTOL * scale`` with ``scale = max(|R(0)|, NEWTON_FLOOR)``:
``R(0)`` is the load of the step (growth, turgor, tractions at u = 0), the quantity a linear
solve's relative residual is measured against (``|b - A x| / |b|``).
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
from plantgrowth.forms.finite import deformation_gradient, jacobian, smallest_elastic_stretch
from plantgrowth.models import diagnostics
from plantgrowth.models.linear import relative_residual

log = logging.getLogger("plantgrowth")

NEWTON_RTOL = 1e-10
"""Relative residual at convergence: the macro CG tolerance (macro_problem.MACRO_RTOL), 100 times
below the time loop's residual bound (diagnostics.RESIDUAL_BOUND), so a converged Newton solve
is as accurate as a linear one. Quadratic convergence makes the last iteration overshoot it by
orders of magnitude, so the stopping point hardly depends on it."""
NEWTON_FLOOR = 1e-6
"""Smallest load norm ``|R(0)|`` the relative test is taken against: steps without loads (a pure
rotation as growth, P1 = 0) stop at ``|R| <= 1e-16``, the assembled residual's round-off for
stresses of order 1; reference loads are ~1e-3 (P1 = 0.001), far above the floor."""
NEWTON_MAX_IT = 25
"""Newton iterations before a step fails (the reference scenes need 2-4)."""
LINE_SEARCH_HALVINGS = 10
"""Backtracking steps alpha = 1 ... 2^-10 before a step fails."""
ARMIJO = 1e-4
"""Sufficient decrease ``|R(u - alpha du)| <= (1 - ARMIJO alpha) |R(u)|``."""
STRETCH_FLOOR = 3.0**-0.5
"""Smallest principal elastic stretch of an admissible state. St Venant-Kirchhoff stress (walls;
the homogenized ``S = E_hom Ee``) falls under further compression below stretch 1/sqrt(3) (in 1D
``P = E lam (lam^2 - 1) / 2``, ``dP/dlam < 0`` there), and ``Fe = 0`` solves the equations with
zero first Piola stress: a collapsed branch. Newton from u = 0 with a pre-grown Fg0 = diag(1, 4)
(``Fe = diag(1, 1/4)``) converged to it (area 4e-20) before this floor."""


@dataclass(frozen=True)
class NewtonReport:
    """Outcome of a converged Newton solve.

    reason: PETSc converged reason of the last linear solve (> 0); residual: final ``|R| /
    scale``; iterations: Newton iterations; history: ``|R|`` (absolute) at each iterate, the
    first being the initial guess; linear_residual: worst true relative residual of the linear
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
        Fg: the growth tensor (for the elastic stretch ``Fe = (I + grad u) Fg^-1``).
        bcs: homogeneous Dirichlet conditions.
        make_ksp: the linear solver for the Jacobian matrix (called once with it).
        fallback: a direct solver for it, made when a (Krylov) solve of make_ksp's fails: a
            Jacobian of finite kinematics can be indefinite (strong compression, follower
            loads), where GMRES + GAMG stagnates (it did on the L-shaped tissue pulled by
            3e-4 per length, which LU solves).
        predictor: writes the linear-kinematics solution at the current Fg into u (one linear
            solve). The initial guess is then the better (smaller residual) of the previous
            solution and ``u_linear + offset``, offset = u_finite - u_linear of the previous
            solve (0 at first), which follows the growth of Fg to O(strain^2). A guess whose
            smallest elastic stretch is below STRETCH_FLOOR loses to one above it (the
            residual norm of a compressed state is small: ``Fe S`` vanishes with Fe). Why: a turgor
            prestress ``(K_hom + (phi_w - 1) I) P1`` that the elastic strain does not yet
            balance is compressive and, with the honeycomb's small shear modulus (nu12 ~ 0.96),
            makes the Jacobian nearly singular: from u = 0 Newton fails on the P1-gradient
            scenes, and from the previous step's u it needs 10 iterations instead of 3.
    """

    def __init__(
        self,
        residual: ufl.Form,
        u: fem.Function,
        Fg: fem.Function,
        bcs: list,
        make_ksp: Callable[[PETSc.Mat], PETSc.KSP],
        predictor: Callable[[], object] | None = None,
        fallback: Callable[[PETSc.Mat], PETSc.KSP] | None = None,
    ) -> None:
        self.u, self.bcs, self.predictor, self.fallback = u, bcs, predictor, fallback
        self.offset = fem.Function(u.function_space, name="u_offset")  # u_finite - u_linear
        self.comm = u.function_space.mesh.comm
        self.F = fem.form(residual)
        self.J = fem.form(jacobian(residual, u))
        self.A = fem.petsc.create_matrix(self.J)
        self.b = fem.petsc.create_vector(self.F)
        self.du = self.A.createVecRight()
        self.ksp = make_ksp(self.A)
        msh, degree = u.function_space.mesh, det_degree(u)
        self._det = MeshSamples(ufl.det(deformation_gradient(u)), msh, degree)
        self._stretch = MeshSamples(smallest_elastic_stretch(u, Fg), msh, degree)
        V = u.function_space
        n_nodes = V.dofmap.index_map.size_local
        self._node_points = V.tabulate_dof_coordinates()[:n_nodes, :2]

    @property
    def guess_functions(self) -> list[fem.Function]:
        """What the next initial guess is made of (u and the offset): a resume state."""
        return [self.u, self.offset]

    def residual_norm(self) -> float:
        """Assemble ``R(u)`` into ``self.b`` (zero on Dirichlet dofs) and return ``|R(u)|``."""
        with self.b.localForm() as local:
            local.set(0.0)
        fem.petsc.assemble_vector(self.b, self.F)
        self.b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem.petsc.set_bc(self.b, self.bcs, self.u.vector, -1.0)
        return self.b.norm()

    def load_norm(self) -> float:
        """``|R(0)|``, the norm of the step's loads (u is restored afterwards)."""
        saved = self.u.x.array.copy()
        self.u.x.array[:] = 0.0
        value = self.residual_norm()
        self.u.x.array[:] = saved
        return value

    def min_det(self) -> tuple[float, np.ndarray]:
        """Smallest ``det F`` over all cells (at the nodes of :mod:`plantgrowth.base.mesh_samples`)
        and where it is."""
        return self._minimum(self._det)

    def min_stretch(self) -> tuple[float, np.ndarray]:
        """Smallest principal elastic stretch over all cells (the same points) and where."""
        return self._minimum(self._stretch)

    def _minimum(self, samples: MeshSamples) -> tuple[float, np.ndarray]:
        return _global_extreme(samples.values(), samples.points, self.comm, np.argmin)

    def _rank(self, r: float) -> tuple:
        """Order of initial guesses: not inverted, then admissible (stretch >= STRETCH_FLOOR),
        then (inadmissible) the larger stretch, then the smaller residual norm r."""
        if not (np.isfinite(r) and self.min_det()[0] > 0.0):
            return (False,)
        stretch = self.min_stretch()[0]
        admissible = stretch >= STRETCH_FLOOR
        return (True, admissible, 0.0 if admissible else stretch, -r)

    def _check_admissible(self) -> None:
        stretch, where = self.min_stretch()
        if stretch < STRETCH_FLOOR:
            raise RunError(
                f"Newton converged to a collapsed state: smallest elastic principal stretch "
                f"{stretch:.3g} < 1/sqrt(3) at x = ({where[0]:.4g}, {where[1]:.4g}), where the "
                "St Venant-Kirchhoff law softens (Fe = 0 is a stress-free solution); likely "
                "cause: growth or loads compress the tissue beyond the small-strain model"
            )

    def solve(self) -> NewtonReport:
        """Newton iterations from the initial guess; raises RunError (collectively) on failure."""
        du = self.du
        scale = max(self.load_norm(), NEWTON_FLOOR)
        r, linear_u = self._predict(self.residual_norm(), scale)
        history, reason, worst_linear, stalled = [r], 1, 0.0, False
        for k in range(NEWTON_MAX_IT + 1):
            if r <= NEWTON_RTOL * scale or stalled:
                self._check_admissible()
                if linear_u is not None:
                    self.offset.x.array[:] = self.u.x.array - linear_u
                return NewtonReport(reason, r / scale, k, tuple(history), worst_linear)
            if k == NEWTON_MAX_IT or not np.isfinite(r):
                break
            self.A.zeroEntries()
            fem.petsc.assemble_matrix(self.A, self.J, bcs=self.bcs)
            self.A.assemble()
            reason, linear, problems = self._solve_linear(du)
            diagnostics.stop_if(problems, self.comm)
            worst_linear = max(worst_linear, linear)
            r, stalled = self._line_search(r, scale, k)
            history.append(r)
        raise RunError(
            f"Newton did not converge: relative residual {r / scale:.3g} after {k} iterations "
            f"(tolerance {NEWTON_RTOL:g}), largest at x = {self._largest_residual_place()}; "
            "likely cause: loads or growth contrast too strong for the elastic tissue"
        )

    def _solve_linear(self, du: PETSc.Vec) -> tuple[int, float, list[str]]:
        """``J du = R``: PETSc's reason, the true relative residual and what went wrong. A
        failed Krylov solve is repeated with ``fallback``, which solves from then on."""
        while True:
            self.ksp.solve(self.b, du)
            reason = self.ksp.getConvergedReason()
            linear = relative_residual(self.A, du, self.b)
            krylov = self.ksp.getType() != "preonly"
            iterations = self.ksp.getIterationNumber() if krylov else 0
            problems = diagnostics.solve_problems(reason, linear, iterations, self.ksp.getType())
            if not problems or self.fallback is None:  # reason, residual: the same on all ranks
                return reason, linear, problems
            log.warning(
                "warning: Newton: %s + GAMG stopped (PETSc reason %d, relative residual %.3g "
                "after %d iterations): the Jacobian is indefinite or far from symmetric here; "
                "LU solves it from now on", self.ksp.getType().upper(), reason, linear, iterations,
            )  # fmt: skip
            self.ksp.destroy()
            self.ksp, self.fallback = self.fallback(self.A), None

    def _predict(self, r: float, scale: float) -> tuple[float, np.ndarray | None]:
        """The initial guess (see the class doc) unless u already solves the problem: the
        residual norm there and the linear solution (None: no prediction)."""
        if self.predictor is None or r <= NEWTON_RTOL * scale:
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

    def _line_search(self, r: float, scale: float, k: int) -> tuple[float, bool]:
        """``u <- u - alpha du`` for the first alpha = 2^-j that leaves no element inverted, keeps
        the smallest elastic stretch above ``min(STRETCH_FLOOR, its value at u)`` (never deeper
        into the collapsed branch) and passes a decrease test; returns the new residual norm
        (``self.b`` holds the residual) and whether the iteration stalled at round-off level
        (relative residual below the time loop's bound, diagnostics.RESIDUAL_BOUND, with no
        decrease left: converged).

        Decrease: the residual norm's (Armijo, ``|R_trial| <= (1 - ARMIJO alpha) |R|``), or,
        when that fails, Deuflhard's natural monotonicity ``|J^{-1} R_trial| <= (1 - alpha / 4)
        |du|`` (one more solve with the current Jacobian). The second, affine-invariant test
        accepts the full steps of thin walls that bend and rotate, where the residual norm
        first grows a hundredfold before Newton converges quadratically (micro model)."""
        start = self.u.vector.copy()
        natural = self.du.duplicate()
        du_norm = self.du.norm()
        alpha, det_min, where = 1.0, 1.0, None
        stretch_floor = min(STRETCH_FLOOR, self.min_stretch()[0])
        for _ in range(LINE_SEARCH_HALVINGS + 1):
            self.u.vector.waxpy(-alpha, self.du, start)
            self.u.x.scatter_forward()
            det_min, where = self.min_det()
            stretch, stretch_where = self.min_stretch() if det_min > 0.0 else (0.0, where)
            admissible = det_min > 0.0 and stretch >= stretch_floor
            trial = self.residual_norm() if admissible else np.inf
            accepted = stalled = False
            if np.isfinite(trial):
                accepted = trial <= (1.0 - ARMIJO * alpha) * r
                stalled = not accepted and trial <= diagnostics.RESIDUAL_BOUND * scale
                if not (accepted or stalled):
                    self.ksp.solve(self.b, natural)
                    accepted = natural.norm() <= (1.0 - 0.25 * alpha) * du_norm
                    self.residual_norm()  # b again holds the residual
            if accepted or stalled:
                start.destroy()
                natural.destroy()
                return trial, stalled
            alpha *= 0.5
        self.u.vector.array[:] = start.array
        self.u.x.scatter_forward()
        start.destroy()
        natural.destroy()
        self.residual_norm()
        if det_min <= 0.0:
            raise RunError(
                f"Newton iteration {k + 1}: inverted element (det F = {det_min:.3g} <= 0) at x = "
                f"({where[0]:.4g}, {where[1]:.4g}) even after {LINE_SEARCH_HALVINGS} step "
                "halvings; likely cause: loads or growth contrast too strong for the tissue"
            )
        if stretch < stretch_floor:
            raise RunError(
                f"Newton iteration {k + 1}: every step compresses the tissue towards collapse "
                f"(elastic stretch {stretch:.7g} < {stretch_floor:.7g}) at x = "
                f"({stretch_where[0]:.4g}, {stretch_where[1]:.4g}) even after "
                f"{LINE_SEARCH_HALVINGS} step halvings; likely cause: growth or loads compress "
                "the tissue beyond the small-strain model"
            )
        raise RunError(
            f"Newton did not converge: the line search found no decrease of the relative "
            f"residual {r / scale:.3g} at iteration {k + 1}, largest at x = "
            f"{self._largest_residual_place()}; likely cause: loads or growth contrast too strong "
            "for the elastic tissue"
        )

    def _largest_residual_place(self) -> str:
        """Where ``|R|`` is largest (a node, over all ranks), as "(x1, x2)"; b holds R."""
        bs = self.u.function_space.dofmap.index_map_bs
        local = np.abs(self.b.array).reshape(-1, bs).max(axis=1)
        x = _global_extreme(local, self._node_points, self.comm, np.argmax)[1]
        return f"({x[0]:.4g}, {x[1]:.4g})"


def _global_extreme(
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
