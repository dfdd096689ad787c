"""Angle nodes the director's interpolant needs (issue 33, item 2): trigonometric (period 180
degrees, today's) against piecewise-linear (before issue 33), at E_f / E = 5.

The reference cell (l1 = l2 = 1, theta = 30, w = 0.05, nu = 0.3, resolution 2) is solved
exactly at 768 director angles 0.234375 degrees apart (the nodes of every node count 12 2^L,
L <= 6) and at 200 random test angles, at Fg = I and at a 10% stretch. For each count N the
largest relative error over the test angles (per packed quantity, the largest: the surrogate's
measure) of both interpolants through the same N equispaced nodes; the node count each needs
for the tolerance is the smallest N whose error is within it. Writes
``benchmarks/results/angle_nodes.json`` with the machine.

    python scripts/benchmarks/bench_angle_nodes.py [--tolerance 1e-3]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from plantgrowth.base.machine import machine_description
from plantgrowth.unitcell import director_lattice
from plantgrowth.unitcell.homogenization import Homogenizer
from plantgrowth.unitcell.surrogate import stretch

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/angle_nodes.json"
GEOMETRY = (1.0, 1.0, 30.0, 0.05)
NU, STIFFNESS, RESOLUTION = 0.3, 5.0, 2
GRID = 768  # angles 180 / 768 apart: every node of 12 2^L for L <= 6
COUNTS = [12 * 2**level for level in range(7)]
STRETCHES = {"Fg = I": (0.0, 0.0), "s = (0.1, 0.05)": (0.1, 0.05)}


def linear(values: np.ndarray, b: np.ndarray, count: int) -> np.ndarray:
    """Piecewise-linear periodic interpolant through ``count`` of the grid's values at b."""
    nodes = values[:: GRID // count]
    x = b / (180.0 / count)
    k = np.floor(x).astype(int)
    t = (x - k)[:, None]
    return (1 - t) * nodes[k % count] + t * nodes[(k + 1) % count]


def trigonometric(values: np.ndarray, b: np.ndarray, count: int) -> np.ndarray:
    """Trigonometric interpolant (director_lattice) through ``count`` of the grid's values."""
    return director_lattice.trigonometric_weights(b, count) @ values[:: GRID // count]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tolerance", type=float, default=1e-3)
    args = parser.parse_args(argv)
    start = time.perf_counter()
    homogenizer = Homogenizer(RESOLUTION, 1e-6, True, True, MPI.COMM_SELF, cell_tolerance=1.0)
    difference = homogenizer.surrogate.relative_difference
    grid = np.arange(GRID) * 180.0 / GRID
    tests = np.random.default_rng(0).uniform(0.0, 180.0, 200)
    result: dict = {
        "cell": dict(zip(("l1", "l2", "theta", "w"), GEOMETRY, strict=True)), "nu": NU,
        "fibre_stiffness": STIFFNESS, "resolution": RESOLUTION, "tolerance": args.tolerance,
        "counts": COUNTS, "stretches": {},
    }  # fmt: skip
    for name, s in STRETCHES.items():
        U = stretch(s)

        def solve(angle: float, U: np.ndarray = U) -> np.ndarray:
            return homogenizer._solve_exact(GEOMETRY, NU, U, (STIFFNESS, float(angle)))

        values = np.array([solve(a) for a in grid])
        exact = np.array([solve(a) for a in tests])
        errors = {
            method: [float(difference(f(values, tests, n), exact).max()) for n in COUNTS]
            for method, f in (("linear", linear), ("trigonometric", trigonometric))
        }
        needed = {
            method: next((n for n, e in zip(COUNTS, errs, strict=True) if e <= args.tolerance),
                         None)
            for method, errs in errors.items()
        }  # fmt: skip
        result["stretches"][name] = {"s": s, "largest_error": errors, "nodes_needed": needed}
        print(name, json.dumps(needed), flush=True)
    result["machine"] = machine_description()
    result["script_seconds"] = time.perf_counter() - start
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
