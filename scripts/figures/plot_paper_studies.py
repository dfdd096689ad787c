"""Figures of the paper's studies from ``benchmarks/results/paper_studies.json`` (and, for the
tissue shapes, the raw run directories of ``scripts/studies/paper_studies.py``); nothing is
solved here.

- ``fig2c_sensitivity.png`` (Fig. 2c): phi = (x0 / X(x0)) dX/dx of the mean tr G per parameter,
  both laws, bars from the sweeps, crosses from the exact homogeneous rate;
- ``fig3_scans.png`` (Fig. 3, first column): mean tr G versus each parameter over its
  docs/model.md section 9 interval, both laws: sweep runs (markers), exact homogeneous rate
  (lines), reference (black);
- ``fig3_micro_macro_<law>.png`` (Fig. 3, columns 2-3): per gradient scene (E, nu, P1, tau, eta),
  the micro walls (Nx = 16) over the macro outline at t_max, the initial tissue shaded, and the
  mean tr G of both versus time. Scenes not run yet are left blank with a note.

``--tables`` prints the Markdown tables of docs/paper_studies.md.

    python scripts/figures/plot_paper_studies.py [--json benchmarks/results/paper_studies.json]
        [--results results/paper_studies] [--out docs/figures] [--tables]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from plot_compare import draw_tissue  # noqa: E402  (scripts/figures/, next to this file)

import plantgrowth as pg  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
LAWS = ("strain", "stress")
COLOURS = {"strain": "tab:blue", "stress": "tab:red"}
MARKERS = {"strain": "o", "stress": "s"}
LABELS = {
    "material.E": "$E$", "material.nu": "$\\nu$", "pressure.P1": "$P_1$",
    "growth.tau": "$\\tau$", "growth.eta": "$\\eta$", "cell.w": "$w$", "l": "$l_1 = l_2$",
    "cell.theta": "$\\theta$",
}  # fmt: skip
REFERENCE = {
    "material.E": 1.0, "material.nu": 0.3, "pressure.P1": 0.001, "growth.tau": 0.0,
    "growth.eta": 1.0, "cell.w": 0.05, "l": 1.0,
}  # fmt: skip
GRADIENTS = {"E": "$E$", "nu": "$\\nu$", "P1": "$P_1$", "tau": "$\\tau$", "eta": "$\\eta$"}


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", type=Path, default=ROOT / "benchmarks/results/paper_studies.json")
    parser.add_argument("--results", type=Path, default=ROOT / "results" / "paper_studies")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "figures")
    parser.add_argument("--tables", action="store_true", help="print the Markdown tables too")
    return parser.parse_args(argv)


def save(fig, path: Path) -> None:
    fig.savefig(path, dpi=130)
    plt.close(fig)
    print(f"wrote {path}")


def plot_sensitivity(data: dict, out: Path) -> None:
    keys = [k for k in LABELS if any(k in data[law] for law in LAWS)]
    fig, ax = plt.subplots(figsize=(8, 4.2), layout="constrained")
    y = np.arange(len(keys))
    for k, law in enumerate(LAWS):
        entries = data[law]
        phi = [entries[key]["phi"] if key in entries else np.nan for key in keys]
        exact = [entries[key]["phi_exact"] if key in entries else np.nan for key in keys]
        offset = (k - 0.5) * 0.38
        ax.barh(y + offset, phi, height=0.36, color=COLOURS[law], label=f"{law} law (sweep)")
        ax.plot(exact, y + offset, "kx", ms=6, label="exact homogeneous rate" if k else None)
    names = [LABELS[key] + (" (around 0.001)" if key == "growth.tau" else "") for key in keys]
    ax.set_yticks(y, names)
    ax.invert_yaxis()
    ax.axvline(0.0, color="0.3", lw=0.8)
    ax.set_xlabel("sensitivity $\\phi = (x_0 / X(x_0))\\, dX/dx$, X = mean tr $G$")
    ax.grid(True, axis="x", alpha=0.3)
    ax.legend(fontsize=8.5, loc="lower right")
    ax.set_title("One-at-a-time sensitivity around the reference (central differences, +/- 5%)")
    save(fig, out)


def plot_scans(data: dict, out: Path) -> None:
    keys = [k for k in REFERENCE if any(k in data[law] for law in LAWS)]
    fig, axes = plt.subplots(2, 4, figsize=(13, 6.2), layout="constrained")
    for ax, key in zip(axes.ravel(), keys, strict=False):
        worst = []
        for law in LAWS:
            if key not in data[law]:
                continue
            entry = data[law][key]
            x = np.array(entry["x"])
            ax.plot(x, entry["exact"], "-", color=COLOURS[law], lw=1, alpha=0.6)
            ax.plot(x, entry["rate"], MARKERS[law], color=COLOURS[law], mfc="none", ms=6)
            ref = np.isclose(x, REFERENCE[key])
            ax.plot(x[ref], np.array(entry["rate"])[ref], "o", color="k", ms=5, zorder=3)
            worst.append(entry["max_relative_difference"])
        ax.set_xlabel(LABELS[key])
        ax.set_title(f"largest |run - exact| / exact: {max(worst):.1e}", fontsize=8.5)
        ax.grid(True, alpha=0.3)
    for ax in axes[:, 0]:
        ax.set_ylabel("mean tr $G$ (constant in time)")
    legend = axes.ravel()[-1]
    legend.axis("off")
    legend.legend(
        handles=[
            Line2D([], [], ls="none", marker=MARKERS[law], mfc="none", color=COLOURS[law],
                   label=f"{law} law: sweep run") for law in LAWS
        ] + [
            Line2D([], [], color="0.4", label="exact homogeneous rate (docs/model.md section 4)"),
            Line2D([], [], ls="none", marker="o", color="k", label="reference value"),
        ],
        loc="center", fontsize=9,
    )  # fmt: skip
    fig.suptitle(
        "Homogeneous tissues: growth rate over each parameter's interval (docs/model.md section 9)"
    )
    save(fig, out)


def plot_micro_macro(data: dict, results: Path, law: str, out: Path) -> None:
    fig, axes = plt.subplots(len(GRADIENTS), 2, figsize=(11, 2.6 * len(GRADIENTS)),
                             layout="constrained", width_ratios=(1.6, 1))  # fmt: skip
    for row, (p, label) in enumerate(GRADIENTS.items()):
        name = f"fig3_micro_{p}_{law}"
        shape, curve = axes[row]
        entry = data.get(name)
        if entry is None:
            for ax in (shape, curve):
                ax.text(0.5, 0.5, f"{name}: not run yet", ha="center", transform=ax.transAxes)
                ax.set_axis_off()
            continue
        run = results / name / "run_0000"
        macro, micro = pg.read_results(run / "macro"), pg.read_results(run / "micro")
        draw_tissue(shape, macro, micro, macro.times[-1])
        shape.set_aspect("equal")
        areas = (f"area x {entry['area_growth_micro']:.3f} micro, "
                 f"x {entry['area_growth_macro']:.3f} macro")  # fmt: skip
        shape.set_title(f"{label} gradient, t = {entry['t']:g}: {areas}", fontsize=9)
        series = entry["series"]
        curve.plot(series["t"], series["rate_macro"], "-", color="k", lw=2, label="macro")
        curve.plot(series["t"], series["rate_micro"], "--", color=COLOURS[law], lw=2,
                   label="micro, $N_x = 16$")  # fmt: skip
        gap = entry["rate_micro"] / entry["rate_macro"] - 1
        curve.set_title(f"mean tr $G$; micro / macro - 1 = {gap:+.2%} at t = {entry['t']:g}",
                        fontsize=9)  # fmt: skip
        curve.ticklabel_format(axis="y", useOffset=False, style="plain")
        curve.grid(True, alpha=0.3)
        curve.legend(fontsize=8)
    axes[-1, 1].set_xlabel("time t")
    axes[0, 0].legend(
        handles=[Patch(color="0.85", label="initial tissue"),
                 Patch(color="tab:green", label="micro walls"),
                 Line2D([], [], color="k", lw=1.2, label="macro outline")],
        fontsize=7.5, loc="lower right",
    )  # fmt: skip
    fig.suptitle(f"{law}-based growth, linear gradients along $x_1$: micro (Nx = 16) and macro")
    save(fig, out)


def tables(data: dict) -> str:
    """The numbers of docs/paper_studies.md as Markdown tables."""
    fig2c, scans, micro = data["fig2c"], data["fig3_scans"], data["fig3_micro_macro"]
    keys = [k for k in LABELS if any(k in fig2c[law] for law in LAWS)]
    lines = ["| parameter | phi strain: sweep / exact | phi stress: sweep / exact |",
             "|---|---:|---:|"]  # fmt: skip
    for key in keys:
        cells = [f"{e['phi']:+.4f} / {e['phi_exact']:+.4f}" if (e := fig2c[law].get(key)) else "-"
                 for law in LAWS]  # fmt: skip
        lines.append(f"| {LABELS[key]} | {' | '.join(cells)} |")
    lines += ["", "| parameter | values | max rel. diff. strain | max rel. diff. stress |",
              "|---|---|---:|---:|"]  # fmt: skip
    for key in REFERENCE:
        entries = [scans[law].get(key) for law in LAWS]
        if not any(entries):
            continue
        ranges = dict.fromkeys(f"{len(e['x'])} in [{min(e['x']):g}, {max(e['x']):g}]"
                               for e in entries if e)  # fmt: skip
        values = " / ".join(ranges)
        cells = [f"{e['max_relative_difference']:.1e}" if e else "-" for e in entries]
        lines.append(f"| {LABELS[key]} | {values} | {' | '.join(cells)} |")
    lines += [
        "",
        "| gradient | law | mean tr G at t_max: micro / macro | rel. diff. "
        "| area growth: micro / macro | rel. diff. | seconds |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for e in micro.values():
        lines.append(
            f"| {GRADIENTS[e['parameter']]} | {e['law']} | {e['rate_micro']:.5f} / "
            f"{e['rate_macro']:.5f} | {e['rate_relative_difference']:.2%} | "
            f"{e['area_growth_micro']:.3f} / {e['area_growth_macro']:.3f} | "
            f"{e['area_growth_relative_difference']:.2%} | {e['seconds']:.0f} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if not args.json.is_file():
        print(f"{args.json} not found: run scripts/studies/paper_studies.py first", file=sys.stderr)
        return 2
    data = json.loads(args.json.read_text())
    args.out.mkdir(parents=True, exist_ok=True)
    plot_sensitivity(data["fig2c"], args.out / "fig2c_sensitivity.png")
    plot_scans(data["fig3_scans"], args.out / "fig3_scans.png")
    for law in LAWS:
        out = args.out / f"fig3_micro_macro_{law}.png"
        plot_micro_macro(data["fig3_micro_macro"], args.results, law, out)
    if args.tables:
        print(tables(data))
    return 0


if __name__ == "__main__":
    sys.exit(main())
