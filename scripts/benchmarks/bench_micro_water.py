"""Cost of the micro model's water fluxes (issue 35: a hydraulic scene at ``balanced`` costs at
most 2x the same scene with turgor given): the same micro scene (stress law, preset
``balanced``) run with ``P1 = Pi + psi_0`` given and with ``[hydraulics]`` (osmotic Pi, initial
potential psi_0, every edge supplied at psi_0), side by side on one machine, at each Nx and
kinematics.

Runs ``plantgrowth run`` as whole processes, given then water, ``repeats`` times interleaved per
case; records summary.csv's per-step seconds, seconds_solve and Newton iterations (step 0, the
initial equilibrium, apart: it solves the given turgor either way), the medians of the seconds
over the later steps of all repeats and the ratio water / given of those medians (finite
kinematics: also per Newton iteration), with the machine and the load average at the start and
the end. Writes ``benchmarks/results/micro_water_cost.json``.

    python scripts/benchmarks/bench_micro_water.py [--nx 8 16] [--steps 3]
        [--kinematics linear finite] [--repeats 3]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from plantgrowth.base.machine import machine_description
from plantgrowth.scene.toml_text import dict_to_toml

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/micro_water_cost.json"
PI, PSI0 = 0.0012, -0.0002
"""Osmotic pressure and initial water potential: turgor Pi + psi_0 = 0.001 in both scenes."""


def scene(nx: int, steps: int, kinematics: str, water: bool) -> dict:
    """The micro scene with the turgor given (``water`` False) or from the water."""
    data = {"model": "micro", "kinematics": kinematics, "growth": {"law": "stress"},
            "time": {"t_max": float(steps), "dt": 1.0}, "micro": {"nx": nx},
            "accuracy": {"preset": "balanced"}}  # fmt: skip
    if not water:
        return data | {"pressure": {"P1": PI + PSI0}}
    supply = [{"edge": e, "conductance": 1.0, "potential": PSI0} for e in ("left", "right", "top")]
    hydraulics = {"osmotic": PI, "conductivity": 1.0, "initial_potential": PSI0, "supply": supply}
    return data | {"hydraulics": hydraulics}


def step_rows(data: dict) -> dict[str, list[float]] | dict[str, int | str]:
    """summary.csv's seconds, seconds_solve and (finite kinematics) newton_iterations of each
    step of one ``plantgrowth run`` of the scene data; a failed run: its exit status and the
    end of its stderr."""
    exe = Path(sys.executable).with_name("plantgrowth")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "scene.toml"
        path.write_text(dict_to_toml(data))
        env = os.environ | {"PLANTGROWTH_CACHE_DIR": "off"}
        done = subprocess.run([exe, "run", str(path), "-o", f"{tmp}/o"], capture_output=True,
                              text=True, env=env)  # fmt: skip
        if done.returncode != 0:
            return {"failed": done.returncode, "stderr": done.stderr[-2000:]}
        with open(Path(tmp) / "o/summary.csv", newline="") as f:
            rows = list(csv.DictReader(f))
    keys = [k for k in ("seconds", "seconds_solve", "newton_iterations") if k in rows[0]]
    return {k: [float(row[k]) for row in rows] for k in keys}


def case(nx: int, steps: int, kinematics: str, repeats: int) -> dict:
    """Given and water runs of one case, interleaved (given, water, given, ...) ``repeats``
    times: each run's per-step columns, the medians over the repeats' steps 1.. (the water
    steps) of the seconds and the ratio water / given of those medians, and each repeat's
    ratio; with Newton, also the ratio of the medians of the seconds per Newton iteration and
    the Newton iterations of steps 1.. of every run."""
    runs: dict[str, list] = {"given": [], "water": []}
    for _ in range(repeats):
        for name, water in (("given", False), ("water", True)):
            rows = step_rows(scene(nx, steps, kinematics, water))
            print(nx, kinematics, name, rows, flush=True)
            if "failed" in rows:
                return {name: rows}
            runs[name].append(rows)
    out = {}
    for name, rows in runs.items():
        later = [t for r in rows for t in r["seconds"][1:]]
        out[name] = {"runs": rows, "median_seconds": statistics.median(later)}
        if "newton_iterations" in rows[0]:
            per = [t / k for r in rows for t, k in
                   zip(r["seconds"][1:], r["newton_iterations"][1:], strict=True)]  # fmt: skip
            out[name]["median_seconds_per_iteration"] = statistics.median(per)
            out[name]["newton_iterations"] = [r["newton_iterations"][1:] for r in rows]
    out["ratio"] = out["water"]["median_seconds"] / out["given"]["median_seconds"]
    out["ratios"] = [
        statistics.median(w["seconds"][1:]) / statistics.median(g["seconds"][1:])
        for g, w in zip(runs["given"], runs["water"], strict=True)
    ]  # fmt: skip
    if "median_seconds_per_iteration" in out["water"]:
        out["ratio_per_iteration"] = (out["water"]["median_seconds_per_iteration"]
                                      / out["given"]["median_seconds_per_iteration"])  # fmt: skip
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--nx", type=int, nargs="+", default=[8, 16])
    parser.add_argument("--steps", type=int, default=3)
    parser.add_argument("--kinematics", nargs="+", default=["linear", "finite"])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    cases, load = {}, os.getloadavg()  # at the start and (below) at the end
    for kinematics in args.kinematics:
        for nx in args.nx:
            cases[f"{kinematics}_nx{nx}"] = case(nx, args.steps, kinematics, args.repeats)
            print(kinematics, nx, "ratio", cases[f"{kinematics}_nx{nx}"].get("ratio"))
    result = {"machine": machine_description(), "load_average": [load, os.getloadavg()],
              "steps": args.steps, "repeats": args.repeats, "cases": cases}  # fmt: skip
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
