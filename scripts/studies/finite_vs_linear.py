"""Linear versus finite kinematics (docs/model.md section 10, issue 12) on the shipped scenes.

Runs every chosen scene twice, ``kinematics = "linear"`` and ``"finite"`` (everything else
as the scene says, or with ``--preset``), in this process, one run at a time, and writes per
scene: the relative differences of the mean growth rate tr G and of the area at every step
next to the growth ratio area(t) / area(0), the wall-time ratio finite / linear, Newton's
iterations, and for each run the time reached, the cause of a stop (the RunError message) and
the largest elastic strain (eps_el or Ee) over the run. Gradient scenes: ``scenes/gradient_*``;
hard cases: ``scenes/hard`` (``--hard``). Results: ``benchmarks/results/finite_vs_linear.json``
(merged with what is there); run directories under ``results/finite_vs_linear/``.

    python scripts/studies/finite_vs_linear.py [--only gradient_E_strain,...] [--hard]
        [--preset draft] [--t-max 60]
"""

from __future__ import annotations

import argparse
import csv
import json
import logging
import time
import tomllib
from pathlib import Path

import numpy as np
from mpi4py import MPI

import plantgrowth as pg
from plantgrowth.base.machine import machine_description
from plantgrowth.models import growth
from plantgrowth.models.macro.model import MacroModel, macro_model
from plantgrowth.models.step import largest_strain
from plantgrowth.runner.output import prepare_directory
from plantgrowth.runner.timeloop import run_model

log = logging.getLogger("plantgrowth")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", type=lambda s: s.split(","), default=None, help="scene names")
    parser.add_argument("--hard", action="store_true", help="the hard cases (scenes/hard)")
    parser.add_argument("--preset", default=None, help="override accuracy.preset (e.g. draft)")
    parser.add_argument("--t-max", type=float, default=None, help="override time.t_max")
    parser.add_argument("--out", type=Path, default=Path("results/finite_vs_linear"))
    parser.add_argument(
        "--json", type=Path, default=Path("benchmarks/results/finite_vs_linear.json")
    )
    return parser.parse_args(argv)


def scene_files(hard: bool, only: list[str] | None) -> list[Path]:
    files = sorted(
        Path("scenes/hard").glob("*.toml") if hard else Path("scenes").glob("gradient_*.toml")
    )
    return [f for f in files if only is None or f.stem in only]


def variant(
    path: Path, kinematics: str, preset: str | None, t_max: float | None, extra: dict | None = None
) -> pg.Scene:
    """The scene of ``path`` with the given kinematics (and preset / t_max overrides, and the
    top-level tables of ``extra``)."""
    data = tomllib.loads(path.read_text(encoding="utf-8")) | (extra or {})
    data["kinematics"] = kinematics
    if preset is not None:
        data.setdefault("accuracy", {})["preset"] = preset
        for key in ("h", "H"):
            data.get("tissue", {}).pop(key, None)
        data.get("time", {}).pop("dt", None)
    if t_max is not None:
        data.setdefault("time", {})["t_max"] = t_max
    return pg.Scene.from_dict(data, directory=path.parent)


def run(scene: pg.Scene, outdir: Path) -> dict:
    """One macro run: its summary rows, the time reached, the cause of a stop, the largest
    elastic strain over the steps run, the wall time."""
    comm = MPI.COMM_WORLD
    prepare_directory(outdir, comm)
    largest = [0.0]

    def strain(step: int, model: MacroModel) -> None:
        p = model.problem
        n = p.n_owned
        Fg = p.cell_values(p.Fg).reshape(-1, 2, 2)[:n]
        kinematics = growth.green_lagrange_strain if p.finite else growth.elastic_strain
        eps = kinematics(p.grad_u()[:n], Fg)
        largest[0] = max(largest[0], largest_strain(eps, comm))

    start = time.perf_counter()
    model = macro_model(scene, comm)
    cause, rows = "", []
    try:
        rows = run_model(model, scene, outdir, comm, on_step=strain)
    except pg.RunError as err:
        cause = str(err)
        rows = _read_rows(outdir / "summary.csv")
    return {
        "rows": rows,
        "t_reached": rows[-1]["t"] if rows else 0.0,
        "cause": cause,
        "max_elastic_strain": largest[0],
        "seconds": time.perf_counter() - start,
    }


def _read_rows(path: Path) -> list[dict[str, float]]:
    with open(path, newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def compare(linear: dict, finite: dict) -> dict:
    """Per common step: relative differences of tr G and area, and the growth ratio."""
    n = min(len(linear["rows"]), len(finite["rows"]))
    out = {"t": [], "growth_ratio": [], "rel_diff_growth_rate": [], "rel_diff_area": []}
    area0 = linear["rows"][0]["area"] if n else 1.0
    for a, b in zip(linear["rows"][:n], finite["rows"][:n], strict=True):
        out["t"].append(a["t"])
        out["growth_ratio"].append(a["area"] / area0)
        rate = a["growth_rate_area"]
        out["rel_diff_growth_rate"].append(
            abs(b["growth_rate_area"] - rate) / max(abs(rate), 1e-300)
        )
        out["rel_diff_area"].append(abs(b["area"] - a["area"]) / a["area"])
    return out


def summary(name: str, linear: dict, finite: dict) -> dict:
    diff = compare(linear, finite)
    newton = [r.get("newton_iterations", 0) for r in finite["rows"]]
    steps = lambda r: max(len(r["rows"]), 1)  # noqa: E731
    return {
        "scene": name,
        "differences": diff,
        "cost_ratio_per_step": (finite["seconds"] / steps(finite))
        / (linear["seconds"] / steps(linear)),
        "newton_iterations": {
            "mean": float(np.mean(newton)) if newton else 0.0,
            "max": max(newton, default=0),
        },
        **{
            kin: {k: r[k] for k in ("t_reached", "cause", "max_elastic_strain", "seconds")}
            for kin, r in (("linear", linear), ("finite", finite))
        },
    }


def line(result: dict) -> str:
    """One progress line: differences at the second and last common steps, cost, stops."""
    d = result["differences"]
    last = len(d["t"]) - 1
    first = min(1, last)
    stops = f"{result['linear']['cause'][:80]!r} / {result['finite']['cause'][:80]!r}"
    if last < 0:
        return f"{result['scene']}: no common step; stops: {stops}"
    return (
        f"{result['scene']}: rel. diff tr G {d['rel_diff_growth_rate'][first]:.2e} at t = "
        f"{d['t'][first]:g}, {d['rel_diff_growth_rate'][last]:.2e} at t = {d['t'][last]:g} "
        f"(area {d['rel_diff_area'][last]:.2e}, growth ratio {d['growth_ratio'][last]:.3f}); "
        f"cost x{result['cost_ratio_per_step']:.2f} per step; reached t = "
        f"{result['linear']['t_reached']:g} / {result['finite']['t_reached']:g}; stops: {stops}"
    )


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    logging.basicConfig(format="%(message)s")
    results = json.loads(args.json.read_text()) if args.json.is_file() else {"scenes": {}}
    for path in scene_files(args.hard, args.only):
        name = ("hard/" if args.hard else "") + path.stem
        runs = {}
        for kinematics in ("linear", "finite"):
            scene = variant(path, kinematics, args.preset, args.t_max)
            runs[kinematics] = run(scene, args.out / name / kinematics)
        results["scenes"][name] = summary(name, runs["linear"], runs["finite"])
        print(line(results["scenes"][name]), flush=True)
        results["settings"] = {"preset": args.preset, "t_max": args.t_max}
        results["machine"] = machine_description()
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(results, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
