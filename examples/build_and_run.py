"""Build a scene in Python, run it, and print the final area and mean growth rate.

    python examples/build_and_run.py OUTDIR [--overwrite]

The scene is a small tissue whose walls are twice as extensible on the right as on the left
(growth.eta from 0.5 to 2.0 along x1), at the draft preset: a few seconds. OUTDIR receives
the run's files (summary.csv, fields.xdmf, ...: docs/outputs.md); open OUTDIR/fields.xdmf in
ParaView, or draw a field with examples/plot_field.py OUTDIR PICTURES. Under
``mpirun -n 2 python examples/build_and_run.py OUTDIR`` the run is shared by the two ranks.
"""

import argparse
from pathlib import Path

from mpi4py import MPI

import plantgrowth as pg


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("outdir", type=Path, help="output directory of the run")
    parser.add_argument("--overwrite", action="store_true", help="replace an earlier run there")
    args = parser.parse_args()

    # The same tables and keys as a scene file (plantgrowth/scene/__init__.py lists them all);
    # every key left out takes its default, and the preset sets h, H, dt and the cell accuracy.
    scene = pg.Scene.from_dict(
        {
            "tissue": {"width": 4.0, "height": 2.0},
            "growth": {"law": "stress", "eta": {"from": 0.5, "to": 2.0}},
            "time": {"t_max": 10},
            "accuracy": {"preset": "draft"},
        }
    )

    # Runs as `plantgrowth run` does: bad input raises pg.InputError before anything is
    # written, a failed step pg.RunError after every completed step is written.
    results = pg.run(scene, args.outdir, overwrite=args.overwrite)

    # summary.csv as numpy arrays, one entry per step: the last entry is t = t_max.
    summary = results.summary
    t, area = summary["t"][-1], summary["area"][-1]
    rate = summary["growth_rate_area"][-1]  # tr G averaged over the tissue: d ln(area)/dt
    if MPI.COMM_WORLD.rank == 0:  # every rank has the results; print once
        print(f"final area at t = {t:g}: {float(area)!r}")
        print(f"mean growth rate (growth_rate_area) at t = {t:g}: {float(rate)!r}")


if __name__ == "__main__":
    main()
