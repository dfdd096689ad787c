"""Draw one field of a finished (or still running) run on the deformed tissue, to a PNG.

    python examples/plot_field.py RUNDIR OUTDIR [--field G] [--component tr] [--time T]

RUNDIR is a run written by ``plantgrowth run`` or ``pg.run`` (e.g. by
examples/build_and_run.py); it is only read. The picture, OUTDIR/<field>[_<component>]_t<T>.png,
shows the field per triangle of the output mesh moved by the displacement u at time T (default:
the last written time). Tensor fields (Fg, G, sigma_hom, eps_hom) need a component: 11, 12,
21, 22 or tr (the trace; tr G is the areal growth rate); vectors are drawn as their length.
``plantgrowth render`` draws the same and more (docs/outputs.md).
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # draw to files only: no display needed
import matplotlib.pyplot as plt
import numpy as np

import plantgrowth as pg

COMPONENTS = {"11": (0, 0), "12": (0, 1), "21": (1, 0), "22": (1, 1)}


def per_triangle(values: np.ndarray, component: str) -> np.ndarray:
    """One number per triangle: a tensor's component or trace, a vector's length."""
    if values.ndim == 3:  # tensors, (M, 2, 2)
        if component == "tr":
            return values[:, 0, 0] + values[:, 1, 1]
        return values[:, COMPONENTS[component][0], COMPONENTS[component][1]]
    if values.ndim == 2:  # vectors, (M, 2)
        return np.linalg.norm(values, axis=1)
    return values  # scalars, (M,)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rundir", type=Path, help="the run to read")
    parser.add_argument("outdir", type=Path, help="directory for the picture")
    parser.add_argument("--field", default="G", help="a written cell field (default G)")
    parser.add_argument("--component", default="tr", choices=[*COMPONENTS, "tr"])
    parser.add_argument("--time", type=float, default=None, help="default: the last written")
    args = parser.parse_args()

    results = pg.read_results(args.rundir)  # pg.InputError if RUNDIR holds no run
    t = results.times[-1] if args.time is None else args.time
    deformed = results.points + results.field("u", t)  # u at the nodes, (N, 2)
    field = results.field(args.field, t)  # pg.InputError naming the written fields and times
    values = per_triangle(field, args.component)
    if values.shape != (len(results.triangles),):
        raise SystemExit(f"{args.field} is not a cell field: choose one of {results.fields}")
    if field.ndim == 3:  # a tensor: one component, or the trace
        stem = f"{args.field}_{args.component}"
        label = f"tr {args.field}" if args.component == "tr" else stem
    else:
        stem, label = args.field, (f"|{args.field}|" if field.ndim == 2 else args.field)

    fig, ax = plt.subplots(figsize=(7, 4))
    shown = ax.tripcolor(*deformed.T, results.triangles, facecolors=values, cmap="viridis")
    fig.colorbar(shown, ax=ax, label=label)
    ax.set_aspect("equal")
    ax.set_title(f"{label} at t = {t:g} (deformed tissue)")
    args.outdir.mkdir(parents=True, exist_ok=True)
    path = args.outdir / f"{stem}_t{t:g}.png"
    fig.savefig(path, dpi=120, bbox_inches="tight")
    print(f"{label} at t = {t:g}: min {float(values.min())!r}, max {float(values.max())!r}")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
