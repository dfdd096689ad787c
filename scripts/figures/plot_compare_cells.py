"""Plot the micro-macro errors on generated tissues against their irregularity r
(``scripts/studies/compare_cells.py``; docs/real_tissues.md, "How far the homogenized model can
be trusted on irregular cells").

``compare_cells_r.png`` (``--name``): err_ubar and err_G at the first step (t = 0, solid) and
at t_max of the short run (dashed) versus r, one colour per Nx, the mean over the seeds that ran
(each seed's value a dot); a case whose micro run stopped (walls buckling at step 0) is marked by
a cross at the bottom of its panel (shifted a little by Nx to stay apart). Prints the table of
docs/real_tissues.md (``--ranges``: each mean followed by the range of the seeds where more than
one seed ran). Reads only the JSON files given (``--json``); nothing is solved
here. The finite-kinematics study (seeds 1-3)::

    python scripts/figures/plot_compare_cells.py --ranges --name compare_cells_finite_r.png \
        --json benchmarks/results/compare_cells_finite_{s1,s23,n128_s1,n128_s23,n128_r1_s1}.json

    python scripts/figures/plot_compare_cells.py [--json FILE ...] [--variant shaped]
        [--out docs/figures] [--name compare_cells_r.png] [--ranges]
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

RESULTS = Path("benchmarks/results")
RUNS = ("s1", "s23", "s3", "s2_r1", "mid_s1", "mid_s23")  # "mid": r = 0.125, 0.375
DEFAULT = [RESULTS / f"compare_cells_tmax_{name}.json" for name in RUNS]
COLOURS = {4: "tab:red", 8: "tab:purple", 16: "tab:blue", 32: "tab:green"}
ERRORS = ("err_ubar", "err_G")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", type=Path, nargs="+", default=DEFAULT)
    parser.add_argument("--variant", default="shaped", help="macro side: shaped, unshaped, ...")
    parser.add_argument("--out", type=Path, default=Path("docs/figures"))
    parser.add_argument("--name", default="compare_cells_r.png", help="the figure's file name")
    parser.add_argument("--ranges", action="store_true", help="the seeds' range after each mean")
    return parser.parse_args(argv)


def collect(paths: list[Path], variant: str) -> dict[tuple[int, float], list[dict | None]]:
    """``{(Nx, r): [row per seed]}``, None for a seed whose run stopped."""
    found: dict[tuple[int, float], list[dict | None]] = defaultdict(list)
    for path in paths:
        if not path.exists():
            continue
        for row in json.loads(path.read_text())["rows"]:
            result = row.get(variant)
            if result is not None:
                found[row["nx"], row["r"]].append(None if "error" in result else result)
    return found


def _cell(values: list[float], ranges: bool, form: str = "{:.3g}") -> str:
    """The mean of values, with ``ranges`` and more than one value their range after it."""
    if not values:
        return "-"
    text = form.format(np.mean(values))
    if ranges and len(values) > 1:
        text += " (" + form.format(min(values)) + " to " + form.format(max(values)) + ")"
    return text


def table(found: dict[tuple[int, float], list[dict | None]], ranges: bool = False) -> str:
    """The markdown table of docs/real_tissues.md: per (Nx, r) the seeds run / stopped and the
    mean (over the seeds that ran; with ``ranges`` also their range) of each error at t = 0
    and t_max, and of the tissue's mean area growth rate, macro over micro, at t = 0."""
    keys = ("err_u2", "err_ubar", "err_G", "err_ubar_tmax", "err_G_tmax")
    head = ["seeds ran / stopped", *keys, "mean rate: macro / micro - 1"]
    lines = ["| Nx | r | " + " | ".join(head) + " |", "|---:|---:|---|" + "---:|" * (len(head) - 1)]
    for nx, r in sorted(found):
        rows = [row for row in found[nx, r] if row is not None]
        means = [_cell([row[k] for row in rows], ranges) for k in keys]
        rate = [100 * (row["rate_macro_t0"] / row["rate_micro_t0"] - 1.0) for row in rows]
        means.append(_cell(rate, ranges, "{:.2f}") + (" %" if rows else ""))
        ran = f"{len(rows)} / {len(found[nx, r]) - len(rows)}"
        lines.append(f"| {nx} | {r:g} | {ran} | " + " | ".join(means) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    found = collect(args.json, args.variant)
    print(table(found, args.ranges))
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), constrained_layout=True)
    for ax, key in zip(axes, ERRORS, strict=True):
        for k, nx in enumerate(sorted({nx for nx, _ in found})):
            colour = COLOURS.get(nx, "k")
            rs = sorted(r for n, r in found if n == nx)
            for suffix, style in (("", "-"), ("_tmax", "--")):
                xs, means = [], []
                for r in rs:
                    values = [row[key + suffix] for row in found[nx, r]
                              if row is not None and row[key + suffix] is not None]  # fmt: skip
                    ax.plot([r] * len(values), values, ".", color=colour, alpha=0.5)
                    if values:
                        xs.append(r)
                        means.append(np.mean(values))
                label = f"Nx = {nx}, " + ("t = 0" if suffix == "" else "t_max")
                ax.plot(xs, means, style, color=colour, label=label)
            stopped = [r for r in rs if all(row is None for row in found[nx, r])]
            shifted = [r + 0.025 * (k - 1) for r in stopped]  # side by side, not on top
            if stopped:  # an empty unclipped line collapses constrained_layout
                ax.plot(shifted, [0.0] * len(stopped), "x", color=colour, ms=9, clip_on=False)
        ax.set_xlabel("irregularity r")
        ax.set_ylabel(key)
        ax.set_ylim(bottom=0.0)
        ax.set_title(f"{key} (x: micro stopped at step 0)", fontsize=9)
    axes[0].legend(fontsize=7)
    args.out.mkdir(parents=True, exist_ok=True)
    out = args.out / args.name
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
