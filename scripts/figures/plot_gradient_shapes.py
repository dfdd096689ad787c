"""Tissue shapes grown under linear parameter gradients (the paper's Fig. 3, columns 2-3).

Reads the runs of ``scripts/studies/run_gradient_scenes.py``
(``results/gradients/gradient_<p>_<law>``) with ``pg.read_results``; never re-solves. One row per
parameter (E, nu, P1, tau, eta, w, l1 = l2), one column per growth law (strain, stress). Each
panel shows the initial tissue (grey) and its outline at t = t_max; the row label gives the
parameter's interval, read from the resolved ``scene.toml`` of the run (the parameter rises
linearly in x1 from the first value at x1 = 0 to the second at the right edge).

    python scripts/figures/plot_gradient_shapes.py [--results results/gradients]
        [--out docs/figures/gradient_shapes.png]
"""

from __future__ import annotations

import argparse
import sys
import tomllib
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import plantgrowth as pg  # noqa: E402
from plantgrowth.results.reader import boundary_outline  # noqa: E402

LAWS = ("strain", "stress")
ROWS = (  # (scene tag, scene keys as (table, key), row label)
    ("E", (("material", "E"),), "$E$"),
    ("nu", (("material", "nu"),), "$\\nu$"),
    ("P1", (("pressure", "P1"),), "$P_1$"),
    ("tau", (("growth", "tau"),), "$\\tau$"),
    ("eta", (("growth", "eta"),), "$\\eta$"),
    ("w", (("cell", "w"),), "$w$"),
    ("l", (("cell", "l1"), ("cell", "l2")), "$l_1 = l_2$"),
)
COLOURS = {"strain": "tab:blue", "stress": "tab:red"}


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", type=Path, default=Path("results/gradients"))
    parser.add_argument("--out", type=Path, default=Path("docs/figures/gradient_shapes.png"))
    parser.add_argument("--dpi", type=int, default=150)
    return parser.parse_args(argv)


def interval(run_dir: Path, keys: tuple[tuple[str, str], ...]) -> str:
    """The parameter's range "[a, b]" from the run's resolved scene (a constant shows as is)."""
    with open(run_dir / "scene.toml", "rb") as f:
        scene = tomllib.load(f)
    texts = set()
    for table, key in keys:
        value = scene[table][key]
        texts.add(
            f"[{value['from']:g}, {value['to']:g}]" if isinstance(value, dict) else f"{value:g}"
        )
    return " / ".join(sorted(texts))


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    runs = {}
    for tag, _, _ in ROWS:
        for law in LAWS:
            run_dir = args.results / f"gradient_{tag}_{law}"
            if not (run_dir / "fields.xdmf").is_file():
                print(f"missing {run_dir}: run scripts/studies/run_gradient_scenes.py",
                      file=sys.stderr)  # fmt: skip
                return 1
            runs[tag, law] = run_dir

    fig, axes = plt.subplots(
        len(ROWS), len(LAWS), figsize=(8.0, 15.0), sharex=True, sharey=True, layout="constrained"
    )
    lows, highs = [], []
    for row, (tag, keys, label) in enumerate(ROWS):
        ranges = {law: interval(runs[tag, law], keys) for law in LAWS}
        same = len(set(ranges.values())) == 1
        for col, law in enumerate(LAWS):
            ax = axes[row, col]
            results = pg.read_results(runs[tag, law])
            t = results.times[-1]
            x0 = results.points
            x = x0 + results.field("u", t)
            lows.append(x.min(axis=0))
            highs.append(x.max(axis=0))
            for loop in boundary_outline(x0, results.triangles):
                ax.fill(*x0[loop].T, color="0.75", ec="0.45", lw=0.6)
                closed = list(loop) + [loop[0]]
                ax.plot(*x[closed].T, color=COLOURS[law], lw=1.4)
            ax.plot([0.0], [0.0], "k+", ms=6)
            title = f"{law} law: area {results.summary['area'][-1]:.1f} at t = {t:g}"
            if not same:
                title += f", {label} in {ranges[law]}"
            ax.set_title(title, fontsize=8.5, color=COLOURS[law])
            ax.set_aspect("equal")
            ax.tick_params(labelsize=8)
            if col == 0:
                rng = f"in {ranges[law]}" if same else "(see titles)"
                ax.set_ylabel(f"{label} {rng}\n\n$x_2$", fontsize=10)
            if row == len(ROWS) - 1:
                ax.set_xlabel("$x_1$")
    low, high = np.min(lows, axis=0), np.max(highs, axis=0)
    pad = 0.03 * float(np.max(high - low))
    axes[0, 0].set_xlim(low[0] - pad, high[0] + pad)
    axes[0, 0].set_ylim(low[1] - pad, high[1] + pad)
    fig.suptitle(
        "Linear gradients along $x_1$ (first value at $x_1 = 0$, second at the right edge):\n"
        "initial tissue (grey) and its outline at $t_{max}$; strain law left, stress law right",
        fontsize=10,
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=args.dpi)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
