"""Cost of the macro model's water fluxes (issue 35: a hydraulic scene at ``balanced`` costs at
most 2x the same scene with turgor given): each hydraulic macro scene run with its
``[hydraulics]`` (water) and with the hydraulics replaced by the turgor they reach when the water
is fast, ``P1 = Pi + psi_s`` (given), side by side on one machine.

Scenes: ``scenes/biology/apex_fed_from_below.toml`` (a supplied region), ``drought.toml`` (three
supplied edges; psi_s falls at t = 20, after the runs here end) and ``homogeneous``,
``scenes/reference_stress.toml`` with its P1 = 0.001 made by the water (osmotic 0.001, the
three outer edges supplied at psi_s = 0, walls and edges conducting freely). Both versions
keep the scene's other tables (``[regions]``: their statistics) and output the fields they
share (u, Fg, G, trG; the water's P, psi, water_flux are not written), at preset ``balanced``,
``time.t_max`` = steps.

Runs ``plantgrowth run`` as whole processes (imports and set-up included), the cell cache off,
interleaved: every repeat runs each scene's two versions in turn, the order alternating between
repeats (water first, then given first), so a drift of the machine's load hits both alike.
Records each run's wall seconds and summary.csv's per-step seconds and seconds_solve, the
medians over the repeats of the wall seconds and of each run's median per-step seconds (steps
1.., step 0 being the initial equilibrium), the ratios water / given of those medians and the
range of the ratios pair by pair (one repeat's water run over its given run), with the load
average before each run. Writes ``benchmarks/results/macro_water_cost.json``.

    python scripts/benchmarks/bench_macro_water.py [--repeats 3] [--steps 10] [--scenes ...]
        [--out FILE]
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
import time
import tomllib
from pathlib import Path

from plantgrowth.base.machine import machine_description
from plantgrowth.scene.toml_text import dict_to_toml

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/macro_water_cost.json"
FIELDS = ["u", "Fg", "G", "trG"]
"""The output fields both versions write."""
HOMOGENEOUS = {
    "osmotic": 0.001,
    "conductivity": 1e4,
    "supply": [{"edge": e, "conductance": 1e3, "potential": 0.0} for e in ("left", "right", "top")],
}
"""The reference scene's water: turgor 0.001 = its P1 everywhere, reached fast."""


def scene_files() -> dict[str, dict]:
    """The hydraulic scenes by name, as TOML data."""
    scenes = {}
    for name in ("apex_fed_from_below", "drought"):
        scenes[name] = tomllib.loads((ROOT / f"scenes/biology/{name}.toml").read_text())
    reference = tomllib.loads((ROOT / "scenes/reference_stress.toml").read_text())
    del reference["pressure"]
    scenes["homogeneous"] = reference | {"hydraulics": HOMOGENEOUS}
    return scenes


def given_turgor(water: dict) -> float:
    """``Pi + psi_s`` at t = 0 of a ``[hydraulics]`` with a constant Pi and one supply
    potential (every supply's at t = 0 the same; default 0)."""
    potentials = set()
    for supply in water["supply"]:
        potential = supply.get("potential", 0.0)
        potentials.add(potential["values"][0] if isinstance(potential, dict) else potential)
    if len(potentials) != 1:
        raise ValueError(f"supplies at different potentials: {sorted(potentials)}")
    return water["osmotic"] + potentials.pop()


def version(data: dict, steps: int, water: bool) -> dict:
    """The scene at ``balanced`` over ``steps`` steps, with its water or with the turgor
    given."""
    common = {"time": data["time"] | {"t_max": float(steps)},
              "output": {"fields": FIELDS}, "accuracy": {"preset": "balanced"}}  # fmt: skip
    if water:
        return data | common
    given = {k: v for k, v in data.items() if k != "hydraulics"}
    return given | common | {"pressure": {"P1": given_turgor(data["hydraulics"])}}


def run(data: dict) -> dict:
    """One ``plantgrowth run`` of the scene data: its wall seconds, the load average before it,
    summary.csv's per-step seconds and seconds_solve; a failed run: its exit status and the end
    of its stderr."""
    exe = Path(sys.executable).with_name("plantgrowth")
    load = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="plantgrowth-bench-water-") as tmp:
        path = Path(tmp) / "scene.toml"
        path.write_text(dict_to_toml(data))
        env = os.environ | {"PLANTGROWTH_CACHE_DIR": "off"}
        start = time.perf_counter()
        done = subprocess.run([exe, "run", str(path), "-o", f"{tmp}/o"], capture_output=True,
                              text=True, env=env)  # fmt: skip
        wall = time.perf_counter() - start
        if done.returncode != 0:
            return {"failed": done.returncode, "stderr": done.stderr[-2000:]}
        with open(Path(tmp) / "o/summary.csv", newline="") as f:
            rows = list(csv.DictReader(f))
    out = {"wall_seconds": wall, "load_average_1_5_15": list(load)}
    out |= {k: [float(row[k]) for row in rows] for k in ("seconds", "seconds_solve")}
    out["median_step_seconds"] = statistics.median(out["seconds"][1:])
    return out


def spread(values: list[float]) -> dict[str, float]:
    """Median, min and max."""
    return {"median": statistics.median(values), "min": min(values), "max": max(values)}


def summary(runs: dict[str, list[dict]]) -> dict:
    """Medians of one scene's water and given runs, their ratios and the pair-by-pair ratios'
    spread (None where a run failed)."""
    if any("failed" in r for rs in runs.values() for r in rs):
        return {"failed": True}
    out = {}
    for key in ("wall_seconds", "median_step_seconds"):
        water = [r[key] for r in runs["water"]]
        given = [r[key] for r in runs["given"]]
        out[key] = {"water": spread(water), "given": spread(given)}
        out[key]["ratio_of_medians"] = statistics.median(water) / statistics.median(given)
        out[key]["ratio_pairs"] = spread([w / g for w, g in zip(water, given, strict=True)])
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--steps", type=int, default=10)
    parser.add_argument("--scenes", nargs="+", default=None, help="default: all three")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    scenes = scene_files()
    names = args.scenes or list(scenes)
    runs = {name: {"water": [], "given": []} for name in names}
    for repeat in range(args.repeats):
        order = (True, False) if repeat % 2 == 0 else (False, True)
        for name in names:
            for water in order:
                result = run(version(scenes[name], args.steps, water))
                runs[name]["water" if water else "given"].append(result)
                print(repeat, name, "water" if water else "given",
                      {k: result.get(k) for k in ("wall_seconds", "median_step_seconds",
                                                  "failed", "stderr")}, flush=True)  # fmt: skip
    cases = {name: {"summary": summary(runs[name]), "runs": runs[name]} for name in names}
    result = {
        "description": "hydraulic macro scenes at balanced: water (u and P solved) against the "
        "same scene with turgor given (P1 = Pi + psi_s), whole plantgrowth run processes",
        "command": "python " + " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        "timing_notes": "interleaved repeats (order alternating), PLANTGROWTH_CACHE_DIR=off; "
        "wall_seconds: the whole process; median_step_seconds: a run's median of summary.csv's "
        "seconds over steps 1..; ratio_pairs: each repeat's water run over its given run",
        "target": "ratio at most 2 (issue 35)",
        "steps": args.steps,
        "repeats": args.repeats,
        "cases": cases,
        "load_average_1_5_15_end": list(os.getloadavg()),
        "machine": machine_description(),
    }
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    for name in names:
        s = cases[name]["summary"]
        if "failed" not in s:
            print(name, {k: round(s[k]["ratio_of_medians"], 3) for k in s})
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
