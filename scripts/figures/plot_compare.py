"""Plot the micro-macro comparison written by ``compare_study.py`` (the paper's Fig. 2 d-j).

- ``compare_error.png`` (Fig. 2 g-h): relative errors [error] of u1 and u2 at the first step
  versus Nx, log-log, one line per w/l2, markers per growth law, a slope -1 triangle;
- ``compare_growth_rate.png`` (Fig. 2 i-j): mean growth rate tr G versus time, macro (solid)
  and micro per Nx (dashed/dotted), one panel per law;
- ``compare_shapes.png`` (Fig. 2 d-f): the micro walls (deformed, x + u) over the macro outline
  (x + u) at t = 0 and at t_max, Nx = 16, initial tissue shaded. Needs the raw ``fields.h5``
  under ``--raw``; skipped with a message if they are absent.

Reads only result files (``--bench``: index.json, compare.csv, summary.csv; ``--raw``: fields);
nothing is solved here.

    python scripts/figures/plot_compare.py [--bench benchmarks/results/compare] [--out docs/figures]
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch, PathPatch, Rectangle  # noqa: E402
from matplotlib.path import Path as MplPath  # noqa: E402

import plantgrowth as pg  # noqa: E402
from plantgrowth.results.reader import boundary_outline  # noqa: E402

WIDTH_COLOURS = {0.05: "tab:blue", 0.1: "tab:orange", 0.2: "tab:green"}
LAW_MARKERS = {"strain": dict(marker="o", mfc="none", ms=9), "stress": dict(marker="x", ms=6)}
NX_STYLES = ("--", ":", "-.", (0, (5, 1, 1, 1, 1, 1)))
NX_COLOURS = ("tab:red", "tab:purple", "tab:blue", "tab:green")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--bench", type=Path, default=Path("benchmarks/results/compare"))
    parser.add_argument("--raw", type=Path, default=Path("results/compare_study"))
    parser.add_argument("--out", type=Path, default=Path("docs/figures"))
    parser.add_argument("--shape-nx", type=int, default=16, help="Nx of the shapes figure")
    return parser.parse_args(argv)


def read_csv(path: Path) -> dict[str, np.ndarray]:
    """A numeric CSV as ``{column: array}``."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    # "nan" for the empty t_max columns of --first-step-only
    return {key: np.array([float(row[key] or "nan") for row in rows]) for key in rows[0]}


def cases_of(index: dict, kind: str) -> list[dict]:
    return [case for case in index["cases"].values() if case["kind"] == kind]


def slope_triangle(ax, x0: float, y0: float, factor: float = 1.6) -> None:
    """A slope -1 triangle (e ~ 1/Nx = delta) with its lower-left corner at (x0, y0)."""
    x1 = x0 * factor
    ax.plot([x0, x1, x0, x0], [y0 * factor, y0, y0, y0 * factor], color="0.3", lw=1)
    ax.text(x0 / 1.04, y0 * np.sqrt(factor), "1", ha="right", va="center", fontsize=9)
    ax.text(np.sqrt(x0 * x1), y0 / 1.05, "1", ha="center", va="top", fontsize=9)


def plot_errors(index: dict, bench: Path, out: Path) -> None:
    cases = sorted(cases_of(index, "error"), key=lambda c: (c["w"], c["law"]))
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.4), constrained_layout=True)
    nx_all: set[int] = set()
    for case in cases:
        data = read_csv(bench / case["name"] / "compare.csv")
        nx_all |= set(data["nx"].astype(int).tolist())
        colour = WIDTH_COLOURS.get(case["w"], "k")
        style = "-" if case["law"] == "strain" else "--"
        for ax, key in zip(axes, ("err_u1", "err_u2"), strict=True):
            ax.loglog(
                data["nx"], data[key], ls=style, color=colour, lw=1.2, **LAW_MARKERS[case["law"]]
            )
    nx = sorted(nx_all)
    for ax, comp in zip(axes, ("1", "2"), strict=True):
        ax.set_xlabel("cells per row $N_x$ ($\\delta = 1/N_x$)")
        ax.set_ylabel(f"relative error $e(u_{comp})$ at the first step")
        ax.set_xticks(nx, [str(n) for n in nx])
        ax.minorticks_off()
        ax.grid(True, which="both", alpha=0.3)
        ymin = ax.get_ylim()[0]
        slope_triangle(ax, nx[0] * 1.05, ymin * 1.6)
    axes[0].set_title("(g) $u_1$")
    axes[1].set_title("(h) $u_2$")
    handles = [
        Line2D([], [], color=c, lw=2, label=f"$w/l_2 = {w:g}$") for w, c in WIDTH_COLOURS.items()
    ] + [
        Line2D([], [], color="0.3", ls="-" if law == "strain" else "--", label=f"{law} law", **kw)
        for law, kw in LAW_MARKERS.items()
    ]
    axes[1].legend(handles=handles, fontsize=9, loc="upper right")
    resolutions = sorted({c["resolution"] for c in cases})
    fig.suptitle(
        "Micro vs macro displacement at t = 0 (both laws coincide: $F_g = I$ at the first step); "
        f"micro P2, {'/'.join(map(str, resolutions))} elements across a wall",
        fontsize=10,
    )
    fig.savefig(out, dpi=130)
    plt.close(fig)
    print(f"wrote {out}")


