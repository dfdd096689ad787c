"""The scaling study's tissue per step: LU against CG + BoomerAMG, 1 and 2 ranks, against the
reference scene (issue 33: the 1e5-dof tissue at most 30x the reference scene per step, 1 -> 2
ranks at least 1.8x per step).

Whole ``plantgrowth run`` processes of this checkout (cell cache off): for each tissue size
(``--dofs``, the tissue of scripts/benchmarks/scaling.py, gradient_E_strain scaled, to
``--t-max``) and rank count, every ``solver.macro`` of ``--macro`` in turn, interleaved with a
1-rank run of ``scenes/reference_stress.toml``, ``--repeats`` times. Per run: CPU (``getrusage``
of the children, all ranks), wall, step 0's phases (cold start: factorization or hierarchy,
surrogate filled) and the median over steps 1..n of summary.csv's ``seconds_*`` columns (the
wall of a step on rank 0), the CG iterations of each step (run.log). Per size and rank count:
the medians over the repeats, the largest relative difference of each solver's summary columns
from the first solver's (``max |a - b| / max |b|`` over the steps), and the per-step ratios to
the reference scene (the repeats' medians) and 2 ranks to 1, with the load average and the
speed-up two processes of a fixed numpy task get on the machine before and after each repeat
(``two_core_speedup``: 2 on two free cores; the ceiling of a 2-rank run's speed-up); over the
sizes, the fine dofs where iterative's per-step time (whole step, and solve alone) meets
direct's (``crossover``: what sets ``solver.macro_threshold``).

    python scripts/benchmarks/bench_tissue_solver.py [--dofs 1e5 5e4 2e5] [--ranks 1 2]
        [--macro direct iterative] [--repeats 3] [--t-max 10] [--kinematics finite] [--label NAME]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import statistics
import subprocess
import sys
import tomllib
from pathlib import Path

from phase_timings import PHASES, whole_run
from scaling import scaled_scene

from plantgrowth.base.machine import machine_description
from plantgrowth.scene.toml_text import dict_to_toml

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/tissue_solver.json"
REFERENCE = ROOT / "scenes/reference_stress.toml"
EXE = str(Path(sys.executable).with_name("plantgrowth"))
COMPARED = (
    "area", "growth_rate_11", "growth_rate_22", "growth_rate_area", "u1_max", "u2_max",
    "elastic_strain_max",
)  # fmt: skip
"""Summary columns compared between the solvers (their physics, not their seconds)."""
PROBE = """import time, numpy as np
a = np.random.default_rng(0).standard_normal((200000, 2, 2)); a = a + a.transpose(0, 2, 1)
start = time.perf_counter()
for _ in range(10):
    np.linalg.eigh(a)
