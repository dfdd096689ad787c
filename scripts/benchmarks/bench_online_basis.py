"""Could a reduced basis built during the run, with no offline phase, stand in for the fibred
cell solves of the stress-feedback scene? (issue 33; a study, not in the code)

Question: the feedback scene (``bench_feedback_cost.feedback_text``, ``balanced``) solves 590
fibred cell problems (584 lattice points, 6 exact self-checks). Replayed in the run's order,
each point is first answered on the span of the solutions kept so far (the Galerkin
projection of ``bench_reduced_basis``), and kept as answered when the relative residual of
the full system, ``max_k |f_k - A V y_k| / |f_k|`` over the four right-hand sides, is at
most ``tau``; otherwise it is solved in full and its four solutions join the basis
(orthonormalized). How many full solves does each ``tau`` leave, how far are the accepted
answers from the full solves (the surrogate's relative error per packed segment), does the
residual predict that error, and what does an accepted answer cost?

Method: the run's fibred solve points (the stretch U and the director angle, E = 1) are
recorded from ``CellSolver.solve`` during one run of the scene in this process (cell cache
off). Each point is also solved in full for the comparison (not counted). The costs are timed
apart at the final basis size of the replay at ``--cost-tau``: the reduced solve (the r x r
system of ``bench_reduced_basis``'s math), the residual check (the cell matrix's affine sum,
``GradientBasis.matrix``, and four products with ``V y``), a full solve, and a basis growth by
four columns (``V^T [B_1 v, ..., B_30 v]``, the 30 reduced products' new rows, as one product;
this study rebuilds its reduced products instead, which a run would not).

    PYTHONPATH=. nice -n 19 .venv/bin/python scripts/benchmarks/bench_online_basis.py \
        [--taus 3e-1 1e-1 3e-2 1e-2 1e-3] [--cost-tau 1e-2]

Writes ``benchmarks/results/online_basis.json`` with the machine and the load.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_feedback_cost import feedback_text
from bench_reduced_basis import (
    SEGMENTS,
    ReducedSolution,
    SnapshotSolver,
    full_solve,
    project,
    rb_result,
    reduced_solution,
    scipy_matrix,
    segment_errors,
)
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.base.machine import machine_description
from plantgrowth.cli import main as plantgrowth_main
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.unitcell.homogenization import _pack
from plantgrowth.unitcell.solver import CellSolver, tensor_weights
from plantgrowth.unitcell.surrogate import split_growth

REPO = Path(__file__).resolve().parents[2]
OUTPUT = REPO / "benchmarks" / "results" / "online_basis.json"
RESOLUTION = 2  # the balanced preset's cell_resolution


def record_points() -> np.ndarray:
    """The feedback run's fibred solve points in order, as (s1, s2, b): U = stretch(s)."""
    points = []
    solve = CellSolver.solve

    def recording(self: CellSolver, Fg: np.ndarray, *args: object, **kwargs: float) -> object:
        if kwargs.get("fibre_stiffness", 0.0) > 0.0:
            points.append((np.array(Fg, dtype=float), kwargs["fibre_angle"]))
        return solve(self, Fg, *args, **kwargs)

    CellSolver.solve = recording
    try:
        with tempfile.TemporaryDirectory() as tmp:
            (Path(tmp) / "scene.toml").write_text(feedback_text())
            os.environ["PLANTGROWTH_CACHE_DIR"] = "off"
            plantgrowth_main(["run", f"{tmp}/scene.toml", "-o", f"{tmp}/o", "-q"])
    finally:
        CellSolver.solve = solve
    s = split_growth(np.array([U for U, _ in points]))[1]  # U is a lattice stretch: R = I
    return np.column_stack([s, [b for _, b in points]])


class Residual:
    """``max_k |f_k - A(mu) V y_k| / |f_k|`` of a reduced solution, with the cell solver's own
    affine sum for A(mu) (what an online check would assemble)."""

    def __init__(self, solver: CellSolver) -> None:
        self.solver = solver
        self.A = solver.basis.diagonal.duplicate(copy=True)

    def __call__(self, V: np.ndarray, solution: ReducedSolution) -> float:
        Fg = solution.Fg
        self.solver.basis.matrix([tensor_weights(Fg, C) for C in solution.walls], self.A)
        f = sum(
            reduced @ w
            for reduced, w in zip(self.solver.basis.reduced, solution.loads, strict=True)
        )
        x = V @ solution.y
        worst = 0.0
        for k in range(f.shape[1]):
            vec = PETSc.Vec().createWithArray(np.ascontiguousarray(x[:, k]))
            out = vec.duplicate()
            self.A.mult(vec, out)
            worst = max(worst, np.linalg.norm(f[:, k] - out.array_r) / np.linalg.norm(f[:, k]))
        return worst


