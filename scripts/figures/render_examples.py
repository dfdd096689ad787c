"""The README pictures of ``scenes/examples/`` (issue 21): the soft disc with its region
outlined, the tissue held on its left and pulled on its right, and the sweep over the disc's
named modulus ``parameters.E_in`` (the disc's own growth rate against the whole tissue's).

Runs what is missing into ``results/examples/`` with the installed ``plantgrowth`` (``run`` and
``sweep``; a complete run or sweep is kept, as ``sweep`` itself keeps finished runs), then
draws into ``docs/figures/example_<name>.png``: ``render`` for the two scenes (the disc's region
outlined), a line plot of ``sweep.csv`` for the sweep. About 4 CPU-minutes from nothing.

    python scripts/figures/render_examples.py
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from render_biology import reached_t_max  # noqa: E402  (scripts/figures/, next to this file)

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "scenes" / "examples"
PLANTGROWTH = str(Path(sys.executable).parent / "plantgrowth")
PICTURES = {"soft_disc": ("trG", ["--regions"]), "held_and_pulled": ("elastic_strain", [])}
"""Scene stem: (the field drawn at its last step, further render options)."""


def plot_sweep(table: Path, picture: Path) -> None:
    """disc.trG and the whole tissue's growth_rate_area at t_max against E_in."""
    with open(table, newline="") as f:
        rows = sorted(csv.DictReader(f), key=lambda r: float(r["parameters.E_in"]))
    E_in = [float(r["parameters.E_in"]) for r in rows]
    fig, ax = plt.subplots(figsize=(5.0, 3.4), layout="constrained")
    ax.plot(E_in, [float(r["disc.trG"]) for r in rows], "o-", label="disc (region columns)")
    ax.plot(E_in, [float(r["growth_rate_area"]) for r in rows], "s--", label="whole tissue")
    ax.set_xlabel("E_in, the disc's wall modulus (parameters.E_in)")
    ax.set_ylabel("areal growth rate tr G at t_max")
    ax.legend(frameon=False)
    fig.savefig(picture, dpi=150)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", type=Path, default=REPO / "results" / "examples")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "figures")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for stem, (field, options) in PICTURES.items():
        scene, run = EXAMPLES / f"{stem}.toml", args.results / stem
        if not reached_t_max(scene, run):
            subprocess.run([PLANTGROWTH, "run", str(scene), "-o", str(run), "--overwrite", "-q"],
                           check=True)  # fmt: skip
        subprocess.run(
            [PLANTGROWTH, "render", str(run), "--field", field, *options,
             "-o", str(args.out / f"example_{stem}.png"), "--force", "-q"],
            check=True,
        )  # fmt: skip
    sweep = args.results / "soft_disc_E"
    subprocess.run([PLANTGROWTH, "sweep", str(EXAMPLES / "soft_disc_E.toml"), "-o", str(sweep),
                    "-q"], check=True)  # fmt: skip
    plot_sweep(sweep / "sweep.csv", args.out / "example_soft_disc_E.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
