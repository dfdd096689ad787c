"""Cost of the micro model on a generated tissue of cells (issue 34): wall, CPU, memory, dofs.

The scene: ``model = "micro"``, ``[tissue] cells = {voronoi = N, seed = 1, regularity = 0.5}``
(N = Nx^2/2, the rule of plantgrowth/meshes/voronoi_tissue.py; 968 = Nx 44 is the count nearest
1,000), stress law, P1 = 0.001, ``accuracy.preset = "draft"`` with ``micro.resolution = 1`` (the
preset sets no micro resolution; 1 is the cheapest), ``time.t_max = 10`` (dt = 1: ten growth
steps, eleven solves with t = 0), linear kinematics. Each size is run once by
``mpirun -n RANKS plantgrowth run`` into a temporary directory; recorded: the wall seconds, the
CPU seconds of all its processes (children's user + system), the peak resident memory of the
largest process, the P2 dofs (run.log), the set-up and the per-step solve seconds (summary.csv).

The largest tissue 2 cores run in 10 minutes is an ESTIMATE: a power law ``wall = a N^b`` fitted
to the sizes run (least squares in log-log), solved for wall = 600 s.

    python scripts/benchmarks/bench_real_tissue.py [--cells 128 288 512 968] [--ranks 2]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_naive import REPO, summary_rows

BUDGET_SECONDS = 600.0
RESULTS = "real_tissue_cost.json"
MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           "OMPI_MCA_rmaps_base_oversubscribe": "1",
           "OMPI_MCA_btl_vader_single_copy_mechanism": "none"}  # fmt: skip


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cells", type=int, nargs="+", default=[128, 288, 512, 968])
    parser.add_argument("--ranks", type=int, default=2)
    parser.add_argument("--t-max", type=float, default=10.0)
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks/results" / RESULTS)
    return parser.parse_args(argv)


def scene_text(n_cells: int, t_max: float) -> str:
    return (
        'model = "micro"\n'
        "[tissue]\n"
        f"cells = {{voronoi = {n_cells}, seed = 1, regularity = 0.5}}\n"
        '[accuracy]\npreset = "draft"\n'
        "[micro]\nresolution = 1\n"
        '[growth]\nlaw = "stress"\n'
        "[pressure]\nP1 = 0.001\n"
        f"[time]\nt_max = {t_max}\n"
    )


def run_once(n_cells: int, ranks: int, t_max: float, tmp: Path) -> dict:
    """One run of the scene of ``n_cells`` cells: its cost record."""
    scene, outdir = tmp / f"cells_{n_cells}.toml", tmp / f"run_{n_cells}"
    scene.write_text(scene_text(n_cells, t_max))
    plantgrowth = Path(sys.executable).with_name("plantgrowth")
    command = [str(plantgrowth), "run", str(scene), "-o", str(outdir)]
    if ranks > 1:
        command = ["/usr/bin/mpirun", "-n", str(ranks), *command]
    env = dict(os.environ, PLANTGROWTH_CACHE_DIR="off", **MPI_ENV)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    output = tmp / f"out_{n_cells}.log"
    with open(output, "w") as out:
        start = time.perf_counter()
        redirect = [(os.POSIX_SPAWN_DUP2, out.fileno(), 1), (os.POSIX_SPAWN_DUP2, out.fileno(), 2)]
        pid = os.posix_spawn(command[0], command, env, file_actions=redirect)
        _, status, _ = os.wait4(pid, 0)
        wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if os.waitstatus_to_exitcode(status):
        raise RuntimeError(f"{' '.join(command)} failed:\n{output.read_text()}")
    log = (outdir / "run.log").read_text()
    rows = summary_rows(outdir)
    return {
        "cells": n_cells,
        "nx": int(round((2 * n_cells) ** 0.5)),
        "dofs": int(re.search(r"(\d+) dofs \(P2\)", log).group(1)),
        "wall_seconds": wall,
        "cpu_seconds": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
        "max_rss_mib_largest_process": after.ru_maxrss / 1024,
        "setup_seconds": float(re.search(r"set-up: ([0-9.]+) s", log).group(1)),
        "solves": len(rows),
        "solve_seconds_per_step": [r["seconds_solve"] for r in rows],
        "seconds_per_step": [r["seconds"] for r in rows],
    }


def power_fit(cells: list[float], seconds: list[float]) -> dict:
    """The power law ``seconds = a N^b`` (log-log least squares) and the N it gives for
    BUDGET_SECONDS."""
    b, log_a = np.polyfit(np.log(cells), np.log(seconds), 1)
    return {"exponent_b": float(b), "prefactor_a": float(np.exp(log_a)),
            "cells_in_budget": float(np.exp((np.log(BUDGET_SECONDS) - log_a) / b))}  # fmt: skip


def largest_in_budget(runs: list[dict], ranks: int) -> dict | None:
    """The cells run in BUDGET_SECONDS, fitted to the wall seconds as measured (the shared
    machine's load included) and to the CPU seconds over the ranks (the wall time of an
    otherwise idle machine, if the ranks kept their cores busy); None with fewer than two
    sizes."""
    if len(runs) < 2:
        return None
    cells = [r["cells"] for r in runs]
    return {
        "measured_wall": power_fit(cells, [r["wall_seconds"] for r in runs]),
        "cpu_over_ranks": power_fit(cells, [r["cpu_seconds"] / ranks for r in runs]),
        "budget_seconds": BUDGET_SECONDS,
        "note": "ESTIMATES from power-law fits of the sizes run, not runs at those sizes",
    }


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    load_before = os.getloadavg()
    runs: list[dict] = []
    with tempfile.TemporaryDirectory(prefix="plantgrowth-bench-real-tissue-") as tmp:
        for n_cells in args.cells:  # the file is rewritten after each size
            runs.append(run_once(n_cells, args.ranks, args.t_max, Path(tmp)))
            r = runs[-1]
            print(f"{n_cells} cells: {r['dofs']} dofs, wall {r['wall_seconds']:.1f} s, CPU "
                  f"{r['cpu_seconds']:.1f} s, {r['max_rss_mib_largest_process']:.0f} MiB",
                  flush=True)  # fmt: skip
            write(args, runs, load_before)
    return 0


def write(args: argparse.Namespace, runs: list[dict], load_before: tuple[float, ...]) -> None:
    from plantgrowth.base.machine import machine_description

    result = {
        "description": "plantgrowth run of the micro model on generated tissues of cells "
        "(regularity 0.5), draft preset with micro.resolution = 1, ten steps of dt = 1",
        "command": "python " + " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        "scene": scene_text(args.cells[-1], args.t_max),
        "ranks": args.ranks,
        "timing_notes": "one run per size, PLANTGROWTH_CACHE_DIR=off; wall: the whole mpirun; "
        "cpu: user + system of all child processes; memory: ru_maxrss of the largest one; "
        "the machine is shared (see load averages)",
        "runs": runs,
        "largest_in_10_minutes": largest_in_budget(runs, args.ranks),
        "load_average_1_5_15": {"before": list(load_before), "after": list(os.getloadavg())},
        "machine": machine_description(),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"largest in 10 minutes: {result['largest_in_10_minutes']}; wrote {args.out}")


if __name__ == "__main__":
    sys.exit(main())
