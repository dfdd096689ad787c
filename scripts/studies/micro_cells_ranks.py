"""Serial against ``mpirun -n 2`` on generated irregular tissues (issue 34, docs/real_tissues.md).

The scene of docs/real_tissues.md's "Runs": ``[tissue] cells = {voronoi = Nx^2/2, seed,
regularity = r}``, micro model, ``accuracy.preset = "draft"``, ``micro.resolution = 1``, stress
law, P1 = 0.001, dt = 1, t_max = 3, finite kinematics (and linear for r = 0.25, the only
irregular r it runs at). Each case runs ``plantgrowth run`` (this checkout's .venv) in serial and
under ``mpirun -n 2`` into two separate directories; compared, over every step:

- cells.csv, every numeric column (rows matched by step and cell id);
- summary.csv, every numeric column but the timings (``seconds*``) and the solvers' own
  residuals (``residual``, ``newton_residual``: round-off, not answers; recorded apart);

as ``max |a - b| / max |a|`` per column (``max |a|`` the column's largest magnitude over both
runs; a column zero in both: 0). Recorded per case: the largest of these and its column, the
wall seconds of each run, the steps each reached (against t_max), Newton's iterations per step,
and the cells.csv row where ``growth_direction_*`` differ most with that cell's
``growth_anisotropy`` (the direction of a nearly isotropic G is ill-conditioned: a change dG
turns it by about ``|dG| / (A tr G)``). Results: benchmarks/results/micro_cells_ranks.json
(rewritten after each case) with the machine and the load averages; ``--update`` keeps the
file's other rows and replaces those of the cases run (``updates``: each update's command
and load averages).

    python scripts/studies/micro_cells_ranks.py [--nx 8 16] [--r 0.25 0.5 1] [--seeds 1]
        [--kinematics finite linear] [--update] [--json FILE]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
T_MAX = 3.0
MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           "OMPI_MCA_rmaps_base_oversubscribe": "1",
           "OMPI_MCA_btl_vader_single_copy_mechanism": "none",
           "PLANTGROWTH_CACHE_DIR": "off"}  # fmt: skip
SOLVER_COLUMNS = ("residual", "newton_residual")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--nx", type=int, nargs="+", default=[8, 16])
    parser.add_argument("--r", type=float, nargs="+", default=[0.25, 0.5, 1.0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1])
    parser.add_argument("--kinematics", nargs="+", default=["finite", "linear"])
    parser.add_argument("--update", action="store_true", help="keep the file's other rows")
    parser.add_argument(
        "--json", type=Path, default=REPO / "benchmarks/results/micro_cells_ranks.json"
    )
    return parser.parse_args(argv)


def scene_text(nx: int, r: float, seed: int, kinematics: str) -> str:
    return (
        f'model = "micro"\nkinematics = "{kinematics}"\n'
        f"[tissue]\ncells = {{voronoi = {nx * nx // 2}, seed = {seed}, regularity = {r}}}\n"
        '[accuracy]\npreset = "draft"\n[micro]\nresolution = 1\n'
        '[growth]\nlaw = "stress"\n[pressure]\nP1 = 0.001\n'
        f"[time]\nt_max = {T_MAX}\ndt = 1.0\n"
    )


def run(scene: Path, outdir: Path, ranks: int) -> dict:
    """One ``plantgrowth run``: wall seconds and exit code."""
    command = [str(Path(sys.executable).with_name("plantgrowth")), "run", str(scene), "-o",
               str(outdir)]  # fmt: skip
    if ranks > 1:
        command = ["/usr/bin/mpirun", "-n", str(ranks), *command]
    start = time.perf_counter()
    with open(outdir.parent / f"{outdir.name}.log", "w") as log:
        code = subprocess.call(command, env=dict(os.environ, **MPI_ENV), stdout=log, stderr=log)
    return {"wall_seconds": time.perf_counter() - start, "exit_code": code}


def table(path: Path, keys: tuple[str, ...]) -> dict[str, np.ndarray]:
    """The numeric columns of a csv file, rows sorted by ``keys``."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    rows.sort(key=lambda row: tuple(float(row[k]) for k in keys))
    out = {}
    for name in rows[0] if rows else []:
        try:
            out[name] = np.array([float(row[name]) for row in rows])
        except ValueError:  # a text column
            pass
    return out


