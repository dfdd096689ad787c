"""Micro against macro with water fluxes (docs/micro_vs_macro.md, "With water fluxes"; issue 35).

``plantgrowth compare`` of a hydraulic scene (the reference cell with walls ``--w`` thick,
default 0.05, the stress law, Pi = 0.001, linear kinematics, dt = 1) at ``--nx`` (default
4 8 16) up to ``--t-max`` (default 10), for two supplies:

- ``all_edges``: a homogeneous tissue supplied on every edge it has (left, right, top; the
  symmetry plane x2 = 0 is a mirror), conductance L_s = ``--supply``;
- ``left_edge``: the same tissue supplied on its left edge only.

and two ways of taking Nx to infinity:

- ``fixed_L``: the scene's wall conductivity L = ``--conductivity`` at every Nx, one compare of
  all Nx. The cells are ``4 / Nx`` of the unit cell, so the tissue's conductivity
  ``kappa = (4 / Nx) L kappa_unit`` (docs/model.md, "The cells' size") falls with Nx: the macro
  problem itself changes with Nx (its hydraulic length as Nx^-1/2);
- ``fixed_kappa``: ``L = --conductivity * Nx / 16`` (one compare per Nx), so that kappa, and
  with it the macro problem, is that of Nx = 16 at every Nx: the homogenization limit in the
  strict sense, the micro tissue refining under one macro solution.

Errors (compare.csv, docs/outputs.md) at t = 0 and at t_max, and their least-squares rates p of
``e ~ delta^p`` over the Nx, go to ``--json`` (default
``benchmarks/results/compare_hydraulics.json``) with the machine description; raw runs to
``--raw`` (default ``results/compare_hydraulics``, git-ignored). ``--only`` reruns some cases
and keeps the others' entries; a case with w other than 0.05 is keyed ``<case>_w<w>``.

    nice -n 19 python scripts/studies/compare_hydraulics.py [--only all_edges_fixed_L]
    nice -n 19 python scripts/studies/compare_hydraulics.py --w 0.2
"""

from __future__ import annotations

import argparse
import csv
import json
import shlex
import sys
import time
from pathlib import Path

from plantgrowth.base.machine import machine_description
from plantgrowth.cli import main as plantgrowth
from plantgrowth.scene.toml_text import dict_to_toml
from plantgrowth.studies.compare import fitted_rate

ROOT = Path(__file__).resolve().parents[2]
SUPPLIES = {"all_edges": ("left", "right", "top"), "left_edge": ("left",)}
SCALINGS = ("fixed_L", "fixed_kappa")
CASES = [f"{supply}_{scaling}" for supply in SUPPLIES for scaling in SCALINGS]
REFERENCE_W = 0.05
KAPPA_NX = 16
"""fixed_kappa: L is the scene's conductivity at this Nx, scaled by Nx / KAPPA_NX elsewhere."""
RATED = (
    "err_u1", "err_u2", "err_ubar", "err_G",
    "err_u1_tmax", "err_u2_tmax", "err_ubar_tmax", "err_G_tmax", "err_P_tmax",
)  # fmt: skip


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add = parser.add_argument
    add("--nx", type=int, nargs="+", default=[4, 8, 16], help="cells per row")
    add("--t-max", type=float, default=10.0, help="the later time (dt = 1)")
    add("--conductivity", type=float, default=100.0, help="L (fixed_kappa: at Nx = 16)")
    add("--supply", type=float, default=100.0, help="L_s of each supplied edge")
    add("--w", type=float, default=REFERENCE_W, help="the cell's wall thickness w / l2")
    add("--resolution", type=int, default=2, help="micro P2 elements across a cell's own wall")
    add("--only", nargs="+", choices=CASES, default=CASES, help="cases to run")
    add("--raw", type=Path, default=Path("results/compare_hydraulics"), help="raw run root")
    add("--json", type=Path, default=ROOT / "benchmarks/results/compare_hydraulics.json")
    return parser.parse_args(argv)


def scene_data(supply: str, conductivity: float, args: argparse.Namespace) -> dict:
    """The hydraulic scene of a case: the reference cell with w, stress law, Pi = 0.001."""
    return {
        "model": "micro", "growth": {"law": "stress"}, "cell": {"w": args.w},
        "hydraulics": {
            "osmotic": 0.001, "conductivity": conductivity,
            "supply": [{"edge": e, "conductance": args.supply} for e in SUPPLIES[supply]],
        },
        "time": {"t_max": args.t_max, "dt": 1.0},
        "micro": {"resolution": args.resolution},
    }  # fmt: skip


