"""Scaling benchmark (issue 10, item 3): cost per step and peak memory from 1e4 to 1e6 dofs.

Every run is ``plantgrowth run`` of ``scenes/gradient_E_strain.toml`` (material.E from 0.5 to 2,
strain law) with the tissue's width and height scaled together to a target number of fine dofs
(h and H from the accuracy preset), ``PLANTGROWTH_CACHE_DIR=off``, under ``mpirun -n R`` for
R > 1, each rank under ``/usr/bin/time`` (its peak resident memory, elapsed and CPU time). The
time per step is summary.csv's seconds columns (maximum over ranks) averaged over steps
1..n; step 0, which also builds the multigrid hierarchy or the symbolic factorization and fills
the cell surrogate, is reported on its own. Parts (each replaces its entry in the JSON, the others
are kept):

- ``crossover``: 1 rank, ``solver.macro = "direct"`` and ``"iterative"`` at each size, t_max = 3:
  the macro solve time that sets ``solver.macro_threshold``;
- ``scaling``: 1 and 2 ranks, ``solver.macro = "auto"``, t_max = 5;
- ``micro``: the micro model's walls problem (reference strain scene, P2, 2 elements across a
  wall) at Nx = 16 and 32, 1 rank: two solves (assembly included) with LU and with CG + GAMG
  (rigid-body near-nullspace, the macro solver's options), each in its own process;
- ``organ``: ``scenes/organ_E_gradient.toml`` as shipped (60 steps) on 2 ranks, with the load
  average at start and end (run it last, on an otherwise idle machine).

    python scripts/benchmarks/scaling.py [--parts crossover scaling micro organ] [--out FILE]
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import plantgrowth as pg
from plantgrowth.base.machine import machine_description
from plantgrowth.scene.limits import MACRO_THRESHOLD
from plantgrowth.scene.toml_text import dict_to_toml

REPO = Path(__file__).resolve().parents[2]
BASE = REPO / "scenes" / "gradient_E_strain.toml"
ORGAN = REPO / "scenes" / "organ_E_gradient.toml"
PLANTGROWTH = str(Path(sys.executable).with_name("plantgrowth"))
PHASES = ("seconds", "seconds_cells", "seconds_solve", "seconds_growth", "seconds_io")
SCALING_DOFS = (1e4, 3e4, 1e5, 3e5, 1e6)
CROSSOVER_DOFS = (3e4, 1e5, 2e5, 3e5, 5e5)
ENV = {
    "PLANTGROWTH_CACHE_DIR": "off",
    "OMPI_ALLOW_RUN_AS_ROOT": "1",
    "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
    "OMPI_MCA_rmaps_base_oversubscribe": "1",
    "OMPI_MCA_btl_vader_single_copy_mechanism": "none",
}
TIMED = 'exec /usr/bin/time -f "%M %e %U %S" -o "$0.${OMPI_COMM_WORLD_RANK:-0}" "$@"'
"""Shell wrapper of one rank: GNU time writes peak RSS [KiB], elapsed, user, system [s]."""


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--parts", nargs="+", default=["crossover", "scaling"],
        choices=["crossover", "scaling", "micro", "organ"],
    )  # fmt: skip
    parser.add_argument(
        "--micro-solve",
        nargs=3,
        metavar=("NX", "KIND", "JSON"),
        help="(internal) time the micro solves of one Nx and solver kind",
    )
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks/results/scaling.json")
    return parser.parse_args(argv)


def scaled_scene(target_dofs: float, t_max: float, solver: dict) -> dict:
    """The base scene on a tissue scaled (width and height together) to about ``target_dofs``
    P1 dofs (2 per node of the rectangle mesh at the preset's h)."""
    with open(BASE, "rb") as f:
        data = tomllib.load(f)
    tissue = pg.Scene.from_dict(data).tissue

    def dofs(s: float) -> int:
        nx, ny = round(s * tissue.width / tissue.h), round(s * tissue.height / tissue.h)
        return 2 * (nx + 1) * (ny + 1)

    low, high = 0.1, 1000.0
    for _ in range(60):  # bisection on the scale factor
        middle = (low * high) ** 0.5
        low, high = (middle, high) if dofs(middle) < target_dofs else (low, middle)
    data["tissue"] |= {"width": high * tissue.width, "height": high * tissue.height}
    data.setdefault("time", {})["t_max"] = t_max
    data["solver"] = solver
    return data


def run(scene: dict, ranks: int, workdir: Path) -> dict:
    """One ``plantgrowth run`` of ``scene`` on ``ranks`` ranks: its record (see the module)."""
    workdir.mkdir(parents=True)
    path, outdir, rss = workdir / "scene.toml", workdir / "out", workdir / "rusage"
    path.write_text(dict_to_toml(scene))
    mpirun = ["mpirun", "-n", str(ranks)] if ranks > 1 else []
    command = mpirun + ["sh", "-c", TIMED, str(rss), PLANTGROWTH, "run", str(path), "-o", outdir]
    load_start, start = os.getloadavg(), time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, env=os.environ | ENV)
    wall, load_end = time.perf_counter() - start, os.getloadavg()
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, command))} failed:\n{done.stderr}")
    record = {"ranks": ranks, "wall_seconds": wall, "load_average_start": load_start,
              "load_average_end": load_end, "scene": dict_to_toml(scene)}  # fmt: skip
    record |= run_log(outdir / "run.log") | per_rank(rss, ranks) | steps(outdir / "summary.csv")
    shutil.rmtree(outdir)
    return record