def replay(solver: SnapshotSolver, points: np.ndarray, full: np.ndarray, snaps: list,
           tau: float) -> dict:  # fmt: skip
    """The greedy online basis for one tau (module docstring)."""
    residual = Residual(solver)
    basis, model, V = [], None, None
    accepted_errors, predicted, kept = [], [], 0
    for i, (s1, s2, b) in enumerate(points):
        if model is not None:
            solution = reduced_solution(solver, model, np.array([s1, s2]), b)
            r = residual(V, solution)
            if r <= tau:
                answer = _pack(rb_result(solver, model, solution, time.perf_counter()))
                error = segment_errors(answer[None], full[i][None]).max()
                accepted_errors.append(float(error))
                predicted.append(float(r))
                continue
        kept += 1
        basis.extend(snaps[i])
        V = np.linalg.qr(np.array(basis).T)[0]
        model = project(solver, V)
    errors = np.array(accepted_errors)
    return {"tau": tau, "full_solves": kept, "accepted": len(errors), "basis_size": V.shape[1],
            "accepted_max_error": float(errors.max()) if len(errors) else None,
            "accepted_median_error": float(np.median(errors)) if len(errors) else None,
            "largest_error_over_residual": float((errors / np.array(predicted)).max())
            if len(errors) else None}  # fmt: skip


def costs(solver: SnapshotSolver, points: np.ndarray, snaps: list, r: int) -> dict:
    """Median seconds, at basis size r, of the parts of an accepted answer (the reduced solve,
    the residual check) and of a full solve, and of a basis growth by four columns: its 30
    products' new rows and columns, ``V^T [B_1 v, ..., B_30 v]`` as one product."""
    V = np.linalg.qr(np.array([v for group in snaps[: r // 4] for v in group]).T)[0]
    model = project(solver, V)
    residual = Residual(solver)
    reduced, check, full, grow = [], [], [], []
    products = [scipy_matrix(B) for part in solver.basis.products for B in part]
    for s1, s2, b in points[:60]:
        start = time.perf_counter()
        solution = reduced_solution(solver, model, np.array([s1, s2]), b)
        reduced.append(time.perf_counter() - start)
        start = time.perf_counter()
        residual(V, solution)
        check.append(time.perf_counter() - start)
        start = time.perf_counter()
        full_solve(solver, np.array([s1, s2]), b)
        full.append(time.perf_counter() - start)
    new = np.ascontiguousarray(V[:, -4:])
    for _ in range(10):
        start = time.perf_counter()
        V.T @ np.hstack([B @ new for B in products])
        grow.append(time.perf_counter() - start)
    return {"r": V.shape[1], "reduced_solve_seconds": statistics.median(reduced),
            "residual_check_seconds": statistics.median(check),
            "full_solve_seconds": statistics.median(full),
            "enrich_seconds": statistics.median(grow)}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--taus", type=float, nargs="+", default=[3e-1, 1e-1, 3e-2, 1e-2, 1e-3])
    parser.add_argument(
        "--cost-tau",
        type=float,
        default=1e-2,
        help="the replay whose final basis size the costs are timed at",
    )
    parser.add_argument("--output", type=Path, default=OUTPUT)
    args = parser.parse_args(argv)
    load_before = os.getloadavg()
    points = record_points()
    print(f"{len(points)} fibred solves recorded", flush=True)
    solver = SnapshotSolver(HoneycombCell(), RESOLUTION, MPI.COMM_SELF, fibres=True)
    full, snaps = [], []
    for s1, s2, b in points:
        full.append(_pack(full_solve(solver, np.array([s1, s2]), b)))
        snaps.append(list(solver.snapshots))
    full = np.array(full)
    rows = []
    for tau in args.taus:
        rows.append(replay(solver, points, full, snaps, tau))
        print(json.dumps(rows[-1]), flush=True)
    at = min(rows, key=lambda row: abs(np.log(row["tau"] / args.cost_tau)))
    cost = costs(solver, points, snaps, at["basis_size"])
    print(json.dumps(cost), flush=True)
    result = {
        "machine": machine_description(), "load_before": load_before,
        "load_after": os.getloadavg(), "command": " ".join(["python", *sys.argv]),
        "points": len(points), "resolution": RESOLUTION, "segments": list(SEGMENTS),
        "replays": rows, "costs": cost,
    }  # fmt: skip
    args.output.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
