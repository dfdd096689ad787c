"""Homogenized moduli versus wall thickness and versus growth (the paper's Fig. 1 d-o).

Two sweeps over l1/l2 in {1, 1.5, 2} (l2 = 1, theta = 30 deg, E = 1, nu = 0.3):
(i) thickness: w/l2 log-spaced in [0.01, 0.8], Fg = I, one cell per geometry (``pg.cell``);
(ii) growth along x1: Fg = diag(g, 1), g in [1, 3], w/l2 = 0.05, one CellSolver per l1/l2
reused for every g. Writes the full summary of every point (``pg.cell``'s keys, which are
``CellResult.summary()``'s) as columns.

    python scripts/studies/cell_moduli_curves.py [--resolution 3] [--out FILE.json]
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

import plantgrowth as pg
from plantgrowth.base.machine import write_study_json
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.unitcell.solver import DEFAULT_RESOLUTION, CellSolver


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--resolution", type=int, default=DEFAULT_RESOLUTION)
    parser.add_argument("--ratios", type=float, nargs="+", default=[1.0, 1.5, 2.0], help="l1/l2")
    parser.add_argument("--theta", type=float, default=30.0, help="degrees")
    parser.add_argument("--E", type=float, default=1.0)
    parser.add_argument("--nu", type=float, default=0.3)
    parser.add_argument("--w-range", type=float, nargs=2, default=[0.01, 0.8], help="w/l2")
    parser.add_argument("--n-thickness", type=int, default=15)
    parser.add_argument("--g-range", type=float, nargs=2, default=[1.0, 3.0])
    parser.add_argument("--n-growth", type=int, default=11)
    parser.add_argument("--w-growth", type=float, default=0.05, help="w/l2 of the growth sweep")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/cell_moduli.json"))
    return parser.parse_args(argv)


def columns(summaries: list[dict]) -> dict[str, list]:
    """List of summary dicts -> dict of lists (one column per key)."""
    return {key: [s[key] for s in summaries] for key in summaries[0]} if summaries else {}


def thickness_sweep(args: argparse.Namespace, ratio: float, ws: np.ndarray) -> dict:
    summaries = [
        pg.cell(l1=ratio, l2=1.0, theta=args.theta, w=float(w), E=args.E, nu=args.nu,
                resolution=args.resolution, comm=MPI.COMM_SELF)
        for w in ws
    ]  # fmt: skip
    return {"w_over_l2": [float(w) for w in ws], **columns(summaries)}


def growth_sweep(args: argparse.Namespace, ratio: float, gs: np.ndarray) -> dict:
    cell = HoneycombCell(l1=ratio, l2=1.0, theta_deg=args.theta, w=args.w_growth)
    solver = CellSolver(cell, resolution=args.resolution, comm=MPI.COMM_SELF)
    summaries = [solver.solve(np.diag([g, 1.0]), args.E, args.nu).summary() for g in gs]
    return {"g": [float(g) for g in gs], **columns(summaries)}


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    logging.getLogger().setLevel(logging.WARNING)  # quiet the JIT's compiler log
    start = time.perf_counter()
    ws = np.geomspace(*args.w_range, args.n_thickness)
    gs = np.linspace(*args.g_range, args.n_growth)
    for ratio in args.ratios:
        w_max = HoneycombCell(l1=ratio, l2=1.0, theta_deg=args.theta, w=1e-3).w_max
        if ws.max() >= w_max:
            raise SystemExit(f"w/l2 = {ws.max()} >= w_max = {w_max:.4g} for l1/l2 = {ratio}")

    thickness, growth, seconds = {}, {}, {}
    for ratio in args.ratios:
        key = f"{ratio:g}"
        t0 = time.perf_counter()
        thickness[key] = thickness_sweep(args, ratio, ws)
        t1 = time.perf_counter()
        growth[key] = growth_sweep(args, ratio, gs)
        t2 = time.perf_counter()
        seconds[key] = {"thickness": t1 - t0, "growth": t2 - t1}
        print(
            f"l1/l2 = {key}: thickness sweep {t1 - t0:.1f} s, growth sweep {t2 - t1:.1f} s",
            flush=True,
        )

    result = {
        "description": "Homogenized moduli vs wall thickness and vs growth Fg = diag(g, 1)",
        "E": args.E,
        "nu": args.nu,
        "l2": 1.0,
        "theta_deg": args.theta,
        "resolution": args.resolution,
        "ratios": args.ratios,
        "w_growth": args.w_growth,
        "thickness": thickness,
        "growth": growth,
        "seconds": seconds,
    }
    write_study_json(args.out, result, start)
    return 0


if __name__ == "__main__":
    sys.exit(main())
