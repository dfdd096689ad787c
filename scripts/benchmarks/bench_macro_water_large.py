"""A large hydraulic tissue on the iterative path (issue 35: a 1e5-dof hydraulic tissue runs
with the iterative path on 2 ranks, per-step time and iterations recorded).

``scenes/biology/apex_fed_from_below.toml`` (water supplied from the strand at its base, the
walls conducting poorly: P falls with the height) on a tissue ``--scale`` times the reference
tissue in width and height, ``solver.macro = "iterative"`` (MINRES + the block preconditioner
of plantgrowth.models.linear.saddle_point_solver), preset ``balanced``, at each fine-mesh
``--h``: the same domain refined, so the iterations show whether they stay bounded with h.
Runs ``mpirun -n RANKS plantgrowth run`` once per h (cell cache off; only P is written) and
records the fine dofs (u and P together), per step summary.csv's seconds and seconds_solve and
run.log's MINRES iterations (step 0, the initial equilibrium, is u alone by LU), the wall time
and the load average before and after each run. Writes
``benchmarks/results/macro_water_large.json``.

    python scripts/benchmarks/bench_macro_water_large.py [--h 0.2 0.1] [--scale 4] [--steps 3]
        [--ranks 2]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import re
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

from bench_ranks import MPI_ENV

from plantgrowth.base.machine import machine_description
from plantgrowth.scene.toml_text import dict_to_toml

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/macro_water_large.json"
SCENE = ROOT / "scenes/biology/apex_fed_from_below.toml"
REFERENCE_TISSUE = (6.928203230275509, 3.0)
"""The reference tissue (width, height), the scene's."""


def scene(scale: float, h: float, steps: int) -> dict:
    """The apex scene on the scaled tissue with fine edges h, iterative, ``steps`` steps."""
    data = tomllib.loads(SCENE.read_text())
    width, height = (scale * x for x in REFERENCE_TISSUE)
    return data | {
        "tissue": {"width": width, "height": height, "h": h},
        "solver": {"macro": "iterative"},
        "time": data["time"] | {"t_max": float(steps)},
        "output": {"fields": ["P"]},
    }


def run(data: dict, ranks: int) -> dict:
    """One ``mpirun -n ranks plantgrowth run`` of the scene data: its dofs, wall seconds, load
    averages, per-step seconds, seconds_solve and MINRES iterations."""
    exe = Path(sys.executable).with_name("plantgrowth")
    before = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="plantgrowth-bench-water-large-") as tmp:
        path = Path(tmp) / "scene.toml"
        path.write_text(dict_to_toml(data))
        command = ["/usr/bin/mpirun", "-n", str(ranks), str(exe), "run", str(path), "-o",
                   f"{tmp}/o"]  # fmt: skip
        start = time.perf_counter()
        done = subprocess.run(command, capture_output=True, text=True,
                              env=os.environ | MPI_ENV)  # fmt: skip
        wall = time.perf_counter() - start
        if done.returncode != 0:
            return {"failed": done.returncode, "stderr": done.stderr[-2000:]}
        with open(Path(tmp) / "o/summary.csv", newline="") as f:
            rows = list(csv.DictReader(f))
        log = (Path(tmp) / "o/run.log").read_text()
    u_dofs = int(re.search(r"macro: (\d+) fine dofs", log).group(1))
    iterations = [int(n) for n in re.findall(r"macro water solve: (\d+) MINRES iterations", log)]
    return {
        "u_dofs": u_dofs,
        "dofs_u_and_P": u_dofs + u_dofs // 2,  # P1 P on the P1 u's nodes
        "wall_seconds": wall,
        "setup_seconds": float(re.search(r"set-up: ([0-9.]+) s", log).group(1)),
        "load_average_1_5_15": {"before": list(before), "after": list(os.getloadavg())},
        "step_seconds": [float(r["seconds"]) for r in rows],
        "step_seconds_solve": [float(r["seconds_solve"]) for r in rows],
        "minres_iterations": [0, *iterations],  # step 0: the initial equilibrium, LU
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--h", type=float, nargs="+", default=[0.2, 0.1])
    parser.add_argument("--scale", type=float, default=4.0)
    parser.add_argument("--steps", type=int, default=3)
    parser.add_argument("--ranks", type=int, default=2)
    args = parser.parse_args(argv)
    runs = {}
    for h in args.h:
        runs[f"h{h:g}"] = result = run(scene(args.scale, h, args.steps), args.ranks)
        print(h, json.dumps(result), flush=True)
    result = {
        "description": "apex_fed_from_below on a tissue scale x the reference, iterative path "
        "(MINRES + field split), mpirun -n ranks, per step seconds and MINRES iterations",
        "command": "python " + " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        "scale": args.scale,
        "steps": args.steps,
        "ranks": args.ranks,
        "timing_notes": "one run per h, PLANTGROWTH_CACHE_DIR=off, the 2 cores shared with "
        "other jobs (load averages recorded): per-step seconds are upper bounds",
        "runs": runs,
        "machine": machine_description(),
    }
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
