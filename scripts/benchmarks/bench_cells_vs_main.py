"""Per-cell tensors against the coarse grid (issue 20, item 4): cost and accuracy of each preset
on ``gradient_E_strain`` (t = 60), or on the soft disc's first step (``--scene soft_disc``, the
accuracy check's run), for this checkout and another (today's main), side by side.

Runs ``plantgrowth run`` of both checkouts as whole processes (imports included, the cell cache
off) in turn, A B A B ..., per preset; records the median CPU and wall seconds, the ratio A/B of
the CPU seconds pair by pair, and the final u1_max, u2_max and area of each (the runs are
deterministic), with the machine and the load average. ``--base`` is the other checkout's
``plantgrowth`` (a venv of its own, e.g. ``git worktree add /tmp/base a1fecfd`` installed into
``/tmp/basevenv``). Writes ``benchmarks/results/cells_vs_main.json``.

    python scripts/benchmarks/bench_cells_vs_main.py --base /tmp/basevenv/bin/plantgrowth \\
        [--repeats 3] [--presets draft balanced fine] [--scene gradient_E_strain|soft_disc]
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

from plantgrowth.base.machine import machine_description
from plantgrowth.scene.toml_text import dict_to_toml

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/cells_vs_main.json"
SCENES = {
    "gradient_E_strain": (ROOT / "scenes/gradient_E_strain.toml", None),
    "soft_disc": (ROOT / "scenes/examples/soft_disc.toml", {"t_max": 1.0, "dt": 1.0}),
}
"""Name: (scene, time table replacing the scene's, or None). Results go under ``presets`` for
gradient_E_strain (as before the soft disc was added) and ``presets_<name>`` otherwise."""
MEASURES = ("u1_max", "u2_max", "area")


def run_rows(exe: str, scene_text: str) -> tuple[float, float, list[dict]]:
    """CPU and wall seconds of one whole run of the scene text (cache off), and the rows of
    its summary.csv."""
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / "scene.toml"
        scene.write_text(scene_text)
        env = os.environ | {"PLANTGROWTH_CACHE_DIR": "off"}
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        subprocess.run([exe, "run", str(scene), "-o", f"{tmp}/o"], check=True,
                       capture_output=True, env=env)  # fmt: skip
        wall = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        with open(Path(tmp) / "o/summary.csv", newline="") as f:
            rows = list(csv.DictReader(f))
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall, rows


def timed_run(exe: str, scene_text: str) -> dict:
    """CPU and wall seconds of one run of the scene text (cache off), and its final measures."""
    cpu, wall, rows = run_rows(exe, scene_text)
    return {"cpu": cpu, "wall": wall} | {m: float(rows[-1][m]) for m in MEASURES}


def preset_text(scene: str, preset: str, base: bool = False) -> str:
    """The scene as shipped, with ``accuracy.preset`` set (and its time table replaced). For the
    base checkout the ``[numerics]`` table is dropped: main knew no ``on_instability``."""
    path, time_table = SCENES[scene]
    data = tomllib.loads(path.read_text())
    data.setdefault("accuracy", {})["preset"] = preset
    if time_table is not None:
        data["time"] = time_table
    if base:
        data.pop("numerics", None)
    return dict_to_toml(data)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--base", required=True, help="the other checkout's plantgrowth")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--presets", nargs="+", default=["draft", "balanced", "fine"])
    parser.add_argument("--scene", choices=sorted(SCENES), default="gradient_E_strain")
    args = parser.parse_args(argv)
    this = str(Path(sys.executable).with_name("plantgrowth"))
    result = json.loads(OUT.read_text()) if OUT.is_file() else {}
    key = "presets" if args.scene == "gradient_E_strain" else f"presets_{args.scene}"
    result.setdefault(key, {})
    result |= {"machine": machine_description(), "load_before": os.getloadavg(),
               "base": args.base, "cache": "off"}  # fmt: skip
    timed_run(this, preset_text(args.scene, "draft"))  # warm-up: JIT and file caches of both
    timed_run(args.base, preset_text(args.scene, "draft", base=True))
    for preset in args.presets:
        text, base_text = preset_text(args.scene, preset), preset_text(args.scene, preset, True)
        runs: dict[str, list[dict]] = {"cells": [], "base": []}
        for _ in range(args.repeats):
            runs["cells"].append(timed_run(this, text))
            runs["base"].append(timed_run(args.base, base_text))
        ratios = [a["cpu"] / b["cpu"] for a, b in zip(runs["cells"], runs["base"], strict=True)]
        record = {"repeats": args.repeats, "cpu_ratio_median": statistics.median(ratios),
                  "cpu_ratios": ratios}  # fmt: skip
        for side, rows in runs.items():
            record[side] = {k: statistics.median(r[k] for r in rows) for k in ("cpu", "wall")}
            record[side] |= {m: rows[-1][m] for m in MEASURES}
        result[key][preset] = record
        print(preset, json.dumps(record), flush=True)
        result["load_after"] = os.getloadavg()
        OUT.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
