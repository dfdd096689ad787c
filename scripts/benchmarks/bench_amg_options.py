"""BoomerAMG's options on the organ scene's own runs: what CG's iterations cost and how many a
step needs (issue 33, "whole runs at the solver's floor").

The macro solve of scenes/organ_E_gradient.toml (1,001,900 fine dofs, CG + BoomerAMG) is most
of the organ's step: in a ``-log_view`` of its steps 0-2 on 2 ranks, the multigrid cycles
(PCApply) took 17.0 of KSPSolve's 18.3 s. Each variant below is a set of PETSc options under
the macro solver's prefix (``plantgrowth_macro_``), given through ``PETSC_OPTIONS`` to an
otherwise unchanged run of the scene to ``--t-max`` on ``--ranks`` ranks; the variants run
interleaved, ``--repeats`` times (A B C A B C ...), cell cache off, PT-SCOTCH on one thread (as
bench_organ.py). Per run: every step's CG iterations (run.log), the solve phase summed over the
steps (summary.csv's seconds_solve: assembly, initial guess, set-ups and CG), its seconds per CG
iteration, the wall time and the area at t_max (a variant changes the answers by the solver's
tolerance only). Writes benchmarks/results/amg_options.json (``--out``) with the machine and
its load average before and after.

    python scripts/benchmarks/bench_amg_options.py [--t-max 2] [--ranks 2] [--repeats 1]
        [--variants default chebyshev ...] [--label L] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
from pathlib import Path

from bench_cg_steps import digest, parse_log
from bench_naive import summary_rows, timed_run
from bench_organ import SCENE, short_scene
from bench_ranks import MPI_ENV

from plantgrowth.base.machine import machine_description

PREFIX = "-plantgrowth_macro_pc_hypre_boomeramg_"
VARIANTS = {
    "default": {},
    "chebyshev": {"relax_type_all": "Chebyshev"},
    "l1_jacobi": {"relax_type_all": "l1scaled-Jacobi"},
    "l1_sor": {"relax_type_all": "l1scaled-SOR/Jacobi"},
    "ext_i_pmax4": {"interp_type": "ext+i", "P_max": "4"},
    "hmis_ext_i_pmax4": {"coarsen_type": "HMIS", "interp_type": "ext+i", "P_max": "4"},
    "pmis_ext_i_pmax4": {"coarsen_type": "PMIS", "interp_type": "ext+i", "P_max": "4"},
    "threshold_035": {"strong_threshold": "0.35"},
}
"""BoomerAMG options (PETSc's names, without the prefix) per variant; ``default`` is the shipped
solver (plantgrowth.models.linear.BOOMERAMG_OPTIONS: PETSc's defaults)."""


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--t-max", type=float, default=2.0, help="time.t_max (dt = 1)")
    parser.add_argument("--ranks", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    parser.add_argument("--label", default=None, help="key of this study in the results file")
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).resolve().parents[2]
                        / "benchmarks/results/amg_options.json")  # fmt: skip
    return parser.parse_args(argv)


def petsc_options(variant: str) -> str:
    """The PETSC_OPTIONS value of a variant."""
    return " ".join(f"{PREFIX}{key} {value}" for key, value in VARIANTS[variant].items())


def run_variant(variant: str, scene: Path, ranks: int, outdir: Path, log: Path) -> dict:
    """One run of the scene with the variant's options: CG per step, solve seconds, wall."""
    options = petsc_options(variant)
    env = dict(os.environ, **MPI_ENV, SCOTCH_PTHREAD_NUMBER="1", PETSC_OPTIONS=options)
    exe = Path(sys.executable).with_name("plantgrowth")
    command = ["/usr/bin/mpirun", "-n", str(ranks), exe, "run", scene, "-o", outdir]
    wall, _ = timed_run(command if ranks > 1 else command[3:], env, log)
    rows = summary_rows(outdir)
    cg = digest(parse_log((outdir / "run.log").read_text()))
    solve = sum(r["seconds_solve"] for r in rows)
    return {"wall_seconds": wall, "solve_seconds": solve, "cg": cg,
            "solve_seconds_per_cg_iteration": solve / cg["total_cg"],
            "area_at_t_max": rows[-1]["area"]}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    study = {
        "command": "python scripts/benchmarks/bench_amg_options.py " + " ".join(sys.argv[1:]),
        "scene": str(SCENE.relative_to(SCENE.parents[1])), "t_max": args.t_max,
        "ranks": args.ranks, "repeats": args.repeats,
        "options": {v: petsc_options(v) for v in args.variants},
        "machine": machine_description(), "load_average_before": os.getloadavg(),
    }  # fmt: skip
    runs: dict[str, list[dict]] = {v: [] for v in args.variants}
    with tempfile.TemporaryDirectory(prefix="plantgrowth-bench-amg-") as tmp:
        tmp = Path(tmp)
        scene = tmp / "organ.toml"
        scene.write_text(short_scene(args.t_max))
        for repeat in range(args.repeats):
            for variant in args.variants:  # interleaved
                record = run_variant(variant, scene, args.ranks, tmp / f"{variant}-{repeat}",
                                     tmp / "log.txt")  # fmt: skip
                runs[variant].append(record)
                print(f"{variant} #{repeat}: CG {record['cg']['total_cg']}, solve "
                      f"{record['solve_seconds']:.1f} s, wall {record['wall_seconds']:.1f} s",
                      flush=True)  # fmt: skip
    study["runs"] = runs
    study["medians"] = {
        v: {key: statistics.median(r[key] for r in rs)
            for key in ("wall_seconds", "solve_seconds", "solve_seconds_per_cg_iteration")}
        for v, rs in runs.items()
    }  # fmt: skip
    study["load_average_after"] = os.getloadavg()
    results = json.loads(args.out.read_text()) if args.out.is_file() else {}
    label = args.label or f"t{args.t_max:g}_ranks{args.ranks}"
    results[label] = study
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=1) + "\n")
    print(json.dumps(study["medians"], indent=1))
    print(f"wrote {args.out} [{label}]")
    return 0


if __name__ == "__main__":
    sys.exit(main())
