"""Checks that stop a run with a message naming the place and the likely cause.

Each ``*_problems`` function returns a list of messages for this rank's data; :func:`stop_if`
gathers them on all ranks (a collective call) and raises one :class:`RunError`. The time loop
prefixes the step and time.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from plantgrowth.base.errors import RunError
from plantgrowth.base.tensors import det2, smallest_eigenvalue_sym3

RESIDUAL_BOUND = 1e-8
"""Largest accepted relative residual of a direct solve and of Newton's linear solves; LU's
round-off is ~1e-14, GMRES stops at 1e-10 (problem.NEWTON_KRYLOV_RTOL). The macro CG solve has its
own bound, TRUE_RESIDUAL_FACTOR times ``solver.macro_rtol`` (SolveReport.bound)."""
TRUE_RESIDUAL_FACTOR = 10.0
"""How far CG's true relative residual may exceed the tolerance it stopped at (its recursive
residual drifts from the true one by round-off: measured equal to 2 digits at 1e-10 to 1e-7)."""

EULER_HINT = "likely cause: a time step too large for explicit Euler (use integrator = 'exp')"
RATE_HINT = (
    "or, where growth rates differ strongly across the tissue (a contrast in eta, tau or E), a "
    'time step too long for them: try a smaller time.dt or time.integrator = "adaptive"'
)
"""Named with every failure that strong growth contrast causes (issue 21, item 8: a 100x eta
contrast inverts elements from step 3 at dt = 1 with the exp integrator)."""
ON_THIS_RANK = " on this rank"
"""Where a count is local; :func:`stop_if` names the rank under MPI and drops it in serial."""


def _where(mask: np.ndarray, points: np.ndarray, what: str) -> str:
    first = np.flatnonzero(mask)[0]
    x = points[first]
    return f"{what} at x = ({x[0]:.4g}, {x[1]:.4g}) ({int(mask.sum())} place(s){ON_THIS_RANK})"


def nonfinite_problems(name: str, values: np.ndarray, points: np.ndarray, cause: str) -> list[str]:
    """NaN or Inf in per-place values (n, ...)."""
    bad = ~np.all(np.isfinite(values.reshape(len(values), -1)), axis=1)
    return [f"{_where(bad, points, f'{name} is NaN or Inf')}; {cause}"] if bad.any() else []


def growth_problems(Fg: np.ndarray, points: np.ndarray, G: np.ndarray | None = None) -> list[str]:
    """Fg (and G) finite and ``det Fg > 0`` in every growth unit."""
    problems = [] if G is None else nonfinite_problems("G", G, points, EULER_HINT)
    problems += nonfinite_problems("Fg", Fg, points, EULER_HINT)
    if problems:
        return problems
    det = det2(Fg)
    bad = det <= 0.0
    if bad.any():
        problems.append(
            f"{_where(bad, points, f'det Fg = {det[bad].min():.3g} <= 0 (inverted growth)')}; "
            + EULER_HINT
        )
    return problems


def inversion_problems(deformation_det: np.ndarray, points: np.ndarray) -> list[str]:
    """Elements inverted in the grown configuration: ``det(I + grad u) <= 0``."""
    bad = deformation_det <= 0.0
    if not bad.any():
        return []
    return [
        f"{_where(bad, points, 'element inverted in the grown configuration')}; likely cause: "
        "displacements too large for the linearised elastic model (pressure, loads or growth "
        f"contrast too strong), {RATE_HINT}"
    ]


def stiffness_problems(C: np.ndarray, nodes: np.ndarray) -> list[str]:
    """E_hom (Voigt matrices C, (n, 3, 3)) symmetric positive definite at every coarse node:
    symmetric to 1e-8 of its largest entry, and its symmetric part's leading minors positive
    (Sylvester's criterion; the smallest eigenvalue is computed for the message only)."""
    if not np.all(np.isfinite(C)):
        bad = ~np.all(np.isfinite(C.reshape(len(C), -1)), axis=1)
        return [f"{_where(bad, nodes, 'E_hom is NaN or Inf at a coarse node')}"]
    pairs = ((0, 1), (0, 2), (1, 2))
    asym = np.max([np.abs(C[:, i, j] - C[:, j, i]) for i, j in pairs], axis=0)
    a, d, f = C[:, 0, 0], C[:, 1, 1], C[:, 2, 2]
    b, c, e = (0.5 * (C[:, i, j] + C[:, j, i]) for i, j in pairs)
    det = a * (d * f - e * e) - b * (b * f - e * c) + c * (b * e - d * c)
    bad = ~((a > 0) & (a * d - b * b > 0) & (det > 0))
    # the largest entry is at least the largest diagonal one: only those asymmetric against
    # that need the whole matrix's
    suspect = np.flatnonzero(asym > 1e-8 * np.maximum(np.maximum(np.abs(a), np.abs(d)), np.abs(f)))
    bad[suspect] |= asym[suspect] > 1e-8 * np.abs(C[suspect]).max(axis=(1, 2))
    if not bad.any():
        return []
    smallest = smallest_eigenvalue_sym3(0.5 * (C[bad] + np.swapaxes(C[bad], 1, 2)))
    what = f"E_hom not symmetric positive definite (smallest eigenvalue {smallest.min():.3g})"
    return [
        f"{_where(bad, nodes, what)}; likely cause: a degenerate unit cell there (wall "
        "thickness, angle or growth tensor)"
    ]


def solve_problems(
    reason: int, residual: float, iterations: int = 0, method: str = "cg",
    bound: float = RESIDUAL_BOUND,
) -> list[str]:  # fmt: skip
    """A linear solve that failed or is inaccurate: true relative residual above ``bound``
    (``iterations`` > 0: a Krylov solve, PETSc's KSP type ``method``)."""
    if reason > 0 and residual <= bound:
        return []
    krylov = (
        f" after {iterations} {method.upper()} iterations; the direct solver (solver.macro = "
        f"'direct') is robust to what slows {method.upper()} down: thin walls, stiffness "
        "contrast, nu close to 0.5"
        if iterations > 0
        else ""
    )
    return [
        f"linear solve failed (PETSc reason {reason}, relative residual {residual:.3g} > "
        f"{bound:g}){krylov}; likely cause: a singular or ill-conditioned system "
        "(extreme stiffness contrast, nu close to 0.5 or a degenerate mesh)"
    ]


def _on_ranks(ranks: list[int], size: int) -> str:
    """Which ranks found a problem: nothing in serial, or when all did (replicated data)."""
    if size == 1 or len(ranks) == size:
        return ""
    return f" on rank{'s' if len(ranks) > 1 else ''} {', '.join(map(str, ranks))}"


def stop_if(problems: list[str], comm: MPI.Comm) -> None:
    """Collective: raise one RunError if any rank found a problem."""
    ranks: dict[str, list[int]] = {}
    for rank, part in enumerate(comm.allgather(problems)):
        for problem in part:
            ranks.setdefault(problem, []).append(rank)
    everything = sorted(p.replace(ON_THIS_RANK, _on_ranks(r, comm.size)) for p, r in ranks.items())
    if everything:
        raise RunError("; ".join(everything))


def check_solution(report, u, comm: MPI.Comm) -> None:
    """Collective: the solve converged to the residual bound and the 2D vector field u is
    finite (``report`` is a :class:`plantgrowth.models.linear.SolveReport`)."""
    points = u.function_space.tabulate_dof_coordinates()[:, :2]
    values = u.x.array.reshape(-1, 2)
    stop_if(
        solve_problems(report.reason, report.residual, report.iterations, bound=report.bound)
        + nonfinite_problems("u", values, points, "the solve broke down"),
        comm,
    )
