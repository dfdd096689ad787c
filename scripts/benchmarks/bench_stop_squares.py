"""Per-step cost of the surrogate's answers (issue 33): the stop squares' one lookup against the
walk down every level, on a lattice refined by a smooth analytic map (no cell solve).

The map is tests/test_surrogate_continuity.py's (five smooth quantities of U); the lattice is
refined to ``--tolerance`` by ``--cells`` queries uniform in |s_i| <= ``--spread`` (the
gradient scene at ``balanced``: 4,140 cells, walks of about 6 levels). Then, alternated
``--repeats`` times, one pass of :meth:`LatticeSurrogate._walk` (the stop squares, all known:
a step without refinement) and one of :func:`plantgrowth.unitcell.lattice.walk` at the same
queries (what every step paid before); medians of the seconds, their ratio, the largest
relative difference of the answers. Writes ``benchmarks/results/stop_squares.json`` with the
machine and the load.

    python scripts/benchmarks/bench_stop_squares.py [--cells 4140] [--repeats 21]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from plantgrowth.base.machine import machine_description
from plantgrowth.unitcell.lattice import place, walk
from plantgrowth.unitcell.surrogate import LatticeSurrogate

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/stop_squares.json"


def smooth(table: tuple, U: np.ndarray) -> np.ndarray:
    """Five smooth positive quantities of the stretch U (a cell solve's role)."""
    a, b, c = U[0, 0], U[0, 1], U[1, 1]
    return np.array([2 * np.exp(a) + b, np.sin(3 * b) + 1.5, c**3, 1 + a * b, 2 + np.cos(4 * a)])


def lattice_arguments(description: str) -> argparse.ArgumentParser:
    """The options of the analytic lattice benchmarks: queries, their spread, the tolerance
    and the timing repeats."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--cells", type=int, default=4140)
    parser.add_argument("--spread", type=float, default=0.15)
    parser.add_argument("--tolerance", type=float, default=1e-3)
    parser.add_argument("--repeats", type=int, default=21)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = lattice_arguments(__doc__.split("\n\n")[0]).parse_args(argv)
    lat = LatticeSurrogate(smooth, args.tolerance, [slice(0, 5)], MPI.COMM_SELF)
    s = np.random.default_rng(0).uniform(-args.spread, args.spread, (args.cells, 2))
    ids = np.zeros(len(s), dtype=np.int64)
    lat.evaluate([(1,)], ids, s)
    keys, surplus = lat._points_table()
    squares = np.array(sorted(lat._built), dtype=np.int64)
    times: dict[str, list[float]] = {"stop_squares": [], "walk": []}
    load_before = os.getloadavg()
    for _ in range(args.repeats):
        start = time.perf_counter()
        cached = lat._walk(ids, s)[0]
        times["stop_squares"].append(time.perf_counter() - start)
        start = time.perf_counter()
        walked = walk(squares, keys, surplus, ids, s, place(s)[:, None, :])["values"][:, 0]
        times["walk"].append(time.perf_counter() - start)
    difference = np.abs(cached - walked).max(axis=1) / np.abs(walked).max(axis=1)
    ratios = [a / b for a, b in zip(times["stop_squares"], times["walk"], strict=True)]
    result = {
        "machine": machine_description(), "load_before": load_before,
        "load_after": os.getloadavg(), "cells": args.cells, "spread": args.spread,
        "tolerance": args.tolerance, "repeats": args.repeats, "points": len(keys),
        "squares": len(squares), "deepest_level": int(lat._deepest(ids, s)[0].max()),
        "seconds": times, "median_seconds": {k: statistics.median(v) for k, v in times.items()},
        "ratio_median": statistics.median(ratios), "largest_relative_difference": difference.max(),
    }  # fmt: skip
    print(json.dumps({k: result[k] for k in ("median_seconds", "ratio_median",
                                             "largest_relative_difference")}))  # fmt: skip
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
