"""The organ scene per phase, this checkout against a baseline (issues 23, 33).

scenes/organ_E_gradient.toml (1,001,900 fine dofs, CG + GAMG) run to ``--t-max`` (steps 0 to
t_max) by this checkout, once per surrogate interpolant of ``--interpolants`` (the scene's
``accuracy.cell_interpolant`` set), and by the baseline's ``plantgrowth`` (``--baseline``: an
executable, e.g. a checkout of 7c43f7c with its venv, given the scene without that key, which it
predates), interleaved per rank count (A B C A B C ...), so that all meet the same machine. Per
run: the whole wall time (start-up included; issue 33's "whole run"), the peak memory, every
step's CG iterations (issue 33: at most 6 from step 16 on) and the phases of summary.csv (cells,
solve, growth, output) and the rest of the step (other), with their medians over the steps after
step 0 of all repeats (step 0 pays the first multigrid set-up and cell problems); the largest
relative difference of the summary's results (area, u, growth rates, the largest elastic
strain; every step) from the baseline's; with ``--rank-check``, one more run of the first
interpolant on 1 rank and its
summary's largest difference from the 2-rank one (issue 33: within 1e-6). The cell cache is off
(as in bench_ranks.py), and every run, the baseline's too, partitions the mesh with PT-SCOTCH on
one thread (``SCOTCH_PTHREAD_NUMBER=1``, this checkout's default: plantgrowth/__init__.py), so
all runs get the same partition (with SCOTCH's threads it changed from run to run, and the
2-rank CG counts with it). Writes benchmarks/results/organ.json with the machine and its load
average before and after (2 cores: a run measured while other jobs run is slower, and a 2-rank
run more so).

    python scripts/benchmarks/bench_organ.py --baseline /tmp/i33r-venv-7c43f7c/bin/plantgrowth
        [--t-max 3] [--repeats 2] [--ranks 2 1] [--interpolants bilinear c1] [--rank-check]
        [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import sys
import tempfile
from pathlib import Path

from bench_cg_steps import digest, parse_log, with_interpolant
from bench_naive import REPO, summary_rows, timed_run
from bench_ranks import MPI_ENV  # Open MPI as root, oversubscribed; cell cache off

from plantgrowth.base.machine import machine_description

SCENE = REPO / "scenes" / "organ_E_gradient.toml"
PHASES = ("seconds_cells", "seconds_solve", "seconds_growth", "seconds_io")
RESULTS = (
    "area", "u1_max", "u2_max", "growth_rate_11", "growth_rate_22", "growth_rate_area",
    "elastic_strain_max",
)  # fmt: skip
"""The summary columns compared (7c43f7c writes them all); elastic_strain_max, a maximum of grad u
over cells, carries up to about 100 macro_rtol of the CG stop, the others at most 4."""


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", type=Path, required=True, help="the baseline's plantgrowth")
    parser.add_argument("--t-max", type=float, default=3.0, help="time.t_max (dt = 1)")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--ranks", type=int, nargs="+", default=[2, 1])
    parser.add_argument("--interpolants", nargs="+", default=["bilinear"],
                        choices=["bilinear", "c1"], help="this checkout's variants")
    parser.add_argument("--rank-check", action="store_true",
                        help="the first interpolant once more on 1 rank, against its 2 ranks")
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks/results/organ.json")
    return parser.parse_args(argv)


def short_scene(t_max: float) -> str:
    """The shipped scene's text with ``time.t_max`` replaced (text, not the resolved scene: the
    baseline must read it too)."""
    text, n = re.subn(r"(?m)^t_max = .*$", f"t_max = {t_max!r}", SCENE.read_text())
    assert n == 1, "scenes/organ_E_gradient.toml: no single t_max line"
    return text


def baseline_scene(text: str) -> str:
    """The scene's text without ``accuracy.cell_interpolant`` and ``solver.
    macro_spare_iterations``, which the baseline predates (its defaults, the bilinear
    interpolant and CG stopped at macro_rtol, are the baseline's only ones)."""
    return re.sub(r"(?m)^(cell_interpolant|macro_spare_iterations) = .*\n", "", text)


def run_once(exe: Path, scene: Path, ranks: int, outdir: Path, log: Path) -> dict:
    """One run: wall seconds, peak memory of the launcher's largest child, per-step phases and
    CG iterations."""
    command = [exe, "run", scene, "-o", outdir]
    if ranks > 1:
        command = ["/usr/bin/mpirun", "-n", str(ranks), *command]
    wall, memory = timed_run(command, dict(os.environ, **MPI_ENV, SCOTCH_PTHREAD_NUMBER="1"), log)
    rows = summary_rows(outdir)
    steps = [
        {p: r[p] for p in PHASES} | {"other": r["seconds"] - sum(r[p] for p in PHASES),
                                     "seconds": r["seconds"]}
        for r in rows[1:]
    ]  # fmt: skip
    return {"wall_seconds": wall, "max_rss_mib": memory, "steps": steps, "rows": rows,
            "startup_seconds": wall - sum(r["seconds"] for r in rows),
            "cg": digest(parse_log(log.read_text()))}  # fmt: skip


def medians(runs: list[dict]) -> dict[str, float]:
    """Per-step medians of every phase over all runs' steps after step 0."""
    steps = [s for r in runs for s in r["steps"]]
    return {k: statistics.median(s[k] for s in steps) for k in steps[0]}


def largest_difference(runs: list[dict], baseline: list[dict]) -> dict[str, float]:
    """Largest relative difference per result column between any run and the first baseline
    run, over every step."""
    return row_difference(runs, baseline[0]["rows"])


def row_difference(runs: list[dict], reference: list[dict]) -> dict[str, float]:
    """Largest relative difference per result column between any run's rows and ``reference``,
    over every step."""
    out = {}
    for column in RESULTS:
        out[column] = max(
            abs(a[column] - b[column]) / max(abs(b[column]), 1e-300)
            for r in runs
            for a, b in zip(r["rows"], reference, strict=True)
        )
    return out


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    this = Path(sys.executable).with_name("plantgrowth")
    versions = {name: this for name in args.interpolants} | {"baseline": args.baseline}
    result = {
        "description": __doc__.split("\n\n")[0],
        "command": "python scripts/benchmarks/bench_organ.py " + " ".join(sys.argv[1:]),
        "t_max": args.t_max,
        "repeats": args.repeats,
        "machine": machine_description(),
        "load_average_before": os.getloadavg(),
        "versions": {k: str(v) for k, v in versions.items()},
    }
    runs: dict[str, dict[int, list[dict]]] = {v: {r: [] for r in args.ranks} for v in versions}
    with tempfile.TemporaryDirectory(prefix="plantgrowth-bench-organ-") as tmp:
        tmp = Path(tmp)
        text = short_scene(args.t_max)
        scenes = {name: tmp / f"organ-{name}.toml" for name in versions}
        for name, scene in scenes.items():
            scene.write_text(baseline_scene(text) if name == "baseline"
                             else with_interpolant(text, name))  # fmt: skip
        for ranks in args.ranks:
            for repeat in range(args.repeats):
                for name, exe in versions.items():  # interleaved: new, baseline, new, ...
                    outdir = tmp / f"{name}-{ranks}-{repeat}"
                    record = run_once(exe, scenes[name], ranks, outdir, tmp / "log.txt")
                    runs[name][ranks].append(record)
                    print(f"{name} {ranks} rank(s) #{repeat}: wall {record['wall_seconds']:.1f} s,"
                          f" step {medians([record])['seconds']:.2f} s, CG from step 16 at most"
                          f" {record['cg']['max_cg_from_step_16']}", flush=True)  # fmt: skip
        if args.rank_check:
            first = args.interpolants[0]
            serial = run_once(this, scenes[first], 1, tmp / "rank-check", tmp / "log.txt")
            two = runs[first][2][0]["rows"]
            result["rank_check"] = {
                "interpolant": first,
                "one_rank_run": serial,
                "largest_relative_difference_1_vs_2_ranks": row_difference([serial], two),
            }
            print(f"rank check: {result['rank_check']['largest_relative_difference_1_vs_2_ranks']}")
    per_step = {
        name: {str(r): medians(runs[name][r]) for r in args.ranks} for name in versions
    }  # fmt: skip
    result["per_step_medians"] = per_step
    result["runs"] = runs  # with every run's summary rows and CG counts
    wall = {
        name: {str(r): statistics.median(x["wall_seconds"] for x in runs[name][r])
               for r in args.ranks}
        for name in versions
    }  # fmt: skip
    result["whole_run_ratio_over_baseline"] = {
        name: {r: wall[name][r] / wall["baseline"][r] for r in wall[name]}
        for name in args.interpolants
    }  # fmt: skip
    result["ratio_new_over_baseline"] = {
        name: {str(r): per_step[name][str(r)]["seconds"] / per_step["baseline"][str(r)]["seconds"]
               for r in args.ranks}
        for name in args.interpolants
    }  # fmt: skip
    if {1, 2} <= set(args.ranks):
        result["speedup_2_over_1"] = {
            name: per_step[name]["1"]["seconds"] / per_step[name]["2"]["seconds"]
            for name in versions
        }
    result["largest_relative_difference"] = {
        name: {str(r): largest_difference(runs[name][r], runs["baseline"][r]) for r in args.ranks}
        for name in args.interpolants
    }  # fmt: skip
    result["load_average_after"] = os.getloadavg()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    keys = ("whole_run_ratio_over_baseline", "ratio_new_over_baseline",
            "largest_relative_difference")
    print(json.dumps({k: result[k] for k in keys}))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
