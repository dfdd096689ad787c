"""Micro against macro with fibre-reinforced walls and stress feedback (docs/fibres.md, "Micro
against macro"; issue 22's Done item).

Three ``plantgrowth compare`` cases of the scenes in ``scenes/compare/`` (a = 90, E_f / E = 5,
strain law, the reference geometry):

- ``first_step``: ``fibres_a90_strain.toml`` at ``--nx`` (default 4 8 16), first step only: the
  errors err_u1, err_u2, err_ubar, err_G and their least-squares rates in delta = 1/Nx;
- ``feedback_a90``: ``fibres_a90_feedback.toml`` (``[feedback] cue = "stress"``, k = 0.5) up to
  t = 60 at ``--feedback-nx`` (default 4 8 16): homogeneous and traction-free, so the macro
  director never turns; the micro directors do, cell by cell (docs/fibres.md);
- ``feedback_gradient_E``: ``fibres_gradient_E_feedback.toml``, the same with E rising along x1
  from 0.5 to 2: the directors turn in both models;
- ``single_cell``: the micro feedback's response to one turned director (:func:`single_cell`);
- ``macro_patch``: the homogenized model's response to a turned patch the size of one of those
  cells (:func:`macro_patch`).

``--walls`` sets the feedback cases' ``feedback.walls`` (the micro cue's walls: "around", the
default, both halves of every wall around the cell; "own", the cell's own halves, as before the
option existed): their scene is then a copy in ``--raw`` with that key, and their entries are
keyed ``<case>_<walls>`` (``single_cell_<walls>``).

Each compare runs in this process through the CLI (one process; run it under ``nice -n 19`` on
a shared machine); raw runs go to ``--raw`` (default ``results/compare_fibres``, git-ignored).
``--json`` (default ``benchmarks/results/compare_fibres.json``) gets, per case, the command,
the wall and CPU seconds, compare.csv's rows, each run's last summary row (fibre_order,
fibre_angle_mean, area, rates) and the fitted rates, with the machine description. ``--only``
reruns some cases and keeps the others' entries.

    nice -n 19 python scripts/studies/compare_fibres.py [--only first_step] [--feedback-nx 4 8]
    nice -n 19 python scripts/studies/compare_fibres.py --only feedback_a90 single_cell \
        --walls own --json benchmarks/results/compare_feedback.json
"""

from __future__ import annotations

import argparse
import csv
import json
import shlex
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
from mpi4py import MPI

from plantgrowth.base.machine import machine_description
from plantgrowth.cli import main as plantgrowth
from plantgrowth.models import fibres
from plantgrowth.models.macro.model import macro_model
from plantgrowth.models.micro.model import MicroModel
from plantgrowth.scene import parse_scene
from plantgrowth.scene.limits import FEEDBACK_WALLS
from plantgrowth.scene.toml_text import dict_to_toml
from plantgrowth.studies.compare import fitted_rate

ROOT = Path(__file__).resolve().parents[2]
SCENES = {
    "first_step": "fibres_a90_strain",
    "feedback_a90": "fibres_a90_feedback",
    "feedback_gradient_E": "fibres_gradient_E_feedback",
}
FIRST_STEP = ("err_u1", "err_u2", "err_ubar", "err_G")
AT_TMAX = tuple(f"{k}_tmax" for k in FIRST_STEP) + ("err_fibre_angle_tmax",)
LAST_ROW = (
    "step", "t", "area", "growth_rate_11", "growth_rate_22", "growth_rate_area",
    "fibre_order", "fibre_angle_mean",
)  # fmt: skip


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add = parser.add_argument
    add("--nx", type=int, nargs="+", default=[4, 8, 16], help="Nx of the first-step case")
    add("--feedback-nx", type=int, nargs="+", default=[4, 8, 16], help="Nx of the t = 60 cases")
    cases = [*SCENES, "single_cell", "macro_patch"]
    add("--only", nargs="+", choices=cases, default=cases, help="cases to run")
    add("--walls", choices=FEEDBACK_WALLS, default=None,
        help="feedback.walls of the feedback cases (default: the scenes')")  # fmt: skip
    add("--raw", type=Path, default=Path("results/compare_fibres"), help="raw run root")
    add("--json", type=Path, default=ROOT / "benchmarks/results/compare_fibres.json")
    return parser.parse_args(argv)


def read_rows(path: Path) -> list[dict[str, float]]:
    """A CSV file's rows as numbers (empty cells left out)."""
    with open(path, newline="") as f:
        return [{k: float(v) for k, v in row.items() if v != ""} for row in csv.DictReader(f)]