def run_log(path: Path) -> dict:
    """Fine dofs, coarse nodes, set-up time, the solver and its CG iterations from run.log."""
    text = path.read_text()
    sizes = re.search(r"macro: (\d+) fine dofs, (\d+) coarse nodes", text)
    iterations = [int(k) for k in re.findall(r"macro solve: (\d+) CG iterations", text)]
    return {
        "fine_dofs": int(sizes[1]),
        "coarse_nodes": int(sizes[2]),
        "setup_seconds": float(re.search(r"set-up: ([\d.]+) s", text)[1]),
        "macro_solver": re.search(r"macro solver: (.+?) \(", text)[1],
        "cg_iterations": iterations,
    }


def per_rank(prefix: Path, ranks: int) -> dict:
    """Peak memory (per rank, their sum and maximum, MiB) and CPU seconds from GNU time."""
    rows = [prefix.with_name(f"{prefix.name}.{r}").read_text().split()[-4:] for r in range(ranks)]
    peak = [int(row[0]) / 1024 for row in rows]
    return {
        "peak_rss_mib": peak,
        "peak_rss_mib_total": sum(peak),
        "peak_rss_mib_max": max(peak),
        "cpu_seconds": [float(row[2]) + float(row[3]) for row in rows],
    }


def steps(path: Path) -> dict:
    """Step 0's seconds per phase and the mean over steps 1..n; cell solves per step."""
    with open(path, newline="") as f:
        rows = [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]
    later = rows[1:]
    return {
        "steps": len(rows),
        "step0": {p: rows[0][p] for p in PHASES},
        "per_step": {p: statistics.fmean(r[p] for r in later) for p in PHASES},
        "cell_solves": [int(r["n_cell_solves"]) for r in rows],
        "largest_residual": max(r["residual"] for r in rows),
    }


def report(record: dict, label: str) -> None:
    phases = " ".join(f"{p[8:] or 'step'} {record['per_step'][p]:.3g}" for p in PHASES)
    print(
        f"{label}: {record['fine_dofs']} dofs, {record['ranks']} rank(s), {record['macro_solver']}"
        f": s/step {phases}; peak {record['peak_rss_mib_total']:.0f} MiB; "
        f"wall {record['wall_seconds']:.1f} s",
        flush=True,
    )


def crossover(workdir: Path) -> dict:
    """Macro solve time per step of LU and CG + GAMG at each size, 1 rank."""
    runs = []
    for target in CROSSOVER_DOFS:
        for kind in ("direct", "iterative"):
            scene = scaled_scene(target, 3.0, {"macro": kind})
            runs.append(run(scene, 1, workdir / f"crossover_{target:.0e}_{kind}"))
            report(runs[-1], f"crossover {kind}")
    return {"runs": runs, "crossover_dofs": crossing(runs), "threshold": MACRO_THRESHOLD}


