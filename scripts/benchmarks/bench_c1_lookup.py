"""Cost and accuracy of the C1 interpolant of the surrogate's lattice points against the stop
squares' bilinear answer (issue 33 prototype, docs/surrogate_c1.md), with no cell solve.

The lattice is bench_stop_squares.py's: its smooth analytic map of U refined to ``--tolerance``
by ``--cells`` queries uniform in |s_i| <= ``--spread``. Then, alternated ``--repeats`` times,
one pass of :meth:`LatticeSurrogate._walk` (the stop squares, all known: a step without
refinement) and one of :meth:`SmoothLattice.evaluate` at the same queries (built once per
refinement: its build time is reported apart). Medians of the seconds and their ratio; the
largest relative error of each against the exact map at ``--check`` fresh queries; the largest
relative difference at the built points. Writes ``benchmarks/results/c1_lookup.json`` with the
machine and the load.

    python scripts/benchmarks/bench_c1_lookup.py [--cells 4140] [--repeats 21]
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
from bench_stop_squares import smooth
from mpi4py import MPI

from plantgrowth.base.machine import machine_description
from plantgrowth.unitcell.lattice import H0, LOW, OFFSET, STEP
from plantgrowth.unitcell.smooth_lattice import SmoothLattice
from plantgrowth.unitcell.surrogate import LatticeSurrogate, stretch

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/c1_lookup.json"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cells", type=int, default=4140)
    parser.add_argument("--spread", type=float, default=0.15)
    parser.add_argument("--tolerance", type=float, default=1e-3)
    parser.add_argument("--repeats", type=int, default=21)
    parser.add_argument("--check", type=int, default=20000)
    args = parser.parse_args(argv)
    lat = LatticeSurrogate(smooth, args.tolerance, [slice(0, 5)], MPI.COMM_SELF)
    rng = np.random.default_rng(0)
    s = rng.uniform(-args.spread, args.spread, (args.cells, 2))
    ids = np.zeros(len(s), dtype=np.int64)
    lat.evaluate([(1,)], ids, s)
    keys = np.array(sorted(lat._surplus), dtype=np.int64)
    ij = np.column_stack([((keys >> 21) & LOW) - OFFSET, (keys & LOW) - OFFSET])
    exact = np.array([lat.values[(1,), tuple(p)] for p in ij.tolist()])
    start = time.perf_counter()
    c1 = SmoothLattice(keys, exact)
    build = time.perf_counter() - start
    times: dict[str, list[float]] = {"stop_squares": [], "c1": []}
    load_before = os.getloadavg()
    for _ in range(args.repeats):
        start = time.perf_counter()
        lat._walk(ids, s)
        times["stop_squares"].append(time.perf_counter() - start)
        start = time.perf_counter()
        c1.evaluate(ids, s)
        times["c1"].append(time.perf_counter() - start)
    ratios = [a / b for a, b in zip(times["c1"], times["stop_squares"], strict=True)]
    fresh = rng.uniform(-args.spread, args.spread, (args.check, 2))
    truth = np.array([smooth((), stretch(x)) for x in fresh])
    zeros = np.zeros(len(fresh), dtype=np.int64)
    errors = {
        "bilinear": lat.relative_difference(lat._walk(zeros, fresh)[0], truth),
        "c1": lat.relative_difference(c1.evaluate(zeros, fresh), truth),
    }
    at_points = lat.relative_difference(
        c1.evaluate(np.zeros(len(ij), np.int64), ij * (H0 / STEP)), exact
    )
    result = {
        "machine": machine_description(), "load_before": load_before,
        "load_after": os.getloadavg(), "cells": args.cells, "spread": args.spread,
        "tolerance": args.tolerance, "repeats": args.repeats, "points": len(keys),
        "seconds": times, "median_seconds": {k: statistics.median(v) for k, v in times.items()},
        "ratio_median_c1_over_stop_squares": statistics.median(ratios), "c1_build_seconds": build,
        "largest_relative_error": {k: float(v.max()) for k, v in errors.items()},
        "median_relative_error": {k: float(np.median(v)) for k, v in errors.items()},
        "c1_largest_difference_at_points": float(at_points.max()),
    }  # fmt: skip
    print(json.dumps({k: v for k, v in result.items() if k not in ("machine", "seconds")}))
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
