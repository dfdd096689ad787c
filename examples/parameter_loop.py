"""Run one scene for several wall stiffnesses (material.E) and plot the tissue's growth rate.

    python examples/parameter_loop.py OUTDIR [--figure FILE.png] [--overwrite]

Under the strain law a softer wall stretches more under the same turgor, so it grows faster.
Each run goes to OUTDIR/E_<value>; the figure (the last step's growth_rate_area, the mean of
tr G over the tissue, against E) to FILE.png, by default OUTDIR/growth_rate_vs_E.png. A few
seconds at the draft preset. For larger studies, with resumable runs and a results table, see
``plantgrowth sweep`` (docs/usage.md, Sweeps).
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # draw to files only: no display needed
import matplotlib.pyplot as plt
from mpi4py import MPI

import plantgrowth as pg

STIFFNESSES = [0.5, 1.0, 2.0, 4.0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("outdir", type=Path, help="directory for the runs")
    parser.add_argument("--figure", type=Path, help="default: OUTDIR/growth_rate_vs_E.png")
    parser.add_argument("--overwrite", action="store_true", help="replace earlier runs there")
    args = parser.parse_args()
    figure = args.figure or args.outdir / "growth_rate_vs_E.png"

    base = pg.Scene.from_dict(
        {
            "growth": {"law": "strain"},
            "time": {"t_max": 5},
            "accuracy": {"preset": "draft"},
        }
    )
    rates = {}  # E -> growth_rate_area at each step
    for E in STIFFNESSES:
        # replace() checks the new value as the scene file would (pg.SceneError if invalid)
        scene = base.replace(**{"material.E": E})
        results = pg.run(scene, args.outdir / f"E_{E:g}", overwrite=args.overwrite)
        rates[E] = results.summary["growth_rate_area"]

    if MPI.COMM_WORLD.rank != 0:  # under mpirun: rank 0 prints and draws
        return
    final = [float(rates[E][-1]) for E in STIFFNESSES]
    for E, rate in zip(STIFFNESSES, final, strict=True):
        print(f"E = {E:g}: growth_rate_area at t = {base.time.t_max:g}: {rate!r}")
    fig, ax = plt.subplots(figsize=(5, 4))
    ax.loglog(STIFFNESSES, final, marker="o")
    ax.set_xticks(STIFFNESSES, [f"{E:g}" for E in STIFFNESSES])
    ax.tick_params(axis="x", which="minor", bottom=False, labelbottom=False)
    ax.set_xlabel("wall Young modulus E")
    ax.set_ylabel(f"growth_rate_area at t = {base.time.t_max:g}")
    ax.set_title("Strain law: softer walls grow faster")
    figure.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(figure, dpi=100, bbox_inches="tight")
    print(f"wrote {figure}")


if __name__ == "__main__":
    main()