def rates(rows: list[dict[str, float]], keys: tuple[str, ...]) -> dict[str, float]:
    """Least-squares rates p of ``e ~ delta^p`` for each key present in every row."""
    nx = [r["nx"] for r in rows]
    present = [k for k in keys if all(k in r for r in rows)]
    return {k: round(fitted_rate(nx, [r[k] for r in rows]), 3) for k in present}


def case_scene(name: str, walls: str | None, raw: Path) -> Path:
    """The case's scene: the shipped one, or (``walls``) a copy in ``raw`` with that
    ``feedback.walls`` and ``numerics.on_instability = "warn"``: the micro walls' check with the
    fibred wall tensor finds a few non-elliptic wall points before t = 60 (0.02% of the tissue
    at the top-right corner, t = 49, Nx = 4, homogeneous scene), and the comparison runs on,
    the run logs saying where."""
    scene = ROOT / "scenes" / "compare" / f"{SCENES[name]}.toml"
    if walls is None:
        return scene
    data = tomllib.loads(scene.read_text())
    data["feedback"]["walls"] = walls
    data.setdefault("numerics", {})["on_instability"] = "warn"
    copy = raw / f"{SCENES[name]}_{walls}.toml"
    copy.parent.mkdir(parents=True, exist_ok=True)
    copy.write_text(dict_to_toml(data))
    return copy


def run_case(name: str, nxs: list[int], raw: Path, walls: str | None = None) -> dict:
    """One compare in this process; its rows, last summary rows, rates and seconds."""
    scene = case_scene(name, walls, raw)
    out = raw / (name if walls is None else f"{name}_{walls}")
    shown = scene.relative_to(ROOT).as_posix() if scene.is_relative_to(ROOT) else str(scene)
    command = ["compare", shown, "--nx", *map(str, nxs)]
    command += ["--first-step-only"] if name == "first_step" else []
    argv = ["compare", str(scene), *command[2:], "-o", str(out), "--overwrite", "-q"]
    wall, cpu = time.perf_counter(), time.process_time()
    code = plantgrowth(argv)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    rows = read_rows(out / "compare.csv") if (out / "compare.csv").is_file() else []
    last = {
        f"nx{nx}": {
            model: {k: v for k, v in read_rows(out / f"nx{nx}" / model / "summary.csv")[-1].items()
                    if k in LAST_ROW}
            for model in ("macro", "micro")
            if (out / f"nx{nx}" / model / "summary.csv").is_file()
        }
        for nx in nxs
    }  # fmt: skip
    return {
        "exit_code": code,  # not 0: the Nx whose compare failed has no row (run.log says why)
        "scene": shown,
        "feedback_walls": walls or "the scene's",
        "command": shlex.join(["plantgrowth", *command]),
        "wall_seconds": round(wall, 1),
        "cpu_seconds": round(cpu, 1),
        "rows": rows,
        "last_summary_rows": last,
        "fitted_rates": rates(rows, FIRST_STEP + AT_TMAX) if len(rows) > 1 else {},
    }


def single_cell(
    nx: int = 8, delta: float = 1.0, resolution: int | None = None, walls: str = "around"
) -> dict:
    """The micro feedback's response to one turned director, elastic only (Fg = I, one step of
    dt = 1): ``feedback_a90``'s tissue at Nx with every director at 90 degrees but the cell
    nearest the tissue's middle at 90 + delta. Each director's turn over the step minus its
    turn when all are at 90 (the boundary's own cue), per degree of delta and unit rate k:
    the turned cell's (> 0: it turns further, the uniform director is unstable) and its six
    neighbours'. ``walls``: the cue's ``feedback.walls``."""
    data = tomllib.loads(
        (ROOT / "scenes" / "compare" / f"{SCENES['feedback_a90']}.toml").read_text()
    )
    data["model"] = "micro"
    data["micro"]["nx"] = nx
    data["feedback"]["walls"] = walls
    if resolution is not None:  # else the scene's
        data["micro"]["resolution"] = resolution
    scene = parse_scene(data)
    model = MicroModel(scene, MPI.COMM_WORLD)
    centres = model.layout.centres
    middle = int(np.argmin(np.linalg.norm(centres - centres.mean(axis=0), axis=1)))
    near = np.argsort(np.linalg.norm(centres - centres[middle], axis=1))[:7]
    turned = []
    for extra in (0.0, delta):
        angle = np.full(model.layout.n_cells, 90.0)
        angle[middle] += extra
        model.director.restore(angle)
        model.step(model.initial_growth())
        model.end_step(1.0)
        turned.append(fibres.reduce_angle(model.director.angle - angle))
    response = (turned[1] - turned[0])[near] / (delta * scene.feedback.rate)
    return {
        "nx": nx, "resolution": scene.micro_resolution, "walls": walls, "delta_degrees": delta,
        "rate_k": scene.feedback.rate, "cell": middle, "centre": centres[middle].tolist(),
        "turn_per_degree_per_k": round(float(response[0]), 5),
        "neighbours_turn_per_degree_per_k": [round(float(r), 5) for r in response[1:]],
    }  # fmt: skip


