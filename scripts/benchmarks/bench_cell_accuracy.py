"""Accuracy versus cost of the unit-cell solver (docs/model.md sections 3 and 9).

The reference cell (E = 1, nu = 0.3, l1 = l2 = 1, theta = 30 deg, w = 0.05) is solved at several
resolutions (P2 elements across the wall thickness w) for Fg = I and for the grown cell
Fg = diag(1.5, 1). For each resolution it records the number of dofs, the set-up time (mesh,
constraints, forms, first assembly; JIT excluded by a warm-up), the first solve (symbolic LU
factorization included) and the median time of repeated solves, i.e. the time per cell problem in
the coupled loop, where one CellSolver serves many Fg. Errors of E1, E2, nu12, G12, K11, K22 are
relative to the reference resolution. When the reference is divisible by 4, the ladder R/4, R/2, R
also gives a Richardson extrapolation (observed order per quantity) that estimates the error of
the reference itself.

    python scripts/benchmarks/bench_cell_accuracy.py [--resolutions 1 2 ... 12] [--reference 32]
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

QUANTITIES = ("E1", "E2", "nu12", "G12", "K11", "K22")
CASES = {
    "Fg=I": np.eye(2),
    "Fg=diag(1.5,1)": np.diag([1.5, 1.0]),
}
THRESHOLDS = {"1%": 1e-2, "0.1%": 1e-3}


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--resolutions", type=int, nargs="+", default=[1, 2, 3, 4, 5, 6, 8, 10, 12])
    parser.add_argument(
        "--reference",
        type=int,
        default=32,
        help="reference resolution (default 32: ~1.1e6 dofs, ~30 s per solve, ~6 GB)",
    )
    parser.add_argument("--repeats", type=int, default=5, help="timed solves per case")
    parser.add_argument("--E", type=float, default=1.0)
    parser.add_argument("--nu", type=float, default=0.3)
    parser.add_argument(
        "--jit-cache",
        choices=("temporary", "user"),
        default="temporary",
        help="'temporary': a fresh JIT cache, so the reported JIT time is a cold compile",
    )
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/cell_accuracy.json"))
    return parser.parse_args(argv)


def timed_solver(CellSolver, cell, resolution: int):
    start = time.perf_counter()
    solver = CellSolver(cell, resolution=resolution)
    return solver, time.perf_counter() - start


def run_resolution(CellSolver, cell, resolution: int, repeats: int, E: float, nu: float) -> dict:
    """Set-up, first solve and `repeats` timed solves per case at one resolution."""
    solver, setup = timed_solver(CellSolver, cell, resolution)
    first = solver.solve(None, E, nu).seconds
    out = {"resolution": resolution, "ndofs": solver.ndofs, "setup_seconds": setup}
    out["first_solve_seconds"] = first
    out["cases"] = {}
    for name, Fg in CASES.items():
        results = [solver.solve(Fg, E, nu) for _ in range(repeats)]
        summary = results[-1].summary()
        times = [r.seconds for r in results]
        out["cases"][name] = {
            "solve_seconds": statistics.median(times),
            "solve_seconds_all": times,
            "values": {q: summary[q] for q in QUANTITIES},
            "summary": summary,
        }
    print(
        f"resolution {resolution:3d}: {solver.ndofs:8d} dofs, setup {setup:7.3f} s, "
        f"first solve {first:7.3f} s, solve {out['cases']['Fg=I']['solve_seconds']:7.3f} s",
        flush=True,
    )
    return out


def richardson(coarse: float, mid: float, fine: float) -> dict | None:
    """Extrapolate a ladder with refinement ratio 2; None if not in the asymptotic range."""
    d1, d2 = coarse - mid, mid - fine
    if d1 * d2 <= 0.0 or abs(d2) >= abs(d1):
        return None
    order = math.log2(d1 / d2)
    return {"value": fine - d2 / (2.0**order - 1.0), "order": order}


def relative_errors(values: dict, reference: dict) -> dict:
    return {q: abs(values[q] - reference[q]) / abs(reference[q]) for q in reference}


def cheapest(rows: list[dict], key: str) -> dict:
    """Cheapest resolution (by time per cell) whose max error is within each threshold."""
    out = {}
    for label, tol in THRESHOLDS.items():
        ok = [r for r in rows if r[key] <= tol]
        best = min(ok, key=lambda r: r["solve_seconds"]) if ok else None
        out[label] = (
            None
            if best is None
            else {k: best[k] for k in ("resolution", "ndofs", "solve_seconds", key)}
        )
    return out


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    tmp_cache = None
    if args.jit_cache == "temporary":
        # read by dolfinx.jit at import time, hence before importing the solver
        tmp_cache = tempfile.mkdtemp(prefix="plantgrowth-jit-")
        os.environ["XDG_CACHE_HOME"] = tmp_cache
    from plantgrowth.base.machine import machine_description
    from plantgrowth.meshes.honeycomb import HoneycombCell
    from plantgrowth.unitcell.solver import CellSolver

    logging.getLogger().setLevel(logging.WARNING)  # quiet the JIT's compiler log
    wall_start = time.perf_counter()
    cell = HoneycombCell(l1=1.0, l2=1.0, theta_deg=30.0, w=0.05)
    resolutions = sorted(set(args.resolutions))
    R = args.reference
    ladder = [R // 4, R // 2] if R % 4 == 0 else []

    warm_resolution = resolutions[0]
    _, warmup_setup = timed_solver(CellSolver, cell, warm_resolution)
    runs = {
        r: run_resolution(CellSolver, cell, r, args.repeats, args.E, args.nu) for r in resolutions
    }
    for r in [*ladder, R]:
        if r not in runs:
            repeats = 1 if r == R else args.repeats
            runs[r] = run_resolution(CellSolver, cell, r, repeats, args.E, args.nu)
    jit_seconds = warmup_setup - runs[warm_resolution]["setup_seconds"]

    cases = {}
    for name, Fg in CASES.items():
        ref_values = runs[R]["cases"][name]["values"]
        extrapolated = {}
        if ladder:
            for q in QUANTITIES:
                values = [runs[r]["cases"][name]["values"][q] for r in (*ladder, R)]
                extrapolated[q] = richardson(*values)
        best = {
            q: (extrapolated[q]["value"] if extrapolated.get(q) else ref_values[q])
            for q in QUANTITIES
        }
        rows = []
        for r in sorted(runs):
            run, case = runs[r], runs[r]["cases"][name]
            err = relative_errors(case["values"], ref_values)
            est = relative_errors(case["values"], best)
            rows.append(
                {
                    "resolution": r,
                    "ndofs": run["ndofs"],
                    "setup_seconds": run["setup_seconds"],
                    "first_solve_seconds": run["first_solve_seconds"],
                    "solve_seconds": case["solve_seconds"],
                    "solve_seconds_all": case["solve_seconds_all"],
                    "repeats": len(case["solve_seconds_all"]),
                    "values": case["values"],
                    "rel_error": err,
                    "max_rel_error": max(err.values()),
                    "est_error": est,
                    "max_est_error": max(est.values()),
                    "summary": case["summary"],
                }
            )
        coarse_rows = [row for row in rows if row["resolution"] != R]
        cases[name] = {
            "Fg": Fg.tolist(),
            "reference_values": ref_values,
            "extrapolated": extrapolated,
            "reference_est_error": relative_errors(ref_values, best),
            "rows": rows,
            "cheapest_vs_reference": cheapest(coarse_rows, "max_rel_error"),
            "cheapest_vs_extrapolated": cheapest(coarse_rows, "max_est_error"),
        }

    result = {
        "description": "Unit-cell solver accuracy vs cost, reference cell of docs/model.md "
        "section 9",
        "cell": {"l1": cell.l1, "l2": cell.l2, "theta_deg": cell.theta_deg, "w": cell.w},
        "phi_w": runs[R]["cases"]["Fg=I"]["summary"]["phi_w"],
        "E": args.E,
        "nu": args.nu,
        "element": "P2",
        "resolution_meaning": "P2 elements across the wall thickness w (mesh size w/resolution)",
        "quantities": list(QUANTITIES),
        "resolutions": resolutions,
        "reference_resolution": R,
        "ladder": [*ladder, R] if ladder else None,
        "repeats": args.repeats,
        "jit_cache": args.jit_cache,
        "jit_seconds": jit_seconds,
        "timing_notes": (
            "setup_seconds: CellSolver construction (mesh, constraints, forms, first assembly) "
            "after a JIT warm-up; jit_seconds: warm-up construction minus setup at the same "
            "resolution; first_solve_seconds: first solve on a new solver (symbolic + numeric "
            "LU); solve_seconds: median of repeated solves (assembly, numeric LU, 4 solves, "
            "averages), the time per cell problem when one CellSolver serves many Fg."
        ),
        "machine": machine_description(),
        "cases": cases,
    }
    result["script_seconds"] = time.perf_counter() - wall_start
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    if tmp_cache is not None:
        shutil.rmtree(tmp_cache, ignore_errors=True)

    print(f"JIT (cold={args.jit_cache == 'temporary'}): {jit_seconds:.2f} s")
    for name, case in cases.items():
        print(f"{name}:")
        for row in case["rows"]:
            print(
                f"  r={row['resolution']:3d} ndofs={row['ndofs']:8d} "
                f"t={row['solve_seconds']:.4f} s  max err={row['max_rel_error']:.2e} "
                f"(est. {row['max_est_error']:.2e})"
            )
        print(f"  cheapest vs reference:    {case['cheapest_vs_reference']}")
        print(f"  cheapest vs extrapolated: {case['cheapest_vs_extrapolated']}")
    print(f"wrote {args.out} in {result['script_seconds']:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