def differences(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> dict[str, float]:
    """``max |a - b| / max(|a|, |b|)`` per shared column (module docstring); None: row counts
    differ."""
    out = {}
    for name in sorted(set(a) & set(b)):
        if len(a[name]) != len(b[name]):
            out[name] = None
            continue
        scale = max(np.abs(a[name]).max(initial=0.0), np.abs(b[name]).max(initial=0.0))
        out[name] = float(np.abs(a[name] - b[name]).max(initial=0.0) / scale) if scale else 0.0
    return out


def worst(diffs: dict[str, float | None]) -> dict:
    if any(v is None for v in diffs.values()):
        return {"max_relative": None, "column": "row counts differ"}
    name = max(diffs, key=diffs.get)
    return {"max_relative": diffs[name], "column": name}


def direction_worst(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> dict:
    """The cells.csv row (step, cell) where the growth direction differs most, the difference
    and that cell's growth_anisotropy (run a's)."""
    diff = np.hypot(a["growth_direction_1"] - b["growth_direction_1"],
                    a["growth_direction_2"] - b["growth_direction_2"])  # fmt: skip
    i = int(np.argmax(diff))
    return {"step": int(a["step"][i]), "cell": int(a["cell"][i]), "difference": float(diff[i]),
            "growth_anisotropy": float(a["growth_anisotropy"][i]),
            "growth_anisotropy_min": float(a["growth_anisotropy"].min())}  # fmt: skip


def one(nx: int, r: float, seed: int, kinematics: str, tmp: Path) -> dict:
    case = f"nx{nx}_r{r}_s{seed}_{kinematics}"
    scene = tmp / f"{case}.toml"
    scene.write_text(scene_text(nx, r, seed, kinematics))
    row: dict = {"nx": nx, "cells": nx * nx // 2, "r": r, "seed": seed, "kinematics": kinematics}
    out = {ranks: tmp / f"{case}_ranks{ranks}" for ranks in (1, 2)}
    for ranks, outdir in out.items():
        row[f"ranks{ranks}"] = run(scene, outdir, ranks)
        summary = outdir / "summary.csv"
        s = table(summary, ("step",)) if summary.exists() else {}
        row[f"ranks{ranks}"] |= {
            "steps": int(s["step"].max()) if "step" in s else None,
            "t_last": float(s["t"].max()) if "t" in s else None,
            "reached_t_max": bool("t" in s and s["t"].max() >= T_MAX - 1e-12),
            "newton_iterations": s["newton_iterations"].tolist() if "newton_iterations" in s
            else None,
        }  # fmt: skip
    if not all((out[k] / "cells.csv").exists() for k in out):
        return row | {"error": "a run wrote no cells.csv (see its exit code)"}
    cells_tables = [table(out[k] / "cells.csv", ("step", "cell")) for k in out]
    cells = differences(*cells_tables)
    summaries = [table(out[k] / "summary.csv", ("step",)) for k in out]
    summary = differences(*summaries)
    answers = {k: v for k, v in summary.items()
               if not k.startswith("seconds") and k not in SOLVER_COLUMNS}  # fmt: skip
    return row | {
        "cells_csv": worst(cells), "summary_csv": worst(answers),
        "growth_direction_worst": direction_worst(*cells_tables),
        "cells_csv_columns": cells, "summary_csv_columns": answers,
        "solver_residuals": {k: [s[k].tolist() for s in summaries] for k in SOLVER_COLUMNS
                             if all(k in s for s in summaries)},
    }  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    from plantgrowth.base.machine import machine_description

    command = "python scripts/studies/micro_cells_ranks.py " + " ".join(sys.argv[1:])
    result = {
        "description": "plantgrowth run in serial against mpirun -n 2 on generated tissues: "
        "largest relative difference of cells.csv and summary.csv columns (module docstring)",
        "command": command, "machine": machine_description(),
        "load_average_before": os.getloadavg(), "rows": [],
    }  # fmt: skip
    loads = result  # where this run's load averages go
    if args.update and args.json.is_file():  # an update: its command and loads listed apart
        result = json.loads(args.json.read_text())
        loads = {"command": command, "load_average_before": os.getloadavg()}
        result.setdefault("updates", []).append(loads)
    with tempfile.TemporaryDirectory(prefix="plantgrowth-cells-ranks-") as tmp:
        for nx in args.nx:
            for r in args.r:
                for seed in args.seeds:
                    for kinematics in ("finite", "linear") if r == 0.25 else ("finite",):
                        if kinematics not in args.kinematics:
                            continue
                        row = one(nx, r, seed, kinematics, Path(tmp))
                        case = (nx, r, seed, kinematics)
                        result["rows"] = [
                            old for old in result["rows"]
                            if (old["nx"], old["r"], old["seed"], old["kinematics"]) != case
                        ] + [row]  # fmt: skip
                        print(json.dumps({k: v for k, v in row.items()
                                          if not k.endswith("_columns")}), flush=True)  # fmt: skip
                        loads["load_average_after"] = os.getloadavg()
                        args.json.parent.mkdir(parents=True, exist_ok=True)
                        args.json.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
