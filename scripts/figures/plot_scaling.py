"""Figure of the scaling benchmark (reads benchmarks/results/scaling.json; never solves).

Left: seconds per step and fine dof by phase (steps 1..n) against the fine dofs, 1 rank (solid)
and 2 ranks (dashed), the organ scene as a star; middle: peak memory summed over the ranks;
right: the macro solve per step of LU and CG + GAMG on 1 rank and the ``auto`` threshold.

    python scripts/figures/plot_scaling.py [--results FILE] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
PHASES = {"seconds": "whole step", "seconds_cells": "cell problems", "seconds_solve": "macro solve",
          "seconds_growth": "growth law", "seconds_io": "output"}  # fmt: skip
STYLE = {1: "-", 2: "--"}


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", type=Path, default=REPO / "benchmarks/results/scaling.json")
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks/results/scaling.png")
    return parser.parse_args(argv)


def by_ranks(runs: list[dict], ranks: int) -> list[dict]:
    return sorted((r for r in runs if r["ranks"] == ranks), key=lambda r: r["fine_dofs"])


def cost_per_dof(ax, runs: list[dict], organ: dict | None) -> None:
    for ranks, style in STYLE.items():
        chosen = by_ranks(runs, ranks)
        dofs = [r["fine_dofs"] for r in chosen]
        for k, (phase, label) in enumerate(PHASES.items()):
            values = [1e6 * r["per_step"][phase] / r["fine_dofs"] for r in chosen]
            ax.plot(dofs, values, style, marker="o", color=f"C{k}",
                    label=f"{label}" if ranks == 1 else None)  # fmt: skip
    if organ:
        ax.plot(organ["fine_dofs"], 1e6 * organ["per_step"]["seconds"] / organ["fine_dofs"],
                "*", color="C0", markersize=14, label="organ scene, 2 ranks")  # fmt: skip
    ax.set(
        xscale="log",
        yscale="log",
        xlabel="fine dofs",
        ylabel="seconds per step per 1e6 dofs",
        title="cost per dof (solid 1 rank, dashed 2)",
    )
    ax.legend(fontsize=7)


def memory(ax, runs: list[dict], organ: dict | None) -> None:
    for ranks, style in STYLE.items():
        chosen = by_ranks(runs, ranks)
        ax.plot([r["fine_dofs"] for r in chosen], [r["peak_rss_mib_total"] / 1024 for r in chosen],
                style, marker="o", color="k", label=f"{ranks} rank(s)")  # fmt: skip
    if organ:
        ax.plot(organ["fine_dofs"], organ["peak_rss_mib_total"] / 1024, "*", color="C3",
                markersize=14, label="organ scene, 2 ranks")  # fmt: skip
    ax.set(xscale="log", yscale="log", xlabel="fine dofs", ylabel="peak memory, all ranks [GiB]",
           title="peak memory")  # fmt: skip
    ax.legend(fontsize=7)


def crossover(ax, runs: list[dict], threshold: int) -> None:
    for solver, color in (("LU", "C1"), ("CG + GAMG", "C2")):
        chosen = sorted((r for r in runs if r["macro_solver"] == solver),
                        key=lambda r: r["fine_dofs"])  # fmt: skip
        ax.plot([r["fine_dofs"] for r in chosen],
                [r["per_step"]["seconds_solve"] for r in chosen], marker="o", color=color,
                label=solver)  # fmt: skip
    ax.axvline(threshold, color="grey", linestyle=":", label="solver.macro_threshold")
    ax.set(xscale="log", yscale="log", xlabel="fine dofs", ylabel="macro solve per step [s]",
           title="LU vs CG + GAMG, 1 rank")  # fmt: skip
    ax.legend(fontsize=7)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    results = json.loads(args.results.read_text())
    organ = results.get("organ")
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5))
    cost_per_dof(axes[0], results["scaling"]["runs"], organ)
    memory(axes[1], results["scaling"]["runs"], organ)
    crossover(axes[2], results["crossover"]["runs"], results["crossover"]["threshold"])
    fig.tight_layout()
    fig.savefig(args.out, dpi=120)
    return 0


if __name__ == "__main__":
    sys.exit(main())