def plot_growth_rate(index: dict, bench: Path, out: Path) -> None:
    cases = {c["law"]: c for c in cases_of(index, "full")}
    laws = [law for law in ("strain", "stress") if law in cases]
    fig, axes = plt.subplots(1, len(laws), figsize=(5.4 * len(laws), 4.4), constrained_layout=True)
    axes = np.atleast_1d(axes)
    for ax, law, letter in zip(axes, laws, "ij", strict=False):
        case = cases[law]
        macro_lines = []
        for k, nx in enumerate(case["nx"]):
            macro = read_csv(bench / case["name"] / f"nx{nx}" / "macro" / "summary.csv")
            micro = read_csv(bench / case["name"] / f"nx{nx}" / "micro" / "summary.csv")
            macro_lines.append(macro["growth_rate_area"])
            # macro on each Nx tissue's outline; they coincide (uniform growth), drawn once below
            ax.plot(macro["t"], macro["growth_rate_area"], "-", color="k", lw=2.5 - 0.6 * k)
            gap = 100 * (micro["growth_rate_area"][-1] / macro["growth_rate_area"][-1] - 1)
            ax.plot(
                micro["t"],
                micro["growth_rate_area"],
                ls=NX_STYLES[k % len(NX_STYLES)],
                color=NX_COLOURS[k % len(NX_COLOURS)],
                lw=2.0,
                label=f"micro, $N_x = {nx}$ ({gap:+.2f}% at t = {micro['t'][-1]:g})",
            )
        spread = max(np.ptp(np.vstack(macro_lines), axis=0).max(), 0.0)
        ax.plot([], [], "-", color="k", lw=2, label=f"macro, every $N_x$ (spread {spread:.1e})")
        ax.set_title(f"({letter}) {law}-based growth, $w/l_2 = {case['w']:g}$")
        ax.set_xlabel("time t")
        ax.set_ylabel("mean growth rate tr $G$")
        ax.ticklabel_format(axis="y", useOffset=False, style="plain")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8.5, loc="upper left")
    resolutions = sorted({cases[law]["resolution"] for law in laws})
    fig.suptitle(
        "Mean growth rate (cells' reference areas as weights); micro P2, "
        f"{'/'.join(map(str, resolutions))} elements across a wall",
        fontsize=10,
    )
    fig.savefig(out, dpi=130)
    plt.close(fig)
    print(f"wrote {out}")


def _loops_path(points: np.ndarray, loops: list[np.ndarray]) -> MplPath:
    """One compound path; the outer loop counter-clockwise, the others (holes) clockwise, so
    the non-zero fill rule leaves the holes empty."""
    vertices, codes = [], []
    for k, loop in enumerate(loops):
        ring = loop if k == 0 else loop[::-1]
        vertices.append(np.vstack([points[ring], points[ring[:1]]]))
        codes.append([MplPath.MOVETO] + [MplPath.LINETO] * (len(ring) - 1) + [MplPath.CLOSEPOLY])
    return MplPath(np.vstack(vertices), np.concatenate(codes))


def draw_tissue(ax, macro: pg.Results, micro: pg.Results, t: float) -> None:
    """Initial tissue shaded, micro walls at x + u filled, macro outline at x + u as a line."""
    points = macro.points
    outline = boundary_outline(points, macro.triangles)[0]
    ax.fill(*points[outline].T, color="0.85", lw=0, zorder=0)
    t_micro = min(micro.times, key=lambda s: abs(s - t))
    micro_points = micro.points
    x_micro = micro_points + micro.field("u", t_micro)
    walls = _loops_path(x_micro, boundary_outline(micro_points, micro.triangles))
    ax.add_patch(PathPatch(walls, facecolor="tab:green", edgecolor="none", zorder=1))
    x_macro = points + macro.field("u", t)
    ring = np.append(outline, outline[0])
    ax.plot(*x_macro[ring].T, color="k", lw=1.2, zorder=2)


