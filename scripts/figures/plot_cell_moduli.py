"""Plot the moduli curves written by ``cell_moduli_curves.py`` (the paper's Fig. 1 d-o).

Writes two 2x3 figures (E1, E2, nu12, G12, K11, K22), one line per l1/l2 (red, green, blue as in
the paper): versus w/l2 (log axis) and versus g for Fg = diag(g, 1).

    python scripts/figures/plot_cell_moduli.py [--data benchmarks/results/cell_moduli.json]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

COLOURS = ("red", "green", "blue", "black", "orange")
PANELS = (
    ("E1", "$E_1 / E$"),
    ("E2", "$E_2 / E$"),
    ("nu12", "$\\nu_{12}$ [-]"),
    ("G12", "$G_{12} / E$"),
    ("K11", "$K_{11}$ [-] (per unit pressure)"),
    ("K22", "$K_{22}$ [-] (per unit pressure)"),
)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=Path("benchmarks/results/cell_moduli.json"))
    parser.add_argument("--outdir", type=Path, default=Path("benchmarks/results"))
    return parser.parse_args(argv)


def plot_sweep(data: dict, sweep: str, x_key: str, xlabel: str, logx: bool, title: str):
    fig, axes = plt.subplots(2, 3, figsize=(12, 7), constrained_layout=True)
    for colour, (ratio, curve) in zip(COLOURS, data[sweep].items(), strict=False):
        for ax, (key, _) in zip(axes.flat, PANELS, strict=True):
            # normalise by the wall's E (K is already a ratio to the pressure)
            scale = data["E"] if key in ("E1", "E2", "G12") else 1.0
            y = [v / scale for v in curve[key]]
            ax.plot(curve[x_key], y, "o-", ms=3, color=colour, label=f"$l_1/l_2 = {ratio}$")
    for ax, (key, ylabel) in zip(axes.flat, PANELS, strict=True):
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        if logx:
            ax.set_xscale("log")
            if key in ("E1", "E2", "G12"):
                ax.set_yscale("log")
        ax.grid(True, which="major", alpha=0.3)
    axes.flat[0].legend(fontsize=9)
    fig.suptitle(title, fontsize=11)
    return fig


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    data = json.loads(args.data.read_text())
    common = (
        f"$l_2 = {data['l2']:g}$, $\\theta = {data['theta_deg']:g}°$, wall $E = {data['E']:g}$, "
        f"$\\nu = {data['nu']:g}$, resolution {data['resolution']}"
    )
    figures = {
        "cell_moduli_thickness.png": plot_sweep(
            data,
            "thickness",
            "w_over_l2",
            "$w / l_2$",
            True,
            f"Homogenized moduli vs wall thickness, $F_g = I$; {common}",
        ),
        "cell_moduli_growth.png": plot_sweep(
            data,
            "growth",
            "g",
            "$g$ in $F_g = \\mathrm{diag}(g, 1)$",
            False,
            f"Homogenized moduli vs growth along $x_1$, $w/l_2 = {data['w_growth']:g}$; {common}",
        ),
    }
    args.outdir.mkdir(parents=True, exist_ok=True)
    for name, fig in figures.items():
        fig.savefig(args.outdir / name, dpi=110)
        plt.close(fig)
        print(f"wrote {args.outdir / name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