def macro_patch(radius: float = 0.45, delta: float = 1.0) -> dict:
    """The homogenized model's response to a turned patch, elastic only (Fg = I, one step of
    dt = 1): ``feedback_a90``'s scene as a macro run with every director at 90 degrees but in the
    disc of ``radius`` around the tissue's middle (3.464, 1.5), at 90 + delta (radius 0.45: the
    area of one cell at Nx = 8, 0.65). Each fine cell's turn over the step minus its turn when
    all are at 90, per degree of delta and unit rate k, over the disc's fine cells (mean, least,
    largest), to set beside :func:`single_cell`'s."""
    data = tomllib.loads(
        (ROOT / "scenes" / "compare" / f"{SCENES['feedback_a90']}.toml").read_text()
    )
    disc = f"((x1 - 3.464)**2 + (x2 - 1.5)**2 < {radius * radius!r})"
    turned = []
    for extra in (0.0, delta):
        data["walls"]["fibre_angle"] = {"expr": f"90 + {extra!r} * {disc}"}
        scene = parse_scene(data)
        model = macro_model(scene, MPI.COMM_WORLD)
        angle = model.director.angle.copy()
        model.step(model.initial_growth())
        model.end_step(1.0)
        turned.append(fibres.reduce_angle(model.director.angle - angle))
    inside = fibres.reduce_angle(angle - 90.0) > 0.5 * delta
    response = (turned[1] - turned[0])[inside] / (delta * scene.feedback.rate)
    response = np.concatenate(MPI.COMM_WORLD.allgather(response))  # this rank's fine cells
    return {
        "radius": radius, "delta_degrees": delta, "rate_k": scene.feedback.rate,
        "fine_cells": len(response),
        "turn_per_degree_per_k": {k: round(float(f(response)), 5) for k, f in
                                  (("mean", np.mean), ("least", np.min), ("largest", np.max))},
    }  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    results = json.loads(args.json.read_text()) if args.json.is_file() else {"cases": {}}
    results["machine"] = machine_description()
    results["study_command"] = shlex.join(
        ["nice", "-n", "19", "python", "scripts/studies/compare_fibres.py", *(argv or sys.argv[1:])]
    )
    failed = []
    if "single_cell" in args.only:
        key = "single_cell" if args.walls is None else f"single_cell_{args.walls}"
        results[key] = single_cell(walls=args.walls or "around")
        print(f"{key}: {results[key]}", flush=True)
        write_results(results, args.json)
    if "macro_patch" in args.only:
        results["macro_patch"] = macro_patch()
        print(f"macro_patch: {results['macro_patch']}", flush=True)
        write_results(results, args.json)
    for name in (n for n in args.only if n in SCENES):
        nxs = args.nx if name == "first_step" else args.feedback_nx
        walls = None if name == "first_step" else args.walls
        key = name if walls is None else f"{name}_{walls}"
        print(f"{key}: Nx = {nxs}", flush=True)
        entry = results["cases"][key] = run_case(name, nxs, args.raw, walls)
        print(f"{name}: {entry['wall_seconds']} s wall, rates {entry['fitted_rates']}", flush=True)
        failed += [name] if entry["exit_code"] != 0 else []
        write_results(results, args.json)  # after each case: a later failure keeps it
    print(f"-> {args.json}; failed: {failed or 0}")
    return 1 if failed else 0


def write_results(results: dict, path: Path) -> None:
    """The JSON, cases sorted by name."""
    results["notes"] = (
        "One compare at a time, serial, nice -n 19, on the shared machine: seconds are upper "
        "bounds. Errors are compare.csv's (docs/outputs.md); the _tmax ones at the last step "
        "(t = 60), err_fibre_angle_tmax the cells' RMS director difference in degrees. "
        "fitted_rates: least-squares p of e ~ delta^p over the case's Nx. last_summary_rows: "
        "each run's last summary.csv row (fibre_order, fibre_angle_mean the director the step "
        "used). single_cell: the micro feedback's response to one turned director "
        "(single_cell's docstring in the script); macro_patch: the homogenized model's "
        "response to a turned patch of one such cell's size (macro_patch's docstring). Keys "
        "ending _around or _own: the feedback cases with that feedback.walls (the micro cue "
        "over the walls around each cell, or over its own halves). study_command: the last "
        "invocation; with --only it rewrites only the cases it names."
    )
    results["cases"] = dict(sorted(results["cases"].items()))
    path.write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    sys.exit(main())
