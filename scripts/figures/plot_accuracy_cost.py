"""Figure of the accuracy-cost map: error versus CPU time, log-log, one panel per scene.

Reads ``benchmarks/results/accuracy_cost.json`` (``scripts/studies/accuracy_cost.py``; never solves)
and writes ``benchmarks/results/accuracy_cost.png``. Each knob varied alone from the shipped
scene is one line (its levels as points); the presets are stars, the shipped scene a circle.
The error is the largest of the relative errors of final area, final mean tr G and u at t_max.

    python scripts/figures/plot_accuracy_cost.py
"""

from __future__ import annotations

import argparse
import json
import sys
import tomllib
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "benchmarks/results/accuracy_cost.json"
OUT = ROOT / "benchmarks/results/accuracy_cost.png"
FLOOR = 1e-7  # errors below this (round-off: the run equals the reference) are drawn here


def _point(entry: dict, name: str) -> tuple[float, float] | None:
    run, error = entry["runs"].get(name), entry.get("errors", {}).get(name)
    if not run or run["exit"] != 0 or error is None:
        return None
    return run["cpu_seconds"], max(error["err_max"], FLOOR)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DATA, help="(default: %(default)s)")
    parser.add_argument("--out", type=Path, default=OUT, help="(default: %(default)s)")
    args = parser.parse_args(argv)
    data = json.loads(args.data.read_text())
    scenes = data["scenes"]
    ncols = min(len(scenes), 2)
    nrows = -(-len(scenes) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(5.6 * ncols, 4.6 * nrows), squeeze=False)
    knobs = ("h", "H", "cell_resolution", "cell_tolerance", "dt", "integrator")
    for ax, (stem, entry) in zip(axes.flat, scenes.items(), strict=False):
        for knob in knobs:
            names = [n for n in entry["runs"] if n.startswith(knob + ":")] + ["shipped"]
            points = sorted(p for n in names if (p := _point(entry, n)))
            if points:
                ax.plot(*zip(*points, strict=True), "o-", ms=4, lw=1, label=knob)
        for name, marker in (("preset:draft", "v"), ("preset:balanced", "*"), ("preset:fine", "^")):
            if p := _point(entry, name):
                ax.plot(*p, marker, ms=13, mec="k", mfc="gold", label=name.split(":")[1])
        if p := _point(entry, "shipped"):
            ax.plot(*p, "o", ms=9, mfc="none", mec="k", label="shipped scene")
        for level in (0.03, 0.01, 0.001):
            ax.axhline(level, color="0.7", lw=0.6, ls="--")
        t_max = tomllib.loads(entry["runs"]["shipped"]["scene_text"])["time"]["t_max"]
        title = f"{stem} (t = {t_max:g})"
        ax.set(xscale="log", yscale="log", title=title, xlabel="CPU seconds of the whole run")
        ax.set_ylabel("largest relative error (area, mean tr G, u)")
        ax.grid(True, which="major", lw=0.3)
    axes[0][0].legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
