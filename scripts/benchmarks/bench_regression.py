"""Issue 33's cost regression: whole ``plantgrowth run`` processes of several checkouts side by
side (the accuracy-cost map of 783f8bd took 1.14-1.85x the CPU seconds of 140cbc5's map).

Runs each scene at one preset (cell cache off, every run pays for its own cell solves) with
this checkout's ``plantgrowth`` and with each ``--exe NAME=PATH`` (another checkout's, in a
venv of its own), interleaved: A B C A B C ...; records per scene and checkout the medians of
the CPU and wall seconds, the cell solves (summary.csv's ``n_cell_solves`` summed, as
scripts/studies/accuracy_cost.py counts them), the phase table (the sums of summary.csv's
``seconds_*`` columns, as phase_timings.py), the final u1_max, u2_max and area, and the CPU
ratios to every other checkout pair by pair, with the machine and the load average. Results go
under ``--label`` (e.g. ``before`` / ``after`` a fix) of ``benchmarks/results/regression.json``.

    python scripts/benchmarks/bench_regression.py --exe 140cbc5=/tmp/venv-140/bin/plantgrowth \\
        --exe 7c43f7c=/tmp/venv-7c4/bin/plantgrowth --label after [--repeats 5] \\
        [--scenes gradient_E_strain reference_stress] [--preset balanced]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tomllib
from pathlib import Path

from bench_cells_vs_main import MEASURES, run_rows

from plantgrowth.base.machine import machine_description
from plantgrowth.scene.toml_text import dict_to_toml

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/regression.json"


def scene_text(name: str, preset: str) -> str:
    """This checkout's scene ``scenes/<name>.toml`` with ``accuracy.preset`` set (the shipped
    gradient and reference scenes read the same in 140cbc5, 7c43f7c and main)."""
    data = tomllib.loads((ROOT / f"scenes/{name}.toml").read_text())
    data.setdefault("accuracy", {})["preset"] = preset
    return dict_to_toml(data)


def run_once(exe: str, text: str) -> dict:
    """CPU and wall seconds of one whole run of the scene text, its cell solves, phase totals
    and final measures."""
    cpu, wall, rows = run_rows(exe, text)
    phases = {k: sum(float(r[k]) for r in rows) for k in rows[0] if k.startswith("seconds")}
    return {
        "cpu": cpu, "wall": wall, "steps": len(rows),
        "cell_solves": sum(int(float(r["n_cell_solves"])) for r in rows),
        "solves_per_step": [int(float(r["n_cell_solves"])) for r in rows],
        "phases": phases, "startup_seconds": wall - phases["seconds"],
    } | {m: float(rows[-1][m]) for m in MEASURES}  # fmt: skip


def summarize(runs: list[dict]) -> dict:
    """Medians of the repeated runs (the solves and measures are deterministic: the last)."""
    out = {k: statistics.median(r[k] for r in runs) for k in ("cpu", "wall", "startup_seconds")}
    out["phases"] = {k: statistics.median(r["phases"][k] for r in runs) for k in runs[0]["phases"]}
    return out | {k: runs[-1][k] for k in ("cell_solves", "solves_per_step", "steps", *MEASURES)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--exe", action="append", default=[], help="NAME=PATH of a plantgrowth")
    parser.add_argument("--this", default="this", help="the name of this checkout's run")
    parser.add_argument("--label", default="after")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--scenes", nargs="+", default=["gradient_E_strain", "reference_stress"])
    parser.add_argument("--preset", default="balanced")
    args = parser.parse_args(argv)
    exes = {args.this: str(Path(sys.executable).with_name("plantgrowth"))}
    exes |= dict(e.split("=", 1) for e in args.exe)
    result = json.loads(OUT.read_text()) if OUT.is_file() else {}
    record = {"machine": machine_description(), "load_before": os.getloadavg(), "exes": exes,
              "preset": args.preset, "repeats": args.repeats, "scenes": {}}  # fmt: skip
    for name in args.scenes:
        text = scene_text(name, args.preset)
        for exe in exes.values():  # warm-up: JIT and file caches
            run_once(exe, text)
        runs: dict[str, list[dict]] = {k: [] for k in exes}
        for _ in range(args.repeats):
            for key, exe in exes.items():
                runs[key].append(run_once(exe, text))
        scene = {k: summarize(v) for k, v in runs.items()}
        for a in exes:
            scene[a]["cpu_ratio_to"] = {
                b: statistics.median(
                    x["cpu"] / y["cpu"] for x, y in zip(runs[a], runs[b], strict=True)
                )
                for b in exes if b != a
            }  # fmt: skip
        record["scenes"][name] = scene
        print(name, json.dumps({k: {m: v[m] for m in ("cpu", "wall", "cell_solves")}
                                for k, v in scene.items()}), flush=True)  # fmt: skip
    record["load_after"] = os.getloadavg()
    result[args.label] = record
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
