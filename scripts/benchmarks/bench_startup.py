"""Whole-process time of ``plantgrowth run scenes/reference_stress.toml`` against a baseline
checkout (issue 23: at most 0.6x the baseline's, measured side by side), and the start-up of
the light commands.

Each sample is one ``plantgrowth run`` process into a new output directory, this checkout (A)
and the baseline (B) in turn, A B A B ..., so that a drift of the shared machine's speed hits
both alike; the ratio is taken pair by pair and its median reported. Two cache settings:
``PLANTGROWTH_CACHE_DIR`` as the user has it by default (unset: ``~/.cache/plantgrowth``, warmed
by one run of each side first) and ``off`` (every run solves its cell problems). dolfinx's JIT
cache stays as it is (warmed by the same first runs). Each sample's phases: the process start
to the first line of run.log (imports, MPI_Init, scene, mesh), the logged set-up, the steps
(summary.csv's ``seconds``, split into cells, solve, growth, output) and the rest.

Per command (``--version``, ``--help``, ``validate``, ``run``): the median whole-process time
and the import time (``python -X importtime``, the top-level modules summed) of each side.

Writes ``benchmarks/results/startup.json`` with the machine and the load average (1 min) before,
after and at each sample: the machine is shared, run it when the load is lowest.

    python scripts/benchmarks/bench_startup.py --baseline /tmp/base29 \
        --baseline-python /tmp/base29venv/bin/python [--repeats 5]
"""

from __future__ import annotations

import argparse
import csv
import datetime
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from plantgrowth.base.machine import machine_description

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/startup.json"
SCENE = "scenes/reference_stress.toml"
STEP_COLUMNS = ("seconds", "seconds_cells", "seconds_solve", "seconds_growth", "seconds_io")
LIGHT = {"--version": ["--version"], "--help": ["--help"], "validate": ["validate", SCENE]}


def environment(cache: str) -> dict[str, str]:
    """The process environment: the user's cache (``"default"``) or none (``"off"``)."""
    env = {k: v for k, v in os.environ.items() if k != "PLANTGROWTH_CACHE_DIR"}
    return env | ({"PLANTGROWTH_CACHE_DIR": "off"} if cache == "off" else {})


def log_times(path: Path) -> tuple[float, float, float]:
    """(first line, last line, logged set-up seconds) of a run.log, as epoch seconds."""
    stamps, setup = [], 0.0
    for line in path.read_text().splitlines():
        when = datetime.datetime.strptime(line[:23], "%Y-%m-%d %H:%M:%S,%f")
        stamps.append(when.timestamp())
        if match := re.search(r" set-up: ([0-9.]+) s$", line):
            setup = float(match[1])
    return stamps[0], stamps[-1], setup


def timed_run(python: Path, root: Path, cache: str) -> dict[str, float]:
    """One whole ``plantgrowth run`` of the reference scene of checkout ``root``: its wall
    seconds and phases."""
    with tempfile.TemporaryDirectory() as tmp:
        command = [python.with_name("plantgrowth"), "run", root / SCENE, "-o", f"{tmp}/out"]
        load = os.getloadavg()[0]
        start = time.time()
        subprocess.run(command, check=True, capture_output=True, env=environment(cache))
        end = time.time()
        first, last, setup = log_times(Path(tmp) / "out/run.log")
        with open(Path(tmp) / "out/summary.csv", newline="") as f:
            rows = list(csv.DictReader(f))
    steps = {k: sum(float(r[k]) for r in rows) for k in STEP_COLUMNS if k in rows[0]}
    return {"wall": end - start, "to_first_log_line": first - start, "setup": setup,
            **{f"steps_{k}": v for k, v in steps.items()},
            "after_last_log_line": end - last, "load": load}  # fmt: skip


def import_seconds(python: Path, root: Path, argv: list, env: dict) -> tuple[float, float]:
    """(whole-process wall seconds, import seconds) of ``plantgrowth argv`` under
    ``python -X importtime`` (the import time of the top-level modules, summed)."""
    start = time.perf_counter()
    done = subprocess.run([python, "-X", "importtime", python.with_name("plantgrowth"), *argv],
                          capture_output=True, text=True, env=env, cwd=root)  # fmt: skip
    wall = time.perf_counter() - start
    total = sum(int(m[1]) for m in re.finditer(r"import time:\s+\d+ \|\s+(\d+) \| \S", done.stderr))
    return wall, total * 1e-6


def command_times(sides: dict, repeats: int) -> dict:
    """Median whole-process and import seconds of each light command and of ``run`` (cache as
    the user has it), each side in turn."""
    samples: dict = {}
    for _ in range(repeats):
        for name, argv in [*LIGHT.items(), ("run", None)]:
            for side, (python, root) in sides.items():
                with tempfile.TemporaryDirectory() as tmp:
                    args = argv or ["run", SCENE, "-o", f"{tmp}/out"]
                    wall, imports = import_seconds(python, root, args, environment("default"))
                samples.setdefault(name, {}).setdefault(side, []).append((wall, imports))
    return {
        name: {side: {"wall_seconds": statistics.median(s[0] for s in pairs),
                      "import_seconds": statistics.median(s[1] for s in pairs)}
               for side, pairs in by_side.items()}
        for name, by_side in samples.items()
    }  # fmt: skip


def compare_runs(sides: dict, cache: str, repeats: int) -> dict:
    """A B A B ... whole runs of the reference scene: per side the median of every phase, and
    the median of the pairwise wall ratios A / B."""
    for python, root in sides.values():  # warm-up: JIT cache, file cache, cell cache
        timed_run(python, root, cache)
    samples: dict[str, list] = {side: [] for side in sides}
    for _ in range(repeats):
        for side, (python, root) in sides.items():
            samples[side].append(timed_run(python, root, cache))
    ratios = [a["wall"] / b["wall"] for a, b in zip(*samples.values(), strict=True)]
    out = {side: {k: statistics.median(s[k] for s in runs) for k in runs[0]}
           for side, runs in samples.items()}  # fmt: skip
    return out | {"wall_ratios": ratios, "wall_ratio_median": statistics.median(ratios),
                  "samples": samples}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", type=Path, required=True, help="the baseline checkout")
    parser.add_argument("--baseline-python", type=Path, required=True,
                        help="the python of a venv with the baseline installed")  # fmt: skip
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    baseline_commit = subprocess.run(["git", "-C", args.baseline, "rev-parse", "HEAD"],
                                     capture_output=True, text=True).stdout.strip()  # fmt: skip
    commit = subprocess.run(["git", "-C", ROOT, "rev-parse", "HEAD"], capture_output=True,
                            text=True).stdout.strip()  # fmt: skip
    sides = {"this": (Path(sys.executable), ROOT),
             "baseline": (args.baseline_python, args.baseline.resolve())}  # fmt: skip
    result = {"machine": machine_description(), "load_before": os.getloadavg(),
              "commit": commit, "baseline_commit": baseline_commit, "repeats": args.repeats,
              "scene": SCENE}  # fmt: skip
    for cache in ("default", "off"):
        result[f"run_cache_{cache}"] = compare_runs(sides, cache, args.repeats)
        print(f"cache {cache}: ratio {result[f'run_cache_{cache}']['wall_ratio_median']:.3f}")
    result["commands"] = command_times(sides, args.repeats)
    result["load_after"] = os.getloadavg()
    OUT.write_text(json.dumps(result, indent=1))
    print(json.dumps(result["commands"], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
