"""Per-step cost and accuracy of the surrogate's c1 answers against the bilinear ones
(``accuracy.cell_interpolant``, docs/surrogate_c1.md), with no cell solve.

Two surrogates, ``bilinear`` and ``c1``, are refined by bench_stop_squares.py's smooth analytic
map of U, half of ``--cells`` queries (uniform in |s_i| <= ``--spread``) at step 0, the other
half at step 1 (so c1 has a refinement to blend in); with ``--births N`` > 1, all the queries
drifting outwards (stretches scaled by (b + 1) / (N + 1) at step b = 0..N), so that N
refinements blend at once (the organ's case: 6; ``c1_blending`` is then step N's call). Then,
alternated ``--repeats`` times, one ``evaluate`` of every query on each surrogate (no point is
added: a step without refinement, the same public call the run makes): ``bilinear`` (the stop
squares), ``c1_blending`` (step 1: the step-1 refinement blends in) and ``c1`` (B steps later:
settled, the cached cell polynomials; interleaved with ``bilinear_2``, the bilinear calls
again). The first c1 call after the blends end is timed apart (``c1_first``: it fits every stop
cell's coefficients). Medians of the seconds and their ratios to the bilinear calls they
alternated with; the largest and median relative error of each against the exact map at
``--check`` fresh queries (asked with an infinite tolerance, so nothing is refined); the
largest relative difference of c1 from the exact values at the built points. Writes
``benchmarks/results/c1_lookup.json`` (or ``--out``) with the machine and the load.

    python scripts/benchmarks/bench_c1_lookup.py [--cells 4140] [--repeats 21]
    python scripts/benchmarks/bench_c1_lookup.py --cells 500000 --repeats 5 --out X.json
    python scripts/benchmarks/bench_c1_lookup.py --cells 250000 --births 6 --repeats 3 --out X.json
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from bench_stop_squares import lattice_arguments, smooth
from mpi4py import MPI

from plantgrowth.base.machine import machine_description
from plantgrowth.unitcell.lattice import H0, OFFSETS, STEP
from plantgrowth.unitcell.smooth_answers import BLEND_STEPS
from plantgrowth.unitcell.surrogate import LatticeSurrogate, stretch

ROOT = Path(__file__).resolve().parents[2]
TABLE = [(1,)]


def built_points(lat: LatticeSurrogate) -> np.ndarray:
    """The built points' finest integers (P, 2), from the squares' rows (table (1,) only)."""
    rows = lat.squares()
    step = (STEP >> rows[:, -3])[:, None, None]
    return np.unique((rows[:, None, -2:] + OFFSETS[None] * step).reshape(-1, 2), axis=0)


def timed(call) -> tuple[float, np.ndarray]:
    start = time.perf_counter()
    values = call()
    return time.perf_counter() - start, values


def main(argv: list[str] | None = None) -> int:
    parser = lattice_arguments(__doc__.split("\n\n")[0])
    parser.add_argument("--check", type=int, default=20000)
    parser.add_argument("--births", type=int, default=1)
    parser.add_argument("--label", default="")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks/results/c1_lookup.json")
    args = parser.parse_args(argv)
    rng = np.random.default_rng(0)
    s = rng.uniform(-args.spread, args.spread, (args.cells, 2))
    ids = np.zeros(len(s), dtype=np.int64)
    lats = {
        kind: LatticeSurrogate(smooth, args.tolerance, [slice(0, 5)], MPI.COMM_SELF,
                               interpolant=kind)  # fmt: skip
        for kind in ("bilinear", "c1")
    }
    for lat in lats.values():
        for birth in range(args.births + 1):
            if birth:
                lat.end_step()
            if args.births == 1:
                lat.evaluate(TABLE, ids[: len(s) // (2 - birth)], s[: len(s) // (2 - birth)])
            else:
                lat.evaluate(TABLE, ids, s * (birth + 1) / (args.births + 1))
    bilinear, c1 = lats["bilinear"], lats["c1"]

    def ask(lat: LatticeSurrogate) -> np.ndarray:
        return lat.evaluate(TABLE, ids, s).values

    load_before = os.getloadavg()
    times: dict[str, list[float]] = {"bilinear": [], "c1_blending": [], "bilinear_2": [], "c1": []}
    for _ in range(args.repeats):
        times["bilinear"].append(timed(lambda: ask(bilinear))[0])
        times["c1_blending"].append(timed(lambda: ask(c1))[0])
    for _ in range(BLEND_STEPS):
        c1.end_step()
    first = timed(lambda: ask(c1))[0]
    for _ in range(args.repeats):
        times["bilinear_2"].append(timed(lambda: ask(bilinear))[0])
        times["c1"].append(timed(lambda: ask(c1))[0])
    medians = {k: statistics.median(v) for k, v in times.items()}
    ratios = {"c1_blending": medians["c1_blending"] / medians["bilinear"],
              "c1": medians["c1"] / medians["bilinear_2"]}  # fmt: skip
    fresh = rng.uniform(-args.spread, args.spread, (args.check, 2))
    truth = np.array([smooth((), stretch(x)) for x in fresh])
    endless = np.full(len(fresh), np.inf)
    zeros = np.zeros(len(fresh), dtype=np.int64)
    errors = {
        kind: lat.relative_difference(lat.evaluate(TABLE, zeros, fresh, endless).values, truth)
        for kind, lat in lats.items()
    }
    ij = built_points(c1)
    at_points = c1.relative_difference(
        c1.evaluate(TABLE, np.zeros(len(ij), np.int64), ij * (H0 / STEP)).values,
        np.array([c1.values[TABLE[0], tuple(p)] for p in ij.tolist()]),
    )
    result = {
        "label": args.label, "machine": machine_description(), "load_before": load_before,
        "load_after": os.getloadavg(), "cells": args.cells, "spread": args.spread,
        "births": args.births, "tolerance": args.tolerance, "repeats": args.repeats,
        "points": len(ij),
        "seconds": times, "median_seconds": medians, "c1_first_seconds": first,
        "median_ratio_to_bilinear": ratios,
        "largest_relative_error": {k: float(v.max()) for k, v in errors.items()},
        "median_relative_error": {k: float(np.median(v)) for k, v in errors.items()},
        "c1_largest_difference_at_points": float(at_points.max()),
    }  # fmt: skip
    print(json.dumps({k: v for k, v in result.items() if k not in ("machine", "seconds")}))
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