def crossing(runs: list[dict]) -> float | None:
    """Fine dofs where CG + GAMG's solve time per step meets LU's (log-log interpolation)."""
    by_size: dict[int, dict[str, float]] = {}
    for r in runs:
        kind = "iterative" if r["macro_solver"].startswith("CG + ") else "direct"
        by_size.setdefault(r["fine_dofs"], {})[kind] = r["per_step"]["seconds_solve"]
    points = sorted((n, math.log(t["iterative"] / t["direct"])) for n, t in by_size.items())
    for (n0, d0), (n1, d1) in zip(points, points[1:], strict=False):
        if d0 > 0 >= d1:
            return math.exp(math.log(n0) + d0 / (d0 - d1) * (math.log(n1) - math.log(n0)))
    return None


def scaling(workdir: Path) -> dict:
    runs = []
    for target in SCALING_DOFS:
        for ranks in (1, 2):
            scene = scaled_scene(target, 5.0, {"macro": "auto"})
            runs.append(run(scene, ranks, workdir / f"scaling_{target:.0e}_{ranks}"))
            report(runs[-1], "scaling")
    return {"runs": runs}


MICRO_NX = (16, 32)
MICRO_RTOL = 1e-10  # as the macro solver's


def micro_solves(nx: int, kind: str, out: Path) -> None:
    """Two steps of the micro model at Fg = I with ``kind``'s solver (in this process): each
    step's solve time (assembly included), iterations and true residual."""
    from mpi4py import MPI

    from plantgrowth.models.linear import gamg_solver
    from plantgrowth.models.micro.model import MicroModel

    start = time.perf_counter()
    model = MicroModel(pg.load_scene(REPO / "scenes" / "reference_strain.toml"), MPI.COMM_WORLD, nx)
    setup = time.perf_counter() - start
    if kind == "iterative":
        model.ksp = gamg_solver(model.A, model.V, "micro_", MICRO_RTOL, max_it=5000)
    results, iterations = [], []
    for _ in range(2):
        results.append(model.step(model.initial_growth()))
        iterations.append(model.ksp.getIterationNumber())
    out.write_text(json.dumps({
        "nx": nx, "solver": kind, "dofs": model.ndofs, "setup_seconds": setup,
        "solve_seconds": [r.seconds["seconds_solve"] for r in results], "iterations": iterations,
        "residual": results[-1].residual, "u_norm": model.u.vector.norm(),
    }))  # fmt: skip


def micro(workdir: Path) -> dict:
    runs = []
    for nx in MICRO_NX:
        for kind in ("direct", "iterative"):
            out = workdir / f"micro_{nx}_{kind}.json"
            rss = workdir / f"micro_{nx}_{kind}.rusage"
            command = ["sh", "-c", TIMED, str(rss), sys.executable, __file__, "--micro-solve",
                       str(nx), kind, str(out)]  # fmt: skip
            subprocess.run(command, check=True, env=os.environ | ENV)
            runs.append(json.loads(out.read_text()) | per_rank(rss, 1))
            print(f"micro: {json.dumps(runs[-1])}", flush=True)
    return {"runs": runs}


def organ(workdir: Path) -> dict:
    with open(ORGAN, "rb") as f:
        scene = tomllib.load(f)
    record = run(scene, 2, workdir / "organ")
    report(record, "organ")
    totals = {p: record["per_step"][p] * (record["steps"] - 1) + record["step0"][p] for p in PHASES}
    return record | {"scene_file": "scenes/organ_E_gradient.toml", "totals": totals}


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if args.micro_solve:
        nx, kind, out = args.micro_solve
        micro_solves(int(nx), kind, Path(out))
        return 0
    results = json.loads(args.out.read_text()) if args.out.exists() else {}
    results["description"] = __doc__.split("\n\n")[0]
    results["command"] = "python scripts/benchmarks/scaling.py --parts " + " ".join(args.parts)
    parts = {"crossover": crossover, "scaling": scaling, "micro": micro, "organ": organ}
    with tempfile.TemporaryDirectory() as tmp:
        run(scaled_scene(SCALING_DOFS[0], 1.0, {}), 1, Path(tmp) / "warm-up")  # JIT cache
        for name in args.parts:
            results[name] = {"machine": machine_description()} | parts[name](Path(tmp))
            args.out.write_text(json.dumps(results, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
