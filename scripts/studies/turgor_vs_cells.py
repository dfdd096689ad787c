"""Turgor and growth against cell size and neighbour number in an irregular tissue (issue 34,
item 5; Long et al. 2020; docs/real_tissues.md, "Turgor and cell size").

Runs scenes/biology/irregular_turgor.toml (the micro model with water fluxes on a generated
tissue, every cell fed from beneath) for each seed (``--seeds``, default 1 2 3), reads each
cell's turgor ``P``, current ``area``, ``neighbours`` and growth rate ``trG`` from cells.csv,
and the observed relative areal growth rate ``d ln(area)/dt`` between consecutive written rows,
and gives the Pearson and Spearman correlations of P and of both rates with area and with
neighbour number at a few times (``--times``), over the interior cells (every side a wall
shared with another cell: the outer cells have free outer walls and the bottom row is cut by
the symmetry plane, so their areas and neighbour counts are not those of whole cells); and
again (``y~x detrended``) for y less its quadratic fit in the cells' reference centres, the
cell-to-cell part without the tissue-scale pattern.

Raw runs go to ``--raw`` (default ``results/turgor_vs_cells``, git-ignored; a finished run is
read again, not rerun); ``--json`` (default ``benchmarks/results/turgor_vs_cells.json``) gets
the correlations, the run's settings and the machine description; ``--figure`` (default
``docs/figures/turgor_vs_cells.png``) the scatter plots at the last time.

    nice -n 19 python scripts/studies/turgor_vs_cells.py [--seeds 1 2 3] [--regularity 0.5]
    python scripts/studies/turgor_vs_cells.py --conductivity 5 \
        --raw results/turgor_vs_cells_L5 --json benchmarks/results/turgor_vs_cells_L5.json \
        --figure /tmp/turgor_L5.png
"""

from __future__ import annotations

import argparse
import csv
import json
import time
import tomllib
from pathlib import Path

import numpy as np
from mpi4py import MPI
from scipy import stats

from plantgrowth.api import run
from plantgrowth.base.machine import machine_description
from plantgrowth.scene import parse_scene
from plantgrowth.scene.tissue_cells import cell_polygons

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "biology" / "irregular_turgor.toml"
PAIRS = [("P", "area"), ("P", "neighbours"), ("trG", "area"), ("trG", "neighbours"),
         ("area_rate", "area"), ("area_rate", "neighbours")]  # fmt: skip


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add = parser.add_argument
    add("--seeds", type=int, nargs="+", default=[1, 2, 3])
    add("--regularity", type=float, default=None, help="default: the scene's")
    add("--times", type=float, nargs="+", default=[1.0, 3.0, 6.0], help="written times")
    add("--on-instability", choices=["stop", "warn"], default=None, help="default: the scene's")
    add(
        "--conductivity",
        type=float,
        default=None,
        help="hydraulics.conductivity L (default: " "the scene's)",
    )
    add("--raw", type=Path, default=ROOT / "results" / "turgor_vs_cells")
    add("--json", type=Path, default=ROOT / "benchmarks" / "results" / "turgor_vs_cells.json")
    add("--figure", type=Path, default=ROOT / "docs" / "figures" / "turgor_vs_cells.png")
    return parser.parse_args(argv)


def scene_data(
    seed: int, regularity: float | None, on_instability: str | None, conductivity: float | None
) -> dict:
    """The scene's TOML data with the tissue's seed (and regularity, instability policy, wall
    conductivity) set."""
    data = tomllib.loads(SCENE.read_text())
    if conductivity is not None:
        data["hydraulics"]["conductivity"] = conductivity
    data["tissue"]["cells"]["seed"] = seed
    if regularity is not None:
        data["tissue"]["cells"]["regularity"] = regularity
    if on_instability is not None:
        data.setdefault("numerics", {})["on_instability"] = on_instability
    return data


def interior_cells(data: dict) -> np.ndarray:
    """Ids of the cells whose every side is shared with another cell."""
    cells = cell_polygons(parse_scene(data, directory=SCENE.parent))
    outer = {found[0] for found in cells.sides().values() if len(found) == 1}
    return np.array([i for i in range(cells.n_cells) if i not in outer])


def read_cells(outdir: Path) -> dict[float, dict[str, np.ndarray]]:
    """cells.csv by written time: each column in cell id order, plus ``area_rate``
    ``(ln area_k - ln area_k-1) / (t_k - t_k-1)`` from the row before (NaN at the first)."""
    with (outdir / "cells.csv").open(newline="", encoding="utf-8") as f:
        rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
    out: dict[float, dict[str, np.ndarray]] = {}
    for t in sorted({r["t"] for r in rows}):
        at = sorted((r for r in rows if r["t"] == t), key=lambda r: r["cell"])
        out[t] = {k: np.array([r[k] for r in at]) for k in at[0]}
    times = list(out)
    for before, t in zip([None] + times[:-1], times, strict=True):
        area = out[t]["area"]
        out[t]["area_rate"] = (np.full_like(area, np.nan) if before is None else
                               np.log(area / out[before]["area"]) / (t - before))  # fmt: skip
    return out


