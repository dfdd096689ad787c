"""Speed-up of ``mpirun -n 2`` over one rank (issue 10, item 2), whole wall time.

Scenes (resolved as shipped, ``PLANTGROWTH_CACHE_DIR=off``):
- ``gradient_E_strain``: scenes/gradient_E_strain.toml to t = 60 (the issue's first target);
- ``gradient_w_strain``: scenes/gradient_w_strain.toml to t = 60 (a wall-thickness gradient: a
  cell geometry per coarse column, where the dealing of cell problems matters);
- ``large_direct`` / ``large_iterative``: the E-gradient scene on the 34.6 x 15 tissue (5 x the
  reference in width and height: 104,794 fine dofs, 2,170 coarse nodes at the balanced preset's
  H = 0.5; 576 at H = 1, the issue's count) to t = 10, with ``solver.macro`` direct (LU; MUMPS on
  2 ranks) and iterative (CG + GAMG).
Each run is repeated (``--repeats``, alternating 1 and 2 ranks) and the median wall time kept;
phases from summary.csv of the last repeat (``rest_seconds``: imports, scene, run directory,
JIT cache look-ups and exit, what is neither set-up nor steps). With ``--baseline DIR`` (a
checkout with its own .venv, e.g. ``git worktree add /tmp/base fd1571a``) the same runs of that
version are recorded beside. Load averages before and after go with the numbers: the machine
has 2 cores, and a 2-rank run measured while anything else runs is meaningless.

    python scripts/benchmarks/bench_ranks.py [--repeats 3] [--only NAME ...] [--baseline DIR]
        [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
from pathlib import Path

from bench_naive import PHASES, REPO, run_record, scene_text, timed_run

SCENES = {
    "gradient_E_strain": ("gradient_E_strain.toml", 60.0, {}, {}),
    "gradient_w_strain": ("gradient_w_strain.toml", 60.0, {}, {}),
    "large_direct": ("gradient_E_strain.toml", 10.0, {"macro": "direct"}, {"scale": 5.0}),
    "large_iterative": ("gradient_E_strain.toml", 10.0, {"macro": "iterative"}, {"scale": 5.0}),
}
TARGETS = {"gradient_E_strain": 1.7, "large_direct": 1.8, "large_iterative": 1.8}
"""Issue 10: at least 1.8x on the 576-node tissue, 1.7x on gradient_E_strain."""
MPI_ENV = {
    "OMPI_ALLOW_RUN_AS_ROOT": "1",
    "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
    "OMPI_MCA_rmaps_base_oversubscribe": "1",
    "OMPI_MCA_btl_vader_single_copy_mechanism": "none",
    "PLANTGROWTH_CACHE_DIR": "off",
}


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--only", nargs="*", choices=sorted(SCENES), default=sorted(SCENES))
    parser.add_argument("--baseline", type=Path, help="an older checkout with its own .venv")
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks/results/ranks.json")
    return parser.parse_args(argv)


def resolved_scene(name: str) -> str:
    """The scene text of one benchmark case."""
    import plantgrowth as pg

    file, t_max, solver, tissue = SCENES[name]
    path = REPO / "scenes" / file
    size = {}
    if "scale" in tissue:
        t = pg.load_scene(path).tissue
        size = {"width": tissue["scale"] * t.width, "height": tissue["scale"] * t.height}
    text = scene_text(path, t_max, {}, size)
    if solver:  # the resolved scene has a [solver] table: replace its macro key
        text = text.replace('macro = "auto"', f'macro = "{solver["macro"]}"')
    return text


def measure(checkout: Path, scene: Path, ranks: int, tmp: Path, repeat: int) -> dict:
    """One run of ``checkout``'s plantgrowth on ``ranks`` ranks: wall time, memory, phases."""
    exe = checkout / ".venv" / "bin" / "plantgrowth"
    outdir = tmp / f"{checkout.name}-{scene.stem}-{ranks}-{repeat}"
    command = [exe, "run", scene, "-o", outdir]
    if ranks > 1:
        command = ["/usr/bin/mpirun", "-n", str(ranks), *command]
    wall, memory = timed_run(command, dict(os.environ, **MPI_ENV), tmp / "log.txt")
    return run_record(outdir, wall, memory)


def bench(checkout: Path, names: list[str], repeats: int) -> dict:
    """Median wall times on 1 and 2 ranks and the speed-up per scene, for one checkout."""
    out = {}
    with tempfile.TemporaryDirectory(prefix="plantgrowth-bench-ranks-") as tmp:
        tmp = Path(tmp)
        for name in names:
            scene = tmp / f"{name}.toml"
            text = resolved_scene(name)
            if checkout != REPO:  # an older version may not know the key (its default)
                text = text.replace('kinematics = "linear"\n', "")
            scene.write_text(text)
            runs: dict[int, list[dict]] = {1: [], 2: []}
            for repeat in range(repeats):
                for ranks in (1, 2):
                    runs[ranks].append(measure(checkout, scene, ranks, tmp, repeat))
            walls = {r: statistics.median(x["wall_seconds"] for x in runs[r]) for r in runs}
            out[name] = {
                "wall_seconds": {str(r): walls[r] for r in walls},
                "all_wall_seconds": {str(r): [x["wall_seconds"] for x in runs[r]] for r in runs},
                "speedup": walls[1] / walls[2],
                "phases_last_repeat": {
                    str(r): {p: runs[r][-1][f"{p}_total"] for p in PHASES}
                    | {p: runs[r][-1][p] for p in ("setup_seconds", "rest_seconds")}
                    for r in runs
                },
                "max_rss_mib": {str(r): runs[r][-1]["max_rss_mib"] for r in runs},
                "cell_solves": runs[1][-1]["cell_solves"],
                "target": TARGETS.get(name),
            }
            print(f"{checkout.name} {name}: {walls[1]:.2f} s / {walls[2]:.2f} s "
                  f"= {out[name]['speedup']:.2f}x", flush=True)  # fmt: skip
    return out


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    from plantgrowth.base.machine import machine_description

    result = {
        "description": "whole wall time of plantgrowth run, 1 rank against mpirun -n 2",
        "command": "python scripts/benchmarks/bench_ranks.py " + " ".join(sys.argv[1:]),
        "scenes": {name: resolved_scene(name) for name in args.only},
        "repeats": args.repeats,
        "machine": machine_description(),
        "load_average_before": os.getloadavg(),
    }
    result["current"] = bench(REPO, args.only, args.repeats)
    if args.baseline:
        result["baseline_checkout"] = str(args.baseline)
        result["baseline"] = bench(args.baseline.resolve(), args.only, args.repeats)
    result["load_average_after"] = os.getloadavg()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
