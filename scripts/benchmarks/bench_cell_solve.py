"""Cost of one cell solve in the coupled loop: ``CellSolver.solve`` on a solver that serves many Fg.

For the reference cell (docs/model.md section 9) at resolutions 1, 2, 3 it times repeated solves
with varying growth tensors (stretch, shear and rotation, drawn once from a fixed seed), in the two
modes of the coupled loop: the strain law (pressure problem and strain averages) and the stress
law (pressure problem only). The solver of a baseline commit, read with ``git show`` from this
repository and imported as it was, is timed on the same Fg, interleaved solve by solve with the
current one, so that both see the same machine load; their results are compared too.

The machine is shared: the JSON records the load average before and after, each solve's wall
time (``CellResult.seconds``) and the process CPU time of the call, and reports medians.

    python scripts/benchmarks/bench_cell_solve.py [--resolutions 1 2 3] [--repeats 40]
        [--baseline REV]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import logging
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
MODES = {"strain law": (True, True), "stress law": (True, False)}
BASELINE = "789cf8a"
"""The last commit whose cell solver assembles the UFL forms directly for every Fg."""


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--resolutions", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--repeats", type=int, default=40, help="timed solves per mode")
    parser.add_argument(
        "--baseline",
        default=BASELINE,
        help=f"git revision of the solver to compare with (default {BASELINE}; 'none': skip)",
    )
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/cell_solve.json"))
    return parser.parse_args(argv)


def load_baseline(revision: str, directory: Path):
    """The ``plantgrowth.unitcell.solver`` module of a git revision, imported under another name."""
    source = subprocess.run(
        ["git", "-C", str(REPO), "show", f"{revision}:plantgrowth/unitcell/solver.py"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    path = directory / "cell_solver_baseline.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location("cell_solver_baseline", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up while being built
    spec.loader.exec_module(module)
    return module


def growth_tensors(count: int) -> list[np.ndarray]:
    """Stretch (1-1.8 along a random direction), shear up to 0.3 and a rotation, det > 0."""
    rng = np.random.default_rng(2024)
    out = []
    for _ in range(count):
        t, r = rng.uniform(0.0, np.pi, 2)
        Rt = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
        Rr = np.array([[np.cos(r), -np.sin(r)], [np.sin(r), np.cos(r)]])
        stretch = Rt @ np.diag([rng.uniform(1.0, 1.8), 1.0]) @ Rt.T
        shear = np.array([[1.0, rng.uniform(-0.3, 0.3)], [0.0, 1.0]])
        out.append(Rr @ stretch @ shear)
    return out


def timed(solver, Fg: np.ndarray, flags: tuple[bool, bool]):
    cpu = time.process_time()
    result = solver.solve(Fg, 1.0, 0.3, *flags)
    return result, result.seconds, time.process_time() - cpu


def largest_difference(a, b) -> float:
    """Largest relative difference over the quantities both results hold."""
    worst = 0.0
    for name in ("E_hom", "K_hom", "dbar_w", "dbar_v"):
        x, y = getattr(a, name), getattr(b, name)
        if x is not None and y is not None:
            worst = max(worst, float(np.abs(x - y).max() / np.abs(y).max()))
    return worst


def ms(values: list[float]) -> float:
    return 1e3 * statistics.median(values)


def run_resolution(solvers: dict, cell, resolution: int, repeats: int) -> dict:
    """Set-up and per-mode solve times of each solver at one resolution."""
    built, out = {}, {"resolution": resolution, "modes": {}}
    for key in ("setup_seconds", "setup_cpu_seconds", "first_solve_seconds"):
        out[key] = {}
    for name, CellSolver in solvers.items():
        start, cpu = time.perf_counter(), time.process_time()
        built[name] = CellSolver(cell, resolution)
        out["setup_seconds"][name] = time.perf_counter() - start
        out["setup_cpu_seconds"][name] = time.process_time() - cpu
        # symbolic factorization and first use of each form
        out["first_solve_seconds"][name] = built[name].solve().seconds
    out["ndofs"] = built["current"].ndofs
    tensors = growth_tensors(repeats)
    for mode, flags in MODES.items():
        wall = {name: [] for name in built}
        cpu = {name: [] for name in built}
        difference = 0.0
        for Fg in tensors:
            results = {}
            for name, solver in built.items():
                results[name], w, c = timed(solver, Fg, flags)
                wall[name].append(w)
                cpu[name].append(c)
            if "baseline" in results:
                difference = max(
                    difference, largest_difference(results["current"], results["baseline"])
                )
        out["modes"][mode] = {
            "pressure": flags[0],
            "strain_averages": flags[1],
            "ms_per_solve": {name: ms(v) for name, v in wall.items()},
            "cpu_ms_per_solve": {name: ms(v) for name, v in cpu.items()},
            "wall_seconds_all": wall,
        }
        if "baseline" in built:
            out["modes"][mode]["largest_relative_difference"] = difference
    summary = ", ".join(
        f"{mode}: " + " / ".join(f"{n} {t:.2f}" for n, t in m["ms_per_solve"].items())
        for mode, m in out["modes"].items()
    )
    print(f"resolution {resolution}: {out['ndofs']} dofs, ms per solve {summary}", flush=True)
    return out


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from plantgrowth.base.machine import machine_description
    from plantgrowth.meshes.honeycomb import HoneycombCell
    from plantgrowth.unitcell.solver import CellSolver

    logging.getLogger().setLevel(logging.WARNING)  # quiet the JIT's compiler log
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="plantgrowth-baseline-") as tmp:
        solvers = {"current": CellSolver}
        if args.baseline != "none":
            solvers["baseline"] = load_baseline(args.baseline, Path(tmp)).CellSolver
        cell = HoneycombCell()
        CellSolver(cell, 1).solve()  # JIT warm-up, not timed
        runs = [run_resolution(solvers, cell, r, args.repeats) for r in args.resolutions]
    result = {
        "description": "ms per CellSolver.solve in the coupled loop (one solver, many Fg)",
        "command": "python " + " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        "cell": {"l1": cell.l1, "l2": cell.l2, "theta_deg": cell.theta_deg, "w": cell.w},
        "E": 1.0,
        "nu": 0.3,
        "element": "P2",
        "repeats": args.repeats,
        "baseline": None if args.baseline == "none" else args.baseline,
        "timing_notes": (
            "ms_per_solve: median wall time of CellResult.seconds (matrix, factorization, "
            "the solves and averages); cpu_ms_per_solve: median process CPU time of the call, "
            "less sensitive to other processes on the shared cores; setup_(cpu_)seconds: "
            "construction after a JIT warm-up; first_solve_seconds: the first solve of a new "
            "solver (symbolic factorization included). 'current' and 'baseline' alternate solve by "
            "solve on the same Fg."
        ),
        "load_average_1_5_15": {"before": list(load_before), "after": list(os.getloadavg())},
        "machine": machine_description(),
        "resolutions": runs,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"load average before {load_before}, after {os.getloadavg()}; wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