def detrended(values: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``values`` less their least-squares fit by a quadratic in the cells' reference centres
    ``x`` (n, 2): the cell-to-cell part, without the tissue-scale pattern."""
    x1, x2 = x.T
    basis = np.column_stack([np.ones_like(x1), x1, x2, x1 * x1, x1 * x2, x2 * x2])
    return values - basis @ np.linalg.lstsq(basis, values, rcond=None)[0]


def correlations(columns: dict[str, np.ndarray], cells: np.ndarray) -> dict[str, dict]:
    """Pearson and Spearman r (with p) of each pair of PAIRS over ``cells``, and (``y~x
    detrended``) of y's :func:`detrended` part with x, with the share of y's variance that
    the position explains."""
    out = {}
    centres = np.column_stack([columns["x1_ref"], columns["x2_ref"]])[cells]
    for y, x in PAIRS:
        a, b = columns[x][cells], columns[y][cells]
        if np.isnan(b).any() or np.ptp(b) == 0.0:
            continue
        rest = detrended(b, centres)
        spearman = stats.spearmanr(a, rest)
        out[f"{y}~{x} detrended"] = {
            "spearman": float(spearman[0]),
            "spearman_p": float(spearman[1]),
            "position_share": float(1.0 - rest.var() / b.var()),
        }
        pearson, spearman = stats.pearsonr(a, b), stats.spearmanr(a, b)
        out[f"{y}~{x}"] = {
            "pearson": float(pearson[0]),
            "pearson_p": float(pearson[1]),
            "spearman": float(spearman[0]),
            "spearman_p": float(spearman[1]),
        }
    return out


def study(args: argparse.Namespace) -> dict:
    """Run (or read) every seed; the correlations per seed and time."""
    per_seed, raw_points = {}, {}
    for seed in args.seeds:
        data = scene_data(seed, args.regularity, args.on_instability, args.conductivity)
        outdir = args.raw / f"seed{seed}"
        seconds = None  # a finished run read again
        if not (outdir / "cells.csv").is_file() or not _finished(outdir, data):
            start = time.perf_counter()
            run(parse_scene(data, directory=SCENE.parent), outdir, MPI.COMM_SELF, overwrite=True)
            seconds = time.perf_counter() - start
        cells, table = interior_cells(data), read_cells(outdir)
        per_seed[seed] = {
            "seconds": seconds,
            "interior_cells": len(cells),
            "cells": len(next(iter(table.values()))["cell"]),
            "times": {},
        }
        for t in args.times:
            at = min(table, key=lambda s: abs(s - t))
            per_seed[seed]["times"][f"{at:g}"] = correlations(table[at], cells)
        last = table[max(table)]
        raw_points[seed] = {k: last[k][cells] for k in ("P", "area", "neighbours", "trG")}
    return {"per_seed": per_seed, "points": raw_points}


def _finished(outdir: Path, data: dict) -> bool:
    """Whether the run in ``outdir`` wrote its last time."""
    with (outdir / "summary.csv").open(newline="", encoding="utf-8") as f:
        last = list(csv.DictReader(f))[-1]
    return abs(float(last["t"]) - data["time"]["t_max"]) < 1e-9


def signs(per_seed: dict) -> dict[str, dict[str, str]]:
    """Per time and pair: "+" or "-" if the Spearman r has that sign for every seed, else
    "mixed"."""
    out: dict[str, dict[str, str]] = {}
    seeds = list(per_seed.values())
    for t in seeds[0]["times"]:
        for pair in seeds[0]["times"][t]:
            values = [s["times"][t][pair]["spearman"] for s in seeds]
            sign = "+" if min(values) > 0 else "-" if max(values) < 0 else "mixed"
            out.setdefault(t, {})[pair] = sign
    return out


def draw(points: dict, path: Path) -> None:
    """Scatter plots at the last time: P and trG against area and neighbour number."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 6.5), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 2)
    for row, y in enumerate(("P", "trG")):
        for col, x in enumerate(("area", "neighbours")):
            ax = axes[row, col]
            for k, (seed, p) in enumerate(points.items()):
                jitter = 0.08 * (k - 1) if x == "neighbours" else 0.0
                ax.scatter(p[x] + jitter, p[y], s=10, alpha=0.7, label=f"seed {seed}")
            ax.set_xlabel({"area": "cell area (current)", "neighbours": "neighbour number"}[x])
            ax.set_ylabel({"P": "turgor P (sigma0)", "trG": "growth rate tr G (1/T)"}[y])
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("Interior cells of irregular tissues (scenes/biology/irregular_turgor.toml)")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    result = study(args)
    data = scene_data(args.seeds[0], args.regularity, args.on_instability, args.conductivity)
    report = {
        "scene": str(SCENE.relative_to(ROOT)), "tissue": data["tissue"]["cells"] | {"seed": None},
        "numerics": data.get("numerics", {}), "hydraulics": data["hydraulics"],
        "seeds": args.seeds,
        "per_seed": {str(k): v for k, v in result["per_seed"].items()},
        "robust_signs_spearman": signs(result["per_seed"]),
        "machine": machine_description(),
    }  # fmt: skip
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(report, indent=1) + "\n")
    draw(result["points"], args.figure)
    print(json.dumps(report["robust_signs_spearman"], indent=1))


if __name__ == "__main__":
    main()
