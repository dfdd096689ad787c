"""Homogenized moduli of a fibre-reinforced regular hexagon (docs/fibres.md).

(i) The unit-cell table: E1, E2, nu12, G12, K11, K22 (and E1112, E2212) of the regular
hexagon (l1 = l2 = 1, theta = 30 deg, w = 0.05, E = 1, nu = 0.3, Fg = I) against
E_f/E in {0, 1, 5, 20} and the director angle a in {0, 30, 90} degrees, on the split mesh at
the default resolution; the paper's cell (unsplit mesh, isotropic walls) alongside.
(ii) Convergence with the resolution (P2 elements across a wall, 1..4) of the fibred cell
E_f/E = 5, a = 90. (iii) Cost: solver set-up and one solve, fibred against isotropic (median of
five solves).

    python scripts/studies/fibre_cell_table.py [--out benchmarks/results/fibre_cell.json]
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from plantgrowth.base.machine import write_study_json
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.unitcell.solver import DEFAULT_RESOLUTION, CellSolver

KEYS = ("E1", "E2", "nu12", "G12", "K11", "K22", "E1112", "E2212")
HEADER = {
    "description": "Fibre-reinforced regular hexagon: moduli vs E_f/E and director angle; "
    "convergence with resolution at E_f/E = 5, a = 90; cost",
    "cell": {"l1": 1.0, "l2": 1.0, "theta_deg": 30.0, "w": 0.05, "E": 1.0, "nu": 0.3},
    "resolution": DEFAULT_RESOLUTION,
}


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--stiffness", type=float, nargs="+", default=[0.0, 1.0, 5.0, 20.0])
    parser.add_argument("--angles", type=float, nargs="+", default=[0.0, 30.0, 90.0])
    parser.add_argument("--resolutions", type=int, nargs="+", default=[1, 2, 3, 4])
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/fibre_cell.json"))
    return parser.parse_args(argv)


def moduli(solver: CellSolver, stiffness: float = 0.0, angle: float = 0.0) -> dict:
    """The KEYS of one solve at Fg = I, E = 1, nu = 0.3."""
    summary = solver.solve(np.eye(2), 1.0, 0.3, True, True, stiffness, angle).summary()
    return {key: summary[key] for key in KEYS} | {"ndofs": summary["ndofs"]}


def median_solve_seconds(solver: CellSolver, stiffness: float, repeats: int = 5) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        solver.solve(np.eye(2), 1.0, 0.3, True, True, stiffness, 90.0)
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    logging.getLogger().setLevel(logging.WARNING)  # quiet the JIT's compiler log
    start = time.perf_counter()
    cell = HoneycombCell()
    comm = MPI.COMM_SELF

    t0 = time.perf_counter()
    plain = CellSolver(cell, DEFAULT_RESOLUTION, comm)
    t1 = time.perf_counter()
    fibred = CellSolver(cell, DEFAULT_RESOLUTION, comm, fibres=True)
    t2 = time.perf_counter()
    table = [
        {"fibre_stiffness": s, "fibre_angle": a, **moduli(fibred, s, a)}
        for s in args.stiffness
        for a in args.angles
    ]
    cost = {
        "setup_seconds": {"isotropic": t1 - t0, "fibred": t2 - t1},
        "solve_seconds_median_of_5": {
            "isotropic": median_solve_seconds(plain, 0.0),
            "fibred": median_solve_seconds(fibred, 5.0),
        },
    }
    convergence = []
    for resolution in args.resolutions:
        solver = CellSolver(cell, resolution, comm, fibres=True)
        convergence.append({"resolution": resolution, **moduli(solver, 5.0, 90.0)})
        print(f"resolution {resolution}: {convergence[-1]}", flush=True)

    cells = {"paper_cell": moduli(plain), "table": table, "convergence": convergence}
    write_study_json(args.out, {**HEADER, **cells, "cost": cost}, start)
    return 0


if __name__ == "__main__":
    sys.exit(main())
