"""The README gallery of the biology scenes (issue 11, item 5): ``plantgrowth render <run> --field
trG`` at the last step of each run in ``results/biology/<name>/`` into
``docs/figures/biology_<name>.png``; for a water scene (``[hydraulics]``, docs/hydraulics.md) also
its turgor, ``--field P``, into ``biology_<name>_P.png``, or, when a supply's potential changes in
time, its summary.csv against time (that potential, turgor, growth rate) into
``biology_<name>_series.png``.

Reads the runs of ``scripts/studies/run_biology_scenes.py`` (never re-solves): a scene whose run
is missing or has not reached the scene's t_max is an error that names the study command.

    python scripts/figures/render_biology.py [--only NAME ...]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np

import plantgrowth as pg
from plantgrowth.scene.hydraulics import Potential

REPO = Path(__file__).resolve().parents[2]
PLANTGROWTH = str(Path(sys.executable).parent / "plantgrowth")
STUDY = "python scripts/studies/run_biology_scenes.py"


def reached_t_max(scene: Path, run: Path) -> bool:
    """Whether the run in ``run`` holds the scene's last step (its summary reaches t_max)."""
    try:
        t = pg.read_results(run).summary["t"]
    except (pg.InputError, OSError):
        return False
    t_max = pg.load_scene(scene).time.t_max
    return len(t) > 0 and t[-1] >= t_max - 1e-9 * max(1.0, t_max)


def render(run: Path, picture: Path, field: str = "trG", cells: bool = False) -> None:
    """``plantgrowth render RUN --field FIELD -o PICTURE --force`` (``cells``: ``--cells
    FIELD``, a micro run's cells.csv column)."""
    subprocess.run([PLANTGROWTH, "render", str(run), "--cells" if cells else "--field", field,
                    "-o", str(picture), "--force"], check=True)  # fmt: skip


def water_series(run: Path, potential: Potential, picture: Path) -> None:
    """The run's supply potential, turgor (mean, and its range shaded) and mean growth rate tr G
    against time, from summary.csv, in three panels sharing the time axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = pg.read_results(run).summary
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(6.0, 5.5))
    t = np.linspace(s["t"][0], s["t"][-1], 1000)
    axes[0].plot(t, [potential(x) for x in t], color="tab:blue")
    axes[0].set_ylabel("supply psi_s")
    axes[1].fill_between(s["t"], s["turgor_min"], s["turgor_max"], color="tab:green", alpha=0.3)
    axes[1].plot(s["t"], s["turgor_mean"], color="tab:green")
    axes[1].set_ylabel("turgor P")
    axes[2].plot(s["t"][1:], s["growth_rate_area"][1:], color="tab:red")  # t = 0: P = Pi
    axes[2].set_ylabel("growth rate tr G")
    axes[2].set_xlabel("t")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(picture, dpi=150)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    # the fibre scenes (fibres_*) are drawn with their director glyphs by render_fibres.py
    scenes = sorted(s for s in (REPO / "scenes" / "biology").glob("*.toml")
                    if not s.stem.startswith("fibres_"))  # fmt: skip
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="*", choices=[s.stem for s in scenes])
    parser.add_argument("--results", type=Path, default=REPO / "results" / "biology")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "figures")
    args = parser.parse_args(argv)
    chosen = [s for s in scenes if not args.only or s.stem in args.only]
    missing = [s.stem for s in chosen if not reached_t_max(s, args.results / s.stem)]
    if missing:
        print(f"no complete run of {', '.join(missing)} in {args.results}: run {STUDY} first",
              file=sys.stderr)  # fmt: skip
        return 1
    args.out.mkdir(parents=True, exist_ok=True)
    for scene in chosen:
        run, name = args.results / scene.stem, scene.stem
        render(run, args.out / f"biology_{name}.png")
        loaded = pg.load_scene(scene)
        water = loaded.hydraulics
        if water is not None:
            varying = [s.potential for s in water.supplies if not s.potential.is_constant]
            if varying:
                water_series(run, varying[0], args.out / f"biology_{name}_series.png")
            else:
                micro = loaded.model == "micro"  # its P is per cell, in cells.csv
                render(run, args.out / f"biology_{name}_P.png", "P", cells=micro)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
