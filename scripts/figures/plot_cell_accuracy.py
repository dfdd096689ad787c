"""Plot the unit-cell accuracy/cost benchmark written by ``bench_cell_accuracy.py``.

Left: max relative error (over E1, E2, nu12, G12, K11, K22) versus time per cell problem,
log-log, points labelled with the resolution. Right: the same errors versus resolution.
Filled markers: error against the reference resolution; open markers: error against the
Richardson extrapolation (when the benchmark could compute one).

    python scripts/figures/plot_cell_accuracy.py [--data benchmarks/results/cell_accuracy.json]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=Path("benchmarks/results/cell_accuracy.json"))
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/cell_accuracy.png"))
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    data = json.loads(args.data.read_text())
    R = data["reference_resolution"]
    fig, (ax_t, ax_r) = plt.subplots(1, 2, figsize=(11, 4.5), constrained_layout=True)
    for colour, (name, case) in zip(COLOURS, data["cases"].items(), strict=False):
        rows = [row for row in case["rows"] if row["resolution"] != R]
        t = [row["solve_seconds"] for row in rows]
        r = [row["resolution"] for row in rows]
        err = [row["max_rel_error"] for row in rows]
        est = [row["max_est_error"] for row in rows]
        label = name.replace("Fg", "$F_g$")
        ax_t.loglog(t, err, "o-", color=colour, label=f"{label}, vs resolution {R}")
        ax_r.loglog(r, err, "o-", color=colour, label=f"{label}, vs resolution {R}")
        if case["extrapolated"]:
            ax_t.loglog(t, est, "o--", color=colour, mfc="none", label=f"{label}, vs extrapolated")
            ax_r.loglog(r, est, "o--", color=colour, mfc="none", label=f"{label}, vs extrapolated")
        if colour == COLOURS[0]:
            for ti, ri, ei in zip(t, r, err, strict=True):
                ax_t.annotate(
                    str(ri), (ti, ei), textcoords="offset points", xytext=(4, 4), fontsize=8
                )
    for ax in (ax_t, ax_r):
        for tol, text in ((1e-2, "1%"), (1e-3, "0.1%")):
            ax.axhline(tol, color="0.6", lw=0.8, ls=":")
            ax.text(1.0, tol, f" {text}", transform=ax.get_yaxis_transform(), va="center")
        ax.set_ylabel("max relative error of $E_1, E_2, \\nu_{12}, G_{12}, K_{11}, K_{22}$")
        ax.grid(True, which="major", alpha=0.3)
    ax_t.set_xlabel("time per cell problem [s] (assembly + LU + 4 solves)")
    ax_t.set_title("cost (labels: P2 elements across the wall)")
    resolutions = sorted(
        {row["resolution"] for case in data["cases"].values() for row in case["rows"]} - {R}
    )
    ax_r.set_xticks(resolutions, [str(r) for r in resolutions])
    ax_r.minorticks_off()
    ax_r.set_xlabel("resolution (P2 elements across the wall thickness $w$)")
    ax_r.set_title("convergence")
    ax_r.legend(fontsize=8, loc="lower left")
    machine = data["machine"]
    cell = data["cell"]
    fig.suptitle(
        f"Unit cell $l_1 = {cell['l1']:g}$, $l_2 = {cell['l2']:g}$, "
        f"$\\theta = {cell['theta_deg']:g}°$, $w = {cell['w']:g}$, $E = {data['E']:g}$, "
        f"$\\nu = {data['nu']:g}$; {machine['cpu']}, 1 core, dolfinx {machine['dolfinx']}",
        fontsize=10,
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=130)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
