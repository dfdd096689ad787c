"""Cost of the micro linear solve's refinement step (plantgrowth/models/refinement.py).

On a generated tissue (``[tissue] cells = {voronoi = Nx^2/2, seed, regularity = r}``, the scene
of scripts/studies/micro_cells_ranks.py, linear kinematics, serial): one ``MicroModel.step`` at
t = 0 with the refinement step (A) and without it (B, ``refine`` returning the LU's report),
interleaved A B A B ...; also the solve alone (assembly and LU, then the refinement). Records
the median seconds of each, the ratios A/B pair by pair and their median, the relative change
the step makes to u (``|u_A - u_B| / |u_B|``), the machine and the load averages.
Writes benchmarks/results/micro_refinement.json.

    python scripts/benchmarks/bench_micro_refinement.py [--nx 16] [--repeats 7]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
from mpi4py import MPI

from plantgrowth.base.machine import machine_description
from plantgrowth.models.micro.model import MicroModel
from plantgrowth.scene import parse_scene

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/micro_refinement.json"
sys.path.insert(0, str(ROOT / "scripts/studies"))
from micro_cells_ranks import scene_text  # noqa: E402


def timed(model: MicroModel, refine: bool) -> tuple[float, float, np.ndarray]:
    """Seconds of one step at t = 0 and of its solve, and u, with or without the refinement."""
    if not refine:
        model._refinement.refine = lambda report, *args: report
    solve = model._linear_solve
    seconds = []

    def measured():
        start = time.perf_counter()
        report = solve()
        seconds.append(time.perf_counter() - start)
        return report

    model._linear_solve = measured
    refiner = model._refinement.refine

    def refine_timed(report, *args):
        start = time.perf_counter()
        out = refiner(report, *args)
        seconds[-1] += time.perf_counter() - start
        return out

    model._refinement.refine = refine_timed
    start = time.perf_counter()
    model.step(model.initial_growth())
    step = time.perf_counter() - start
    del model._linear_solve, model._refinement.refine
    return step, seconds[0], model.u.x.array.copy()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--nx", type=int, default=16)
    parser.add_argument("--r", type=float, default=0.25)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args(argv)
    scene = parse_scene(tomllib.loads(scene_text(args.nx, args.r, args.seed, "linear")))
    model = MicroModel(scene, MPI.COMM_SELF)
    result = {"command": "python scripts/benchmarks/bench_micro_refinement.py "
              + " ".join(sys.argv[1:]), "machine": machine_description(),
              "load_average_before": os.getloadavg(), "ndofs": model.ndofs}  # fmt: skip
    timed(model, True)  # warm-up: the forms' first assembly, the scatter, the factorization
    runs: dict[str, list] = {"refined": [], "plain": []}
    for _ in range(args.repeats):
        runs["refined"].append(timed(model, True))
        runs["plain"].append(timed(model, False))
    for k, name in ((0, "step"), (1, "solve")):
        ratios = [a[k] / b[k] for a, b in zip(runs["refined"], runs["plain"], strict=True)]
        result[name] = {
            "refined_seconds_median": statistics.median(r[k] for r in runs["refined"]),
            "plain_seconds_median": statistics.median(r[k] for r in runs["plain"]),
            "ratio_median": statistics.median(ratios), "ratios": ratios,
        }  # fmt: skip
    u_a, u_b = runs["refined"][-1][2], runs["plain"][-1][2]
    result["u_relative_change"] = float(np.linalg.norm(u_a - u_b) / np.linalg.norm(u_b))
    result["load_average_after"] = os.getloadavg()
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps({k: v for k, v in result.items() if k != "machine"}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
