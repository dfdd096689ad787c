"""The adaptive integrator with water fluxes against small fixed steps (issue 35; docs/model.md,
"Water fluxes", "The adaptive integrator").

For each model (macro, micro) and kinematics (linear, finite), the scene of
tests/test_adaptive_water.py (an edge and a region supplied, one drying from t = 1 to 2) runs
to ``--t-max`` (default 2) with ``integrator = "adaptive"`` at dt = 1 and ``--tolerance``
(default 1e-4), and with ``"exp"`` at dt = 1/8 and 1/16. Written per case: the adaptive run's
kept sub-steps, the largest relative difference of area, water, turgor and each supply's
inflow (the exp runs' inflows averaged over each unit step, as the adaptive step's are)
against each exp run, the exp runs' own difference, and the largest
``|water_balance_error| / water``; to ``--json`` (default
``benchmarks/results/adaptive_water.json``) with the machine description.

    nice -n 19 python scripts/studies/adaptive_water.py [--only macro_finite]
"""

from __future__ import annotations

import argparse
import csv
import json
import tempfile
from pathlib import Path

from plantgrowth.base.machine import machine_description
from plantgrowth.cli import main as plantgrowth
from plantgrowth.scene.toml_text import dict_to_toml

ROOT = Path(__file__).resolve().parents[2]
RAMP = {"times": [0.0, 1.0, 2.0], "values": [0.0, 0.0, -5e-4], "interpolation": "linear"}
MODELS = {
    "macro": {
        "tissue": {"width": 3.0, "height": 1.5, "h": 0.35, "H": 1.0},
        "accuracy": {"cell_resolution": 1, "cell_tolerance": 0.0},
        "regions": {"far": {"expr": "x1 > 2.5"}},
        "hydraulics": {"osmotic": 0.001, "conductivity": 50.0, "supply": [
            {"edge": "left", "conductance": 1000.0},
            {"region": "far", "conductance": 1.0, "potential": RAMP}]},
    },
    "micro": {
        "micro": {"nx": 4, "resolution": 1},
        "regions": {"strand": {"expr": "x1 > 5"}},
        "hydraulics": {"osmotic": 0.001, "conductivity": 5.0, "supply": [
            {"edge": "left", "conductance": 2.0, "potential": RAMP},
            {"region": "strand", "conductance": 0.5, "potential": 0.0005}]},
    },
}  # fmt: skip
CASES = [f"{model}_{kinematics}" for model in MODELS for kinematics in ("linear", "finite")]
FINE = (8, 16)
"""The exp runs' steps per unit time."""


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add = parser.add_argument
    add("--only", nargs="+", choices=CASES, default=CASES, help="cases to (re)run")
    add("--t-max", type=float, default=2.0)
    add("--tolerance", type=float, default=1e-4, help="the adaptive runs' time.tolerance")
    add("--json", type=Path, default=ROOT / "benchmarks/results/adaptive_water.json")
    return parser.parse_args(argv)


def run(data: dict, directory: Path, name: str) -> list[dict[str, float]]:
    """``plantgrowth run`` of scene data; its summary rows."""
    scene, outdir = directory / f"{name}.toml", directory / name
    scene.write_text(dict_to_toml(data))
    if plantgrowth(["run", str(scene), "-o", str(outdir), "--quiet"]) != 0:
        raise SystemExit(f"{name}: the run failed")
    with open(outdir / "summary.csv", newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def unit_steps(rows: list[dict[str, float]], n: int) -> list[dict[str, float]]:
    """Every n-th row, its inflows the means over the n rows up to it."""
    out = [rows[0]]
    for k in range(n, len(rows), n):
        part = rows[k - n + 1 : k + 1]
        out.append(rows[k] | {c: sum(r[c] for r in part) / n for c in rows[k] if "inflow." in c})
    return out


def differences(a: list[dict], b: list[dict]) -> dict[str, float]:
    """Largest relative difference per column (area, water: of the value; turgor and inflows:
    of the column's largest value in b)."""
    columns = ["area", "water", "turgor_mean"] + [c for c in a[0] if c.startswith("inflow.")]
    out = {}
    for c in columns:
        scale = {"area": None, "water": None}.get(c, max(abs(r[c]) for r in b))
        out[c] = max(abs(x[c] - y[c]) / (scale or abs(y[c])) for x, y in zip(a, b, strict=True))
    return out


def case(name: str, args: argparse.Namespace, directory: Path) -> dict:
    model, kinematics = name.split("_")
    data = MODELS[model] | {"model": model, "kinematics": kinematics,
                            "growth": {"law": "stress"}}  # fmt: skip
    time = {"t_max": args.t_max, "dt": 1.0}
    adaptive = run(data | {"time": time | {"integrator": "adaptive",
                                           "tolerance": args.tolerance}}, directory, name)
    exp = {n: unit_steps(run(data | {"time": time | {"dt": 1.0 / n, "integrator": "exp"}},
                                     directory, f"{name}_exp{n}"), n) for n in FINE}  # fmt: skip
    return {
        "substeps": [int(r["substeps"]) for r in adaptive],
        "balance": max(abs(r["water_balance_error"]) / r["water"] for r in adaptive),
        **{f"adaptive_vs_exp_dt_1/{n}": differences(adaptive, exp[n]) for n in FINE},
        f"exp_dt_1/{FINE[0]}_vs_1/{FINE[1]}": differences(exp[FINE[0]], exp[FINE[1]]),
    }


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    results = json.loads(args.json.read_text()) if args.json.is_file() else {"cases": {}}
    results |= {"t_max": args.t_max, "tolerance": args.tolerance, "machine": machine_description()}
    with tempfile.TemporaryDirectory() as directory:
        for name in args.only:
            results["cases"][name] = case(name, args, Path(directory))
            print(name, json.dumps(results["cases"][name]))
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(results, indent=2) + "\n")
    print(f"-> {args.json}")


if __name__ == "__main__":
    main()
