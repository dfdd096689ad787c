"""Figures of the finite-kinematics studies (issue 12, docs/model.md section 10).

- ``finite_vs_linear.png``: from ``benchmarks/results/finite_vs_linear.json``
  (``scripts/studies/finite_vs_linear.py``), |finite - linear| / |linear| of the tissue's mean
  growth rate tr G and of its area, per step, against the growth ratio area(t) / area(0), one
  line per gradient scene (grey: hard cases that ran both kinematics to a common step);
- ``finite_micro_macro.png``: from ``benchmarks/results/compare_finite`` and
  ``benchmarks/results/compare`` (``scripts/studies/compare_study.py [--kinematics finite]``), the
  micro-macro errors err_u1, err_u2, err_ubar, err_G at t = 0 and t = t_max against Nx, finite
  (solid) and linear (dashed), and the area of the long gradient run (macro and micro, both
  kinematics) against time.

Reads result files only; nothing is solved here.

    python scripts/figures/plot_finite.py [--out docs/figures]
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ERRORS = ("err_u1", "err_u2", "err_ubar", "err_G")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add = parser.add_argument
    add("--json", type=Path, default=Path("benchmarks/results/finite_vs_linear.json"))
    add("--finite", type=Path, default=Path("benchmarks/results/compare_finite"))
    add("--linear", type=Path, default=Path("benchmarks/results/compare"))
    add("--out", type=Path, default=Path("docs/figures"))
    return parser.parse_args(argv)


def read_csv(path: Path) -> dict[str, np.ndarray]:
    """A numeric CSV as ``{column: array}`` (empty cells: NaN)."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {key: np.array([float(row[key] or "nan") for row in rows]) for key in rows[0]}


def plot_differences(results: dict, path: Path) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharex=True)
    keys = (("rel_diff_growth_rate", "mean tr G"), ("rel_diff_area", "area"))
    colours = iter(plt.get_cmap("tab20").colors)
    for name, result in sorted(results["scenes"].items()):
        d = result["differences"]
        if len(d["t"]) < 2:
            continue
        hard = name.startswith("hard/")
        style = dict(color="0.7", lw=0.8) if hard else dict(color=next(colours), lw=1.3, label=name)
        ratio = np.array(d["growth_ratio"][1:])
        for ax, (key, _) in zip(axes, keys, strict=True):
            ax.plot(ratio, np.maximum(d[key][1:], 1e-16), **style)
    for ax, (_, label) in zip(axes, keys, strict=True):
        ax.set(xscale="log", yscale="log", xlabel="growth ratio area(t) / area(0) (linear run)",
               ylabel=f"|finite - linear| / |linear|, {label}")  # fmt: skip
        ax.grid(True, which="major", alpha=0.3)
    axes[0].legend(fontsize=6.5, ncol=2, loc="lower right")
    fig.suptitle("Linear versus finite kinematics (grey: hard cases)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_micro_macro(finite: Path, linear: Path, path: Path) -> None:
    laws = [p.name for p in sorted(finite.glob("full_*")) if (p / "compare.csv").is_file()]
    long_runs = [
        (kin, run) for kin, root in (("finite", finite), ("linear", linear))
        for run in sorted(root.glob("gradient_*")) if list(run.glob("nx*/*/summary.csv"))
    ]  # fmt: skip
    n = len(laws) + bool(long_runs)
    fig, axes = plt.subplots(1, n, figsize=(4.6 * n, 4.2), squeeze=False)
    colours = dict(zip(ERRORS, ("tab:blue", "tab:orange", "tab:green", "tab:red"), strict=True))
    for ax, case in zip(axes[0], laws, strict=False):
        f = read_csv(finite / case / "compare.csv")
        lin = linear / case / "compare.csv"
        lin = read_csv(lin) if lin.is_file() else None
        for key in ERRORS:
            c = colours[key]
            ax.plot(f["nx"], f[key], "o-", color=c, label=f"{key}, t = 0")
            ax.plot(f["nx"], f[f"{key}_tmax"], "s:", color=c, mfc="none", label=f"{key}, t_max")
            if lin is not None:
                ax.plot(lin["nx"], lin[key], "--", color=c, lw=0.8, alpha=0.6)
        ax.set(xscale="log", yscale="log", xlabel="Nx", ylabel="relative error",
               title=f"{case}: finite (dashed: linear, t = 0)")  # fmt: skip
        ax.set_xticks(f["nx"], [f"{x:g}" for x in f["nx"]])
        ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
        ax.grid(True, alpha=0.3)
    axes[0][0].legend(fontsize=6.5)
    if long_runs:
        ax = axes[0][-1]
        for kin, run in long_runs:
            colour = "tab:blue" if kin == "finite" else "tab:grey"
            for model, style in (("macro", "-"), ("micro", "--")):
                for summary in sorted(run.glob(f"nx*/{model}/summary.csv")):
                    s = read_csv(summary)
                    ax.plot(s["t"], s["area"], style, color=colour, label=f"{kin}, {model}")
        ax.set(xlabel="t", ylabel="tissue area", yscale="log",
               title=f"{long_runs[0][1].name}: area")  # fmt: skip
        ax.legend(fontsize=6.5)
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    plot_differences(json.loads(args.json.read_text()), args.out / "finite_vs_linear.png")
    print(args.out / "finite_vs_linear.png")
    if args.finite.is_dir():
        plot_micro_macro(args.finite, args.linear, args.out / "finite_micro_macro.png")
        print(args.out / "finite_micro_macro.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
