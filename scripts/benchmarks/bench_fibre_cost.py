"""Cost of fibre-reinforced walls (issue 22): a fibred gradient scene against the same scene
without fibres, and the surrogate's cell solves against the exact path's.

Scene: ``scenes/gradient_E_strain.toml`` at ``balanced`` (61 steps), fibred with
``[walls] fibre_stiffness = 5, fibre_angle = 90``. Whole ``plantgrowth run`` processes of this
checkout, the cell cache off, alternated plain / fibred (``--repeats`` pairs); records the
median CPU seconds and the median of the pairs' CPU ratios. Then one run each of the fibred
scene, the fibred scene with ``[feedback] cue = "stress", rate = 0.5``, and both on the exact
path (``accuracy.cell_tolerance = 0``), counting the cell solves (``n_cell_solves`` summed
over the steps). Writes ``benchmarks/results/fibre_cost.json`` with the machine and the load.

    python scripts/benchmarks/bench_fibre_cost.py [--repeats 5]
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
import tomllib
from pathlib import Path

from bench_cells_vs_main import timed_run

from plantgrowth.base.machine import machine_description
from plantgrowth.scene.toml_text import dict_to_toml

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/fibre_cost.json"
SCENE = ROOT / "scenes/gradient_E_strain.toml"
FIBRES = {"fibre_stiffness": 5.0, "fibre_angle": 90.0}
FEEDBACK = {"cue": "stress", "rate": 0.5}


def scene_text(fibres: bool, feedback: bool = False, exact: bool = False) -> str:
    """The gradient scene at ``balanced``, with fibres, feedback, the exact cell path."""
    data = tomllib.loads(SCENE.read_text())
    data.setdefault("accuracy", {})["preset"] = "balanced"
    if fibres:
        data["walls"] = dict(FIBRES)
    if feedback:
        data["feedback"] = dict(FEEDBACK)
    if exact:
        data["accuracy"]["cell_tolerance"] = 0.0
    return dict_to_toml(data)


def cell_solves(exe: str, text: str) -> dict:
    """One run (cache off): its cell solves summed over the steps, and its last fibre_order."""
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "scene.toml").write_text(text)
        env = os.environ | {"PLANTGROWTH_CACHE_DIR": "off"}
        subprocess.run([exe, "run", f"{tmp}/scene.toml", "-o", f"{tmp}/o", "-q"], check=True,
                       capture_output=True, env=env)  # fmt: skip
        with open(Path(tmp) / "o/summary.csv", newline="") as f:
            rows = list(csv.DictReader(f))
    solves = sum(int(float(r["n_cell_solves"])) for r in rows)
    return {"cell_solves": solves, "fibre_order": float(rows[-1].get("fibre_order", "nan"))}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    exe = str(Path(sys.executable).with_name("plantgrowth"))
    result = {"machine": machine_description(), "load_before": os.getloadavg(),
              "scene": str(SCENE.relative_to(ROOT)), "preset": "balanced", "cache": "off",
              "fibres": FIBRES, "feedback": FEEDBACK}  # fmt: skip
    plain, fibred = scene_text(False), scene_text(True)
    timed_run(exe, plain)  # warm-up: the JIT and file caches
    runs: dict[str, list[dict]] = {"plain": [], "fibred": []}
    for _ in range(args.repeats):
        runs["plain"].append(timed_run(exe, plain))
        runs["fibred"].append(timed_run(exe, fibred))
    ratios = [f["cpu"] / p["cpu"] for p, f in zip(runs["plain"], runs["fibred"], strict=True)]
    result["cpu_seconds"] = {k: [r["cpu"] for r in v] for k, v in runs.items()}
    result["cpu_median"] = {k: statistics.median(r["cpu"] for r in v) for k, v in runs.items()}
    result["cpu_ratios"] = ratios
    result["cpu_ratio_median"] = statistics.median(ratios)
    print(json.dumps({k: result[k] for k in ("cpu_median", "cpu_ratio_median")}), flush=True)
    counts = {
        "fibred": cell_solves(exe, fibred),
        "fibred_exact": cell_solves(exe, scene_text(True, exact=True)),
        "feedback": cell_solves(exe, scene_text(True, feedback=True)),
        "feedback_exact": cell_solves(exe, scene_text(True, feedback=True, exact=True)),
    }
    for name in ("fibred", "feedback"):
        counts[name]["fraction_of_exact"] = (
            counts[name]["cell_solves"] / counts[f"{name}_exact"]["cell_solves"]
        )
    result["solves"] = counts
    result["load_after"] = os.getloadavg()
    print(json.dumps(counts), flush=True)
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
