"""Cost and accuracy of stress feedback on the fibred gradient scene (issue 33, item 2).

Scene: ``scenes/gradient_E_strain.toml`` at ``balanced`` (61 steps) with ``[walls]
fibre_stiffness = 5, fibre_angle = 90`` and ``[feedback] cue = "stress", rate = 0.5``, against
the same scene without ``[walls]`` (unfibred). Whole ``plantgrowth run`` processes, cell cache
off, one rank, alternated unfibred / feedback (/ the ``--base`` checkout's feedback run)
``--repeats`` times: median CPU seconds (user + sys of the child) and the median of the pairs'
CPU ratios. Then one feedback run each on the exact path (``cell_tolerance = 0``: one cell
problem per coarse node and step, the directors projected to the nodes) and with
``cell_tolerance = --reference-tolerance`` (the surrogate ten times tighter, each fine cell
answered at its own Fg and director), and their cell solves, t = 60 measures and the largest
error of the runs' exact self-checks; and the cell solves of the fibred scene without feedback
(the fixed director), of this checkout and of ``--base``. With ``--free-solves``, a third kind
alternates with the two: the feedback run with a cell cache that one untimed run filled with
every lattice value the scene asks (``feedback_cached``: no cell problem solved but the exact
self-checks', so its CPU is the floor any cheaper cell solver could reach). Writes
``benchmarks/results/feedback_cost.json`` with the machine and the load.

    python scripts/benchmarks/bench_feedback_cost.py [--repeats 3] \\
        [--base /work/main/.venv/bin/plantgrowth] [--reference-tolerance 1e-4] [--free-solves]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import tomllib
from collections.abc import Mapping
from pathlib import Path

from bench_fibre_cost import scene_text

from plantgrowth.base.machine import machine_description
from plantgrowth.scene.toml_text import dict_to_toml

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/feedback_cost.json"
MEASURES = ("area", "u1_max", "u2_max", "growth_rate_area", "fibre_order", "fibre_angle_mean")
CHECK = re.compile(r"largest so far ([0-9.e+-]+)")


def feedback_text(tolerance: float | None = None) -> str:
    """The fibred feedback scene at ``balanced``, its cell tolerance replaced if given."""
    data = tomllib.loads(scene_text(True, feedback=True))
    if tolerance is not None:
        data["accuracy"]["cell_tolerance"] = tolerance
    return dict_to_toml(data)


def run(
    exe: str, text: str, cache: str = "off", env: Mapping[str, str] | None = None,
    measures: tuple[str, ...] = MEASURES,
) -> dict:  # fmt: skip
    """One whole run of the scene text (cell cache ``cache``, a directory or "off"; the process
    environment ``env``, by default this one's): CPU seconds, cell solves summed over the
    steps, the last row's ``measures`` and the largest error of its exact self-checks
    (run.log)."""
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "scene.toml").write_text(text)
        env = dict(os.environ if env is None else env) | {"PLANTGROWTH_CACHE_DIR": cache}
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        subprocess.run([exe, "run", f"{tmp}/scene.toml", "-o", f"{tmp}/o", "-q"], check=True,
                       capture_output=True, env=env)  # fmt: skip
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        with open(Path(tmp) / "o/summary.csv", newline="") as f:
            rows = list(csv.DictReader(f))
        checks = [float(x) for x in CHECK.findall((Path(tmp) / "o/run.log").read_text())]
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"cpu": cpu, "cell_solves": sum(int(float(r["n_cell_solves"])) for r in rows),
            "largest_checked_error": max(checks, default=None)} | {
        m: float(rows[-1][m]) for m in measures if m in rows[-1]
    }  # fmt: skip


def relative(run_: dict, against: dict) -> dict:
    """Relative differences of the t = 60 measures."""
    return {m: (run_[m] - against[m]) / abs(against[m]) for m in MEASURES if m in against}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--base", help="another checkout's plantgrowth (its feedback run too)")
    parser.add_argument("--reference-tolerance", type=float, default=1e-4)
    parser.add_argument("--free-solves", action="store_true",
                        help="also the feedback run from a filled cell cache")  # fmt: skip
    args = parser.parse_args(argv)
    exe = str(Path(sys.executable).with_name("plantgrowth"))
    result: dict = {"machine": machine_description(), "load_before": os.getloadavg(),
                    "scene": "scenes/gradient_E_strain.toml", "preset": "balanced",
                    "cache": "off, feedback_cached: filled" if args.free_solves else "off",
                    "base": args.base}  # fmt: skip
    kinds = {"unfibred": (exe, scene_text(False), "off"), "feedback": (exe, feedback_text(), "off")}
    if args.base:
        kinds["feedback_base"] = (args.base, feedback_text(), "off")
    filled = tempfile.TemporaryDirectory()
    if args.free_solves:
        kinds["feedback_cached"] = (exe, feedback_text(), filled.name)
        run(exe, feedback_text(), filled.name)  # untimed: fills the cache
    runs: dict[str, list[dict]] = {name: [] for name in kinds}
    for _ in range(args.repeats):
        for name, (program, text, cache) in kinds.items():
            runs[name].append(run(program, text, cache))
            print(name, json.dumps(runs[name][-1]), flush=True)
    filled.cleanup()
    result["runs"] = runs
    result["cpu_median"] = {k: statistics.median(r["cpu"] for r in v) for k, v in runs.items()}
    result["cpu_ratio_median"] = {
        name: statistics.median(
            r["cpu"] / p["cpu"] for p, r in zip(runs["unfibred"], runs[name], strict=True)
        )
        for name in kinds if name != "unfibred"
    }  # fmt: skip
    result["fixed_director"] = {  # the fibred scene without feedback: its cell solves only
        name: run(program, scene_text(True))["cell_solves"]
        for name, program in (("this", exe), ("base", args.base)) if program
    }  # fmt: skip
    exact = run(exe, feedback_text(0.0))
    reference = run(exe, feedback_text(args.reference_tolerance))
    result["exact_path"], result["reference"] = exact, reference
    result["reference_tolerance"] = args.reference_tolerance
    if args.free_solves:  # the cached values are the solved ones: the same answers (expected 0)
        result["feedback_cached"] = {"cell_solves": runs["feedback_cached"][-1]["cell_solves"],
                                     "vs_feedback": relative(runs["feedback_cached"][-1],
                                                               runs["feedback"][-1])}  # fmt: skip
    for name in runs:
        last = runs[name][-1]
        if name not in ("unfibred", "feedback_cached"):
            result[name] = {
                "cell_solves": last["cell_solves"],
                "fraction_of_exact": last["cell_solves"] / exact["cell_solves"],
                "vs_reference": relative(last, reference), "vs_exact_path": relative(last, exact),
            }  # fmt: skip
    result["load_after"] = os.getloadavg()
    print(json.dumps({k: result[k] for k in ("cpu_median", "cpu_ratio_median")}), flush=True)
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