print(time.perf_counter() - start)"""
"""A fixed compute-bound task (numpy's batched eigh, as the growth law's) timed in a process."""


def two_core_speedup() -> float:
    """The speed-up the machine gives two processes now: twice the probe's time alone over the
    longer of two probes started together (2: two free cores; 1: one core's worth left)."""

    def probes(n: int) -> list[float]:
        started = [subprocess.Popen([sys.executable, "-c", PROBE], stdout=subprocess.PIPE,
                                    text=True) for _ in range(n)]  # fmt: skip
        return [float(p.communicate()[0]) for p in started]

    return 2 * probes(1)[0] / max(probes(2))


def run_once(text: str, ranks: int) -> dict:
    """One whole run: CPU, wall, step 0's phases, the medians over steps 1..n, CG iterations,
    and the summary's compared columns at every step."""
    cpu, wall, rows, log = whole_run(EXE, text, ranks)
    later = rows[1:] or rows
    return {
        "cpu": cpu, "wall": wall, "steps": len(rows),
        "startup": wall - sum(r["seconds"] for r in rows),
        "step0": {p: rows[0][p] for p in PHASES},
        "per_step": {p: statistics.median(r[p] for r in later) for p in PHASES},
        "cg_iterations": [int(k) for k in re.findall(r"macro solve: (\d+) CG iterations", log)],
        "solver": re.search(r"macro solver: (.+?) \(", log)[1],
        "fine_dofs": int(re.search(r"macro: (\d+) fine dofs", log)[1]),
        "summary": {c: [r[c] for r in rows] for c in COMPARED},
    }  # fmt: skip


def medians(runs: list[dict]) -> dict:
    """Medians over the repeats (deterministic entries: the last run's)."""
    out = {k: statistics.median(r[k] for r in runs) for k in ("cpu", "wall", "startup")}
    for table in ("step0", "per_step"):
        out[table] = {p: statistics.median(r[table][p] for r in runs) for p in PHASES}
    last = runs[-1]
    keep = ("steps", "cg_iterations", "solver", "fine_dofs", "summary")
    return out | {k: last[k] for k in keep} | {"walls": [r["wall"] for r in runs]}


def difference(a: dict, b: dict) -> dict:
    """Largest relative difference of every compared column, over the steps, of a from b."""
    out = {}
    for c in COMPARED:
        x, y = a["summary"][c], b["summary"][c]
        scale = max(abs(v) for v in y) or 1.0
        out[c] = max(abs(p - q) for p, q in zip(x, y, strict=True)) / scale
    return out


def crossover(runs: dict, ranks: int, phase: str) -> float | None:
    """Fine dofs where iterative's per-step ``phase`` meets direct's, on ``ranks`` ranks (log-log
    interpolation between the measured sizes; None: no crossing among them)."""
    points = sorted(
        (e["direct"]["fine_dofs"], math.log(e["iterative"]["per_step"][phase]
                                            / e["direct"]["per_step"][phase]))
        for key, e in runs.items() if key.endswith(f"ranks={ranks}") and "direct" in e
        and "iterative" in e
    )  # fmt: skip
    for (n0, d0), (n1, d1) in zip(points, points[1:], strict=False):
        if d0 > 0 >= d1:
            return math.exp(math.log(n0) + d0 / (d0 - d1) * (math.log(n1) - math.log(n0)))
    return None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--dofs", type=float, nargs="+", default=[1e5])
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--macro", nargs="+", default=["direct", "iterative"])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--t-max", type=float, default=10.0)
    parser.add_argument("--kinematics", choices=["linear", "finite"], default="linear")
    parser.add_argument("--label", default="now")
    args = parser.parse_args(argv)
    result = json.loads(OUT.read_text()) if OUT.is_file() else {}
    record = {
        "machine": machine_description(), "load_before": os.getloadavg(),
        "command": " ".join(sys.argv), "repeats": args.repeats, "t_max": args.t_max,
        "kinematics": args.kinematics, "runs": {},
    }  # fmt: skip
    reference_text = dict_to_toml(tomllib.loads(REFERENCE.read_text()))
    run_once(reference_text, 1)  # warm-up: dolfinx's JIT cache, file caches
    reference = []
    for dofs in args.dofs:
        scenes = {m: scaled_scene(dofs, args.t_max, {"macro": m}) for m in args.macro}
        texts = {m: dict_to_toml(d | {"kinematics": args.kinematics}) for m, d in scenes.items()}
        for ranks in args.ranks:
            runs: dict[str, list[dict]] = {m: [] for m in args.macro}
            loads, probes = [os.getloadavg()], [two_core_speedup()]
            for _ in range(args.repeats):
                for m, text in texts.items():
                    runs[m].append(run_once(text, ranks))
                reference.append(run_once(reference_text, 1))
                loads.append(os.getloadavg())
                probes.append(two_core_speedup())
            entry = {m: medians(r) for m, r in runs.items()}
            first = entry[args.macro[0]]
            for m in args.macro[1:]:
                entry[m]["difference_from_" + args.macro[0]] = difference(entry[m], first)
            entry["load_averages"], entry["two_core_speedup"] = loads, probes
            record["runs"][f"{dofs:g} ranks={ranks}"] = entry
            brief = {m: (v["per_step"]["seconds"], v["step0"]["seconds"], v["cpu"],
                         v["cg_iterations"]) for m, v in entry.items() if m in texts}  # fmt: skip
            print(f"{dofs:g} ranks={ranks}", json.dumps(brief), loads[-1], probes, flush=True)
    record["reference"] = medians(reference)
    per_ref = record["reference"]["per_step"]["seconds"]
    ratios, speedups = {}, {}
    for key, entry in record["runs"].items():
        for m in args.macro:
            ratios[f"{key} {m}"] = entry[m]["per_step"]["seconds"] / per_ref
            if key.endswith("ranks=2") and key.replace("ranks=2", "ranks=1") in record["runs"]:
                one = record["runs"][key.replace("ranks=2", "ranks=1")][m]
                speedups[f"{key[:-8]} {m}"] = one["per_step"]["seconds"] / entry[m]["per_step"][
                    "seconds"
                ]
    crossings = {f"ranks={r} {p}": crossover(record["runs"], r, p) for r in args.ranks
                 for p in ("seconds", "seconds_solve")}  # fmt: skip
    record |= {"ratio_to_reference": ratios, "speedup_1_to_2": speedups, "crossover": crossings}
    record["load_after"] = os.getloadavg()
    print(json.dumps({"ratios": ratios, "speedups": speedups, "reference": per_ref,
                      "crossover": crossings}, indent=1))  # fmt: skip
    result[args.label] = record
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