def read_rows(path: Path) -> list[dict[str, float]]:
    """compare.csv's rows as numbers (empty cells left out)."""
    with open(path, newline="") as f:
        return [{k: float(v) for k, v in row.items() if v != ""} for row in csv.DictReader(f)]


def compare(scene: dict, nxs: list[int], out: Path) -> tuple[int, list[dict[str, float]], str]:
    """One ``plantgrowth compare`` in this process: exit code, compare.csv's rows, command."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / "scene.in.toml"
    path.write_text(dict_to_toml(scene))
    argv = ["compare", str(path), "--nx", *map(str, nxs), "-o", str(out / "run")]
    code = plantgrowth([*argv, "--overwrite", "-q"])
    table = out / "run" / "compare.csv"
    return code, read_rows(table) if table.is_file() else [], shlex.join(["plantgrowth", *argv])


def run_case(case: str, name: str, args: argparse.Namespace) -> dict:
    """A case's compares (one, or one per Nx for fixed_kappa) into ``--raw``/name, their rows
    and fitted rates."""
    supply, scaling = case.split("_fixed_")
    wall, cpu = time.perf_counter(), time.process_time()
    if scaling == "L":
        scene = scene_data(supply, args.conductivity, args)
        code, rows, command = compare(scene, args.nx, args.raw / name)
        scenes, commands, codes = {"all": scene}, [command], [code]
    else:
        scenes, commands, codes, rows = {}, [], [], []
        for nx in args.nx:
            scene = scene_data(supply, args.conductivity * nx / KAPPA_NX, args)
            code, more, command = compare(scene, [nx], args.raw / name / f"nx{nx}")
            scenes[f"nx{nx}"], rows = scene, rows + more
            commands.append(command)
            codes.append(code)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    nx = [r["nx"] for r in rows]
    rated = [k for k in RATED if len(rows) > 1 and all(k in r for r in rows)]
    return {
        "w": args.w,
        "exit_codes": codes,  # not 0: that compare's failed Nx has no row (its run.log says why)
        "scenes": scenes,
        "commands": commands,
        "wall_seconds": round(wall, 1),
        "cpu_seconds": round(cpu, 1),
        "rows": rows,
        "fitted_rates": {k: round(fitted_rate(nx, [r[k] for r in rows]), 3) for k in rated},
    }


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    results = json.loads(args.json.read_text()) if args.json.is_file() else {"cases": {}}
    results["machine"] = machine_description()
    results["study_command"] = shlex.join(
        ["nice", "-n", "19", "python", "scripts/studies/compare_hydraulics.py",
         *(sys.argv[1:] if argv is None else argv)]
    )  # fmt: skip
    failed = []
    for case in args.only:
        name = case if args.w == REFERENCE_W else f"{case}_w{args.w:g}"
        print(f"{name}: Nx = {args.nx}", flush=True)
        entry = results["cases"][name] = run_case(case, name, args)
        print(f"{name}: {entry['wall_seconds']} s, rates {entry['fitted_rates']}", flush=True)
        failed += [name] if any(entry["exit_codes"]) else []
        write_results(results, args.json)  # after each case: a later failure keeps it
    print(f"-> {args.json}; failed: {failed or 0}")
    return 1 if failed else 0


def write_results(results: dict, path: Path) -> None:
    """The JSON, cases sorted by name."""
    results["notes"] = (
        "Serial, nice -n 19, one compare at a time on a shared 2-core machine: seconds are "
        "upper bounds. Errors are compare.csv's (docs/outputs.md): err_u1, err_u2, err_ubar, "
        "err_G at t = 0, the _tmax ones at t_max; err_P is the cell-by-cell turgor error "
        "sqrt(sum_c Y_c (P_c - P(x_c))^2 / sum_c Y_c P(x_c)^2), 0 at t = 0 (both models start "
        "at P = Pi + psi_0). fitted_rates: least-squares p of e ~ delta^p over the rows' Nx. "
        "fixed_L: the scene's L at every Nx (kappa ~ 4 / Nx); fixed_kappa: L scaled by "
        "Nx / 16, kappa that of Nx = 16 at every Nx (one compare per Nx)."
    )
    results["cases"] = dict(sorted(results["cases"].items()))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    sys.exit(main())
