"""Render one run: the reference tissue (grey) and the grown tissue coloured by a cell field.

Reads ``RESULT_DIR/fields.xdmf`` (+ ``.h5``) written by ``plantgrowth run``; never re-solves.
The grown tissue is the reference mesh moved by the displacement at the last output time,
x + u(t_last). ``--field NAME[:COMPONENT]`` picks the colour: a DG0 field (G, Fg, sigma_hom,
E1111, ...) and, for a tensor, one of 11, 12, 21, 22, tr, det (default ``G:tr``, the areal
growth rate tr G).

    python scripts/render_tissue.py results/reference_stress [--out PNG] [--field G:tr]
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.tri import Triangulation  # noqa: E402

from plantgrowth.results_reader import boundary_outline, read_series  # noqa: E402

LABELS = {"G": "G", "Fg": "F_g", "sigma_hom": "\\sigma_{hom}"}


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("result_dir", type=Path, metavar="RESULT_DIR")
    parser.add_argument(
        "--out", type=Path, default=None, help="PNG (default RESULT_DIR/tissue.png)"
    )
    parser.add_argument(
        "--field", default="G:tr", help="NAME[:COMPONENT], COMPONENT in 11,12,21,22,tr,det"
    )
    parser.add_argument("--dpi", type=int, default=150)
    return parser.parse_args(argv)


def scene_name(result_dir: Path) -> str:
    """The scene file's stem from ``run.log`` (its first line names it), else the directory name."""
    try:
        first = (result_dir / "run.log").read_text().splitlines()[0]
        match = re.search(r"plantgrowth run (\S+) ->", first)
        if match:
            return Path(match.group(1)).stem
    except (OSError, IndexError):
        pass
    return result_dir.name


def field_label(name: str, component: str | None) -> str:
    symbol = LABELS.get(name, name.replace("_", "\\_"))
    if component is None:
        return f"${symbol}$"
    if component == "tr":
        return f"tr ${symbol}$"
    if component == "det":
        return f"det ${symbol}$"
    return f"${symbol}_{{{component}}}$"


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    name, _, component = args.field.partition(":")
    series = read_series(args.result_dir)
    t = series.times[-1]
    values = series.cell_field(name, t, component or None)
    if values.ndim != 1:
        print(f"--field {args.field}: {name} is a tensor, add :COMPONENT", file=sys.stderr)
        return 2
    x0 = series.points
    x = x0 + series.displacement(t)

    fig, ax = plt.subplots(figsize=(9, 4.5), constrained_layout=True)
    loops = boundary_outline(x0, series.triangles)
    mesh = ax.tripcolor(Triangulation(x[:, 0], x[:, 1], series.triangles), facecolors=values)
    spread = float(values.max() - values.min())
    scale = max(float(abs(values).max()), 1e-300)
    uniform = spread <= 1e-6 * scale
    if uniform:  # round-off only: one colour, not a map of the noise
        mean = float(values.mean())
        mesh.set_clim(mean - 1e-3 * scale, mean + 1e-3 * scale)
    for i, loop in enumerate(loops):
        closed = list(loop) + [loop[0]]
        ax.plot(*x[closed].T, color="k", lw=0.8, label="grown" if i == 0 else None)
        # the reference tissue on top, translucent, so it stays visible inside the grown one
        ax.fill(
            *x0[loop].T,
            color="0.6",
            alpha=0.55,
            ec="0.2",
            lw=1.0,
            label="reference (t = 0)" if i == 0 else None,
        )
    ax.plot([0.0], [0.0], "k+", ms=10, mew=1.5)
    ax.set_aspect("equal")
    ax.set_xlabel("$x_1$")
    ax.set_ylabel("$x_2$")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2, fontsize=9, frameon=False)
    note = f" (uniform {values.mean():.4g})" if uniform else ""
    ax.set_title(f"{scene_name(args.result_dir)}: t = {t:g}, colour {args.field}{note}")
    cbar = fig.colorbar(mesh, ax=ax, shrink=0.9, format="%.5g")
    cbar.set_label(field_label(name, component or None) + f" at t = {t:g}")
    out = args.out or args.result_dir / "tissue.png"
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=args.dpi)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