def plot_shapes(index: dict, raw: Path, nx: int, out: Path) -> None:
    cases = {c["law"]: c for c in cases_of(index, "full")}
    dirs = {law: raw / case["name"] / f"nx{nx}" for law, case in cases.items()}
    runs = [d / model for d in dirs.values() for model in ("macro", "micro")]
    missing = [str(run) for run in runs if not (run / "fields.h5").is_file()]
    if not dirs or missing:
        reason = ", ".join(missing) or "no full-time cases in the index"
        print(f"skipped {out}: raw fields not found ({reason}); "
              "run scripts/studies/compare_study.py first")  # fmt: skip
        return
    series = {law: (pg.read_results(d / "macro"), pg.read_results(d / "micro"))
              for law, d in dirs.items()}  # fmt: skip
    first = "strain" if "strain" in series else next(iter(series))
    panels = [("(d) both laws", first, series[first][0].times[0])]
    for law, letter in zip(("strain", "stress"), "ef", strict=True):
        if law in series:
            panels.append((f"({letter}) {law}-based growth", law, series[law][0].times[-1]))
    zoom_law, zoom_t = panels[-1][1], panels[-1][2]
    fig, axes = plt.subplots(2, 2, figsize=(11, 6.2), constrained_layout=True)
    axes = axes.ravel()
    for ax, (title, law, t) in zip(axes, panels, strict=False):
        draw_tissue(ax, *series[law], t)
        ax.set_title(f"{title}, t = {t:g}", fontsize=10)
    # common limits for the tissue panels, so that the growth reads off directly
    corners = np.array([ax.dataLim.get_points() for ax in axes[: len(panels)]])
    lo, hi = corners[:, 0].min(axis=0) - 0.3, corners[:, 1].max(axis=0) + 0.3
    for ax in axes[: len(panels)]:
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(min(lo[1], -0.1), hi[1])
        ax.set_aspect("equal")
        ax.grid(True, alpha=0.2)
        ax.set_xlabel("$x_1$", labelpad=1)
        ax.set_ylabel("$x_2$", labelpad=1)
    # zoom on the top-right corner of the last panel: the outer walls bulge under the pressure
    zoom = axes[len(panels)] if len(panels) < 4 else None
    if zoom is not None:
        macro, micro = series[zoom_law]
        draw_tissue(zoom, macro, micro, zoom_t)
        x = macro.points + macro.field("u", zoom_t)
        x1, x2 = x[:, 0].max(), x[:, 1].max()
        box = (x1 - 2.2, x1 + 0.35, x2 - 1.3, x2 + 0.25)
        zoom.set_xlim(box[0], box[1])
        zoom.set_ylim(box[2], box[3])
        zoom.set_aspect("equal")
        zoom.set_title(f"zoom on the top-right corner of ({panels[-1][0][1]})", fontsize=10)
        zoom.set_xlabel("$x_1$", labelpad=1)
        axes[len(panels) - 1].add_patch(
            Rectangle((box[0], box[2]), box[1] - box[0], box[3] - box[2], fill=False, lw=1, ec="r")
        )
    axes[0].legend(
        handles=[
            Patch(color="0.85", label="initial tissue"),
            Patch(color="tab:green", label=f"micro walls, $N_x = {nx}$"),
            Line2D([], [], color="k", lw=1.2, label="macro outline"),
        ],
        fontsize=8,
        loc="upper right",
    )
    fig.suptitle("Deformed tissue x + u: micro walls over the macro outline", fontsize=11)
    fig.savefig(out, dpi=150)
    plt.close(fig)
    print(f"wrote {out}")


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    index_path = args.bench / "index.json"
    if not index_path.is_file():
        print(f"{index_path} not found: run scripts/studies/compare_study.py first",
              file=sys.stderr)  # fmt: skip
        return 2
    index = json.loads(index_path.read_text())
    args.out.mkdir(parents=True, exist_ok=True)
    if cases_of(index, "error"):
        plot_errors(index, args.bench, args.out / "compare_error.png")
    if cases_of(index, "full"):
        plot_growth_rate(index, args.bench, args.out / "compare_growth_rate.png")
        plot_shapes(index, args.raw, args.shape_nx, args.out / "compare_shapes.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
