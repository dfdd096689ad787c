"""Time per phase of the coupled macro run (cell problems, macro solve, growth, I/O), of this
checkout and of others side by side (issue 33, item 3: the phase tables before and after).

A scene is a scene file, or ``tissue:DOFS``: the scaling study's tissue (gradient_E_strain
scaled to about DOFS fine dofs, scripts/benchmarks/scaling.py) with ``--t-max``. Two kinds of
record, under ``--label`` in ``benchmarks/results/phase_timings.json`` with the machine and the
load average:

- ``runs``: per scene and rank count (``--ranks``), whole ``plantgrowth run`` processes (cell
  cache off) of this checkout and of each ``--exe NAME=PATH``, interleaved A B A B ...,
  ``--repeats`` times: the medians of the CPU seconds (all ranks, ``getrusage`` of the children),
  the wall seconds, the start-up (wall minus the steps), summary.csv's ``seconds_*`` columns
  summed over the steps and averaged over steps 1..n (step 0 also fills the surrogate and
  factorizes), and the CPU ratio to every other checkout (median of the pairs);
- ``profile`` (``--profile``): one run of this checkout per scene on one rank (and on each of
  ``--profile-ranks``: every rank's profile, key ``SCENE ranks=R``), in this process's child
  under cProfile with a CPU clock (``time.process_time``): CPU seconds of the imports, the set-up,
  every phase of the steps (cells, solve, growth: the rest of the step; output: fields, state,
  summary rows; measures; the integrator) and the functions with the most own time.
  cProfile's own overhead inflates Python-heavy phases: compare profiles with profiles.

    python scripts/benchmarks/phase_timings.py [SCENE ...] [--exe 7c43f7c=/tmp/v/bin/plantgrowth]
        [--ranks 1 2] [--repeats 5] [--t-max 5] [--profile] [--label after]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

from scaling import ENV, scaled_scene

from plantgrowth.base.machine import machine_description
from plantgrowth.scene.toml_text import dict_to_toml

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/phase_timings.json"
PHASES = ("seconds", "seconds_cells", "seconds_solve", "seconds_growth", "seconds_io")
DEFAULT = ["scenes/reference_stress.toml", "scenes/gradient_E_strain.toml"]
PROFILED = {
    "run_model": "plantgrowth.runner.timeloop:run_model",
    "step": "plantgrowth.models.macro.model:MacroModel.step",
    "cells": "plantgrowth.models.macro.model:MacroModel.cell_tensors",
    "solve": "plantgrowth.models.macro.model:MacroModel._solve",
    "measures": "plantgrowth.models.macro.model:MacroModel.measures",
    "output_fields": "plantgrowth.runner.output:FieldSeries.write",
    "output_state": "plantgrowth.runner.output:StateFile.write",
    "output_summary": "plantgrowth.runner.output:SummaryWriter.write_rows",
    "model_state": "plantgrowth.models.macro.model:MacroModel.state",
    "integrator": "plantgrowth.runner.timeloop:_advance",
}
"""Phase -> the function whose cumulative CPU time it is (the profile's rows)."""
CHILD = r"""
import cProfile, importlib, json, os, pstats, sys, time
out, profiled, argv = sys.argv[1], json.loads(sys.argv[2]), sys.argv[3:]
out += os.environ.get("OMPI_COMM_WORLD_RANK", "")  # under mpirun: one file per rank
profile = cProfile.Profile(time.process_time)
profile.enable()
from plantgrowth.cli import main
main(argv)
profile.disable()
total = time.process_time()
stats = pstats.Stats(profile).stats
def code(path):
    module, name = path.split(":")
    obj = importlib.import_module(module)
    for part in name.split("."):
        obj = getattr(obj, part)
    c = obj.__code__
    return (c.co_filename, c.co_firstlineno, c.co_name)
cum = {k: v[3] for k, v in stats.items()}
phases = {p: cum.get(code(f), 0.0) for p, f in profiled.items()}
phases["imports"] = sum(v[3] for k, v in stats.items() if k[2] == "_find_and_load"
                        and "importlib" in k[0])
top = sorted(stats.items(), key=lambda kv: -kv[1][2])[:25]
top = [[f"{os.path.relpath(k[0]) if k[0].startswith('/') else k[0]}:{k[1]}({k[2]})", v[0],
        round(v[2], 4), round(v[3], 4)] for k, v in top]
json.dump({"process_cpu": total, "phases": phases, "top_own_time": top}, open(out, "w"))
"""


def scene_text(scene: str, t_max: float) -> str:
    """The scene's TOML: a file as it is, ``tissue:DOFS`` the scaling study's tissue."""
    if scene.startswith("tissue:"):
        return dict_to_toml(scaled_scene(float(scene[7:]), t_max, {"macro": "auto"}))
    return dict_to_toml(tomllib.loads((ROOT / scene).read_text()))


def whole_run(exe: str, text: str, ranks: int) -> tuple[float, float, list[dict], str]:
    """One whole run on ``ranks`` ranks: its CPU and wall seconds, summary rows and run.log."""
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / "scene.toml"
        scene.write_text(text)
        mpirun = ["mpirun", "-n", str(ranks)] if ranks > 1 else []
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        subprocess.run([*mpirun, exe, "run", str(scene), "-o", f"{tmp}/o"], check=True,
                       capture_output=True, env=os.environ | ENV)  # fmt: skip
        wall = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        with open(Path(tmp) / "o/summary.csv", newline="") as f:
            rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
        log = (Path(tmp) / "o/run.log").read_text()
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall, rows, log


def run_once(exe: str, text: str, ranks: int) -> dict:
    """CPU and wall seconds of one whole run on ``ranks`` ranks and its phase table."""
    cpu, wall, rows, _ = whole_run(exe, text, ranks)
    totals = {p: sum(r[p] for r in rows) for p in PHASES}
    later = rows[1:] or rows
    per_step = {p: statistics.fmean(r[p] for r in later) for p in PHASES}
    return {"cpu": cpu, "wall": wall, "startup": wall - totals["seconds"], "steps": len(rows),
            "totals": totals, "per_step": per_step,
            "cell_solves": sum(int(r["n_cell_solves"]) for r in rows)}  # fmt: skip


def median_record(runs: list[dict]) -> dict:
    """Medians over the repeats (steps and cell solves are deterministic: the last run's)."""
    out = {k: statistics.median(r[k] for r in runs) for k in ("cpu", "wall", "startup")}
    for table in ("totals", "per_step"):
        out[table] = {p: statistics.median(r[table][p] for r in runs) for p in PHASES}
    return out | {k: runs[-1][k] for k in ("steps", "cell_solves")}


def compare(text: str, ranks: int, exes: dict[str, str], repeats: int, warm: bool) -> dict:
    """Interleaved repeats of every checkout (after one warm-up run each if ``warm``): medians,
    ratios."""
    for exe in exes.values() if warm else ():
        run_once(exe, text, ranks)
    runs: dict[str, list[dict]] = {k: [] for k in exes}
    for _ in range(repeats):
        for key, exe in exes.items():
            runs[key].append(run_once(exe, text, ranks))
    record = {k: median_record(v) for k, v in runs.items()}
    for a in exes:
        record[a]["cpu_ratio_to"] = {
            b: statistics.median(x["cpu"] / y["cpu"] for x, y in zip(runs[a], runs[b], strict=True))
            for b in exes if b != a
        }  # fmt: skip
    return record


def profile(text: str, ranks: int = 1) -> dict:
    """One run of this checkout under cProfile with a CPU clock (see the module); on more than
    one rank (``mpirun``) each rank's profile, under ``per_rank`` (CPU time includes MPI's busy
    waiting: compare functions that do not communicate)."""
    with tempfile.TemporaryDirectory() as tmp:
        scene, out = Path(tmp) / "scene.toml", Path(tmp) / "profile.json"
        scene.write_text(text)
        argv = ["-q", "run", str(scene), "-o", f"{tmp}/o"]
        mpirun = ["mpirun", "-n", str(ranks)] if ranks > 1 else []
        command = [*mpirun, sys.executable, "-c", CHILD, str(out), json.dumps(PROFILED), *argv]
        subprocess.run(command, check=True, capture_output=True, env=os.environ | ENV, cwd=tmp)
        names = [out.name] if ranks == 1 else [f"{out.name}{r}" for r in range(ranks)]
        results = [json.loads((out.parent / name).read_text()) for name in names]
    for result in results:
        p = result["phases"]
        p["growth"] = p["step"] - p["cells"] - p["solve"]
        p["startup"] = result["process_cpu"] - p["run_model"]  # imports (some lazy), set-up
    return results[0] if ranks == 1 else {"per_rank": results}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenes", nargs="*", default=DEFAULT)
    parser.add_argument("--exe", action="append", default=[], help="NAME=PATH of a plantgrowth")
    parser.add_argument("--this", default="this", help="the name of this checkout's runs")
    parser.add_argument("--ranks", type=int, nargs="+", default=[1])
    parser.add_argument("--repeats", type=int, default=3, help="0: the profile only")
    parser.add_argument(
        "--no-warmup",
        dest="warmup",
        action="store_false",
        help="no warm-up run (JIT and file caches) before the repeats",
    )
    parser.add_argument("--t-max", type=float, default=5.0, help="of the tissue:DOFS scenes")
    parser.add_argument("--profile", action="store_true", help="also a cProfile run per scene")
    parser.add_argument("--profile-ranks", type=int, nargs="+", default=[1], help="its ranks")
    parser.add_argument("--label", default="after")
    args = parser.parse_args(argv)
    exes = {args.this: str(Path(sys.executable).with_name("plantgrowth"))}
    exes |= dict(e.split("=", 1) for e in args.exe)
    result = json.loads(OUT.read_text()) if OUT.is_file() else {}
    record = result.get(args.label, {}) | {
        "machine": machine_description(), "load_before": os.getloadavg(), "exes": exes,
        "repeats": args.repeats, "command": " ".join(sys.argv),
    }  # fmt: skip
    for scene in args.scenes:
        text = scene_text(scene, args.t_max)
        for ranks in args.ranks if args.repeats else ():
            key = f"{scene} ranks={ranks}"
            runs = compare(text, ranks, exes, args.repeats, args.warmup)
            record.setdefault("runs", {})[key] = runs
            brief = {
                k: {m: round(v[m], 3) for m in ("cpu", "wall", "startup")}
                | {"per_step": round(v["per_step"]["seconds"], 4)}
                for k, v in runs.items()
            }
            print(key, json.dumps(brief), flush=True)  # fmt: skip
        for ranks in args.profile_ranks if args.profile else ():
            key = scene if ranks == 1 else f"{scene} ranks={ranks}"
            record.setdefault("profile", {})[key] = prof = profile(text, ranks)
            for part in prof.get("per_rank", [prof]):
                phases = {k: round(v, 3) for k, v in part["phases"].items()}
                print(key, "profile", json.dumps(phases), flush=True)
    record["load_after"] = os.getloadavg()
    result[args.label] = record
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
