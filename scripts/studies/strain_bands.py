"""The largest elastic strain each shipped example reaches (issue 21, item 3): the measurement
behind the strain warnings' bands (plantgrowth/runner/step_warnings.py, STRAIN_BANDS).

Runs every example scene (``scenes/*.toml`` but the 1-million-dof organ, ``scenes/biology``,
``scenes/shapes``, the scenes of ``scenes/examples`` and the pull of docs/usage.md: the
reference scene with ``left = [-0.0002, 0]``, ``right = [0.0002, 0]``) with
``accuracy.preset = "draft"`` (the scene's own h, H and dt dropped), in this process, one after
the other, and records from each run's summary.csv the largest ``elastic_strain_max`` over the
steps run, its time and place, the time reached, and the last area and mean growth rate
(``--kinematics finite``: the same runs with finite kinematics, to see how far the linear ones
are off). Results: ``benchmarks/results/strain_bands.json``; runs under ``results/strain_bands/``.

    python scripts/studies/strain_bands.py [--only reference_stress,...] [--t-max 60]
        [--kinematics finite]
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from collections.abc import Callable
from pathlib import Path

from mpi4py import MPI

import plantgrowth as pg

sys.path.insert(0, str(Path(__file__).resolve().parent))
from finite_vs_linear import variant  # noqa: E402  (a sibling script, not a package)

PULL = {"left": [-0.0002, 0.0], "right": [0.0002, 0.0]}
"""The balanced pull docs/usage.md gives as its example of loads."""


def example_scenes() -> dict[str, tuple[Path, dict]]:
    """name -> (scene file, extra keys) of every shipped example."""
    files = [p for p in sorted(Path("scenes").glob("*.toml")) if p.stem != "organ_E_gradient"]
    files += sorted(Path("scenes/biology").glob("*.toml"))
    files += sorted(Path("scenes/shapes").glob("*.toml"))
    files += [Path(f"scenes/examples/{name}.toml") for name in ("soft_disc", "held_and_pulled")]
    scenes = {p.stem: (p, {}) for p in files}
    scenes["usage_pull"] = (Path("scenes/reference_stress.toml"), {"loads": PULL})
    return scenes


def largest(summary: Path) -> dict:
    """The row of the largest elastic_strain_max in a summary.csv, and the last t."""
    with open(summary, newline="") as f:
        rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
    top = max(rows, key=lambda r: r["elastic_strain_max"])
    return {
        "elastic_strain_max": top["elastic_strain_max"],
        "t": top["t"],
        "x1": top["elastic_strain_max_x1"],
        "x2": top["elastic_strain_max_x2"],
        "at_t0": rows[0]["elastic_strain_max"],
        "t_reached": rows[-1]["t"],
        "area_end": rows[-1]["area"],
        "growth_rate_area_end": rows[-1]["growth_rate_area"],
    }


def run_measured(
    scene: pg.Scene, outdir: Path, name: str, measure: Callable[[Path], dict], comm: MPI.Comm
) -> dict[str, dict]:
    """Run ``scene`` into ``outdir`` (a RunError is its ``stop``); ``measure(summary.csv)`` and
    the stop of each side, by key: ``name``, or ``name/macro`` and ``name/micro``."""
    stop = ""
    try:
        pg.run(scene, outdir, comm, overwrite=True, label=f"{Path(sys.argv[0]).stem} {name}")
    except pg.RunError as err:
        stop = str(err)
    sides = ["macro", "micro"] if scene.model == "both" else [""]
    return {
        f"{name}/{side}" if side else name: measure(outdir / side / "summary.csv") | {"stop": stop}
        for side in sides
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", type=lambda s: s.split(","), default=None, help="scene names")
    parser.add_argument("--t-max", type=float, default=None, help="override time.t_max")
    parser.add_argument("--kinematics", default="linear", help="linear or finite")
    parser.add_argument("--out", type=Path, default=Path("results/strain_bands"))
    parser.add_argument("--json", type=Path, default=Path("benchmarks/results/strain_bands.json"))
    args = parser.parse_args(argv)
    comm = MPI.COMM_WORLD
    found = json.loads(args.json.read_text()) if args.json.exists() else {}
    for name, (path, extra) in example_scenes().items():
        if args.only is not None and name not in args.only:
            continue
        scene = variant(path, args.kinematics, "draft", args.t_max, extra)
        name = name if args.kinematics == "linear" else f"{name}/{args.kinematics}"
        for key, row in run_measured(scene, args.out / name, name, largest, comm).items():
            found[key] = row
            if comm.rank == 0:
                print(key, json.dumps(row), flush=True)
    if comm.rank == 0:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(found, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
