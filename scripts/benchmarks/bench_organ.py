"""The organ scene per phase, 1 and 2 ranks, this checkout against a baseline (issue 23).

scenes/organ_E_gradient.toml (1,001,900 fine dofs, CG + GAMG) run to ``--t-max`` (steps 0 to
t_max) by this checkout and by the baseline's ``plantgrowth`` (``--baseline``: an executable, e.g.
a checkout of 29ac40d with its venv), interleaved per rank count (A B A B ...), so that both meet
the same machine. Per step: the phases of summary.csv (cells, solve, growth, output) and the rest
of the step (other); medians over the steps after step 0 of all repeats (step 0 pays the first
multigrid set-up and cell problems; start-up is outside the steps). Also the whole wall time, the
peak memory and the largest relative difference of the summary's results (area, u, growth rates,
every step) between the two versions; the cell cache is off (as in bench_ranks.py). Writes
benchmarks/results/organ.json with the machine and its load average before and after (2 cores:
a run measured while other jobs run is slower, and a 2-rank run more so).

    python scripts/benchmarks/bench_organ.py --baseline /tmp/base29venv/bin/plantgrowth
        [--t-max 3] [--repeats 2] [--ranks 2 1] [--out FILE]
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

from bench_naive import REPO, summary_rows, timed_run
from bench_ranks import MPI_ENV  # Open MPI as root, oversubscribed; cell cache off

from plantgrowth.base.machine import machine_description

SCENE = REPO / "scenes" / "organ_E_gradient.toml"
PHASES = ("seconds_cells", "seconds_solve", "seconds_growth", "seconds_io")
RESULTS = ("area", "u1_max", "u2_max", "growth_rate_11", "growth_rate_22", "growth_rate_area")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", type=Path, required=True, help="the baseline's plantgrowth")
    parser.add_argument("--t-max", type=float, default=3.0, help="time.t_max (dt = 1)")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--ranks", type=int, nargs="+", default=[2, 1])
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks/results/organ.json")
    return parser.parse_args(argv)


def short_scene(t_max: float) -> str:
    """The shipped scene's text with ``time.t_max`` replaced (text, not the resolved scene: the
    baseline must read it too)."""
    text, n = re.subn(r"(?m)^t_max = .*$", f"t_max = {t_max!r}", SCENE.read_text())
    assert n == 1, "scenes/organ_E_gradient.toml: no single t_max line"
    return text


def run_once(exe: Path, scene: Path, ranks: int, outdir: Path, log: Path) -> dict:
    """One run: wall seconds, peak memory of the launcher's largest child, per-step phases."""
    command = [exe, "run", scene, "-o", outdir]
    if ranks > 1:
        command = ["/usr/bin/mpirun", "-n", str(ranks), *command]
    wall, memory = timed_run(command, dict(os.environ, **MPI_ENV), log)
    rows = summary_rows(outdir)
    steps = [
        {p: r[p] for p in PHASES} | {"other": r["seconds"] - sum(r[p] for p in PHASES),
                                     "seconds": r["seconds"]}
        for r in rows[1:]
    ]  # fmt: skip
    return {"wall_seconds": wall, "max_rss_mib": memory, "steps": steps, "rows": rows,
            "startup_seconds": wall - sum(r["seconds"] for r in rows)}  # fmt: skip


def medians(runs: list[dict]) -> dict[str, float]:
    """Per-step medians of every phase over all runs' steps after step 0."""
    steps = [s for r in runs for s in r["steps"]]
    return {k: statistics.median(s[k] for s in steps) for k in steps[0]}


def largest_difference(runs: list[dict], baseline: list[dict]) -> dict[str, float]:
    """Largest relative difference per result column between any run and the first baseline
    run, over every step."""
    reference = baseline[0]["rows"]
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
    versions = {"new": Path(sys.executable).with_name("plantgrowth"), "baseline": args.baseline}
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
        scene = tmp / "organ.toml"
        scene.write_text(short_scene(args.t_max))
        for ranks in args.ranks:
            for repeat in range(args.repeats):
                for name, exe in versions.items():  # interleaved: new, baseline, new, ...
                    outdir = tmp / f"{name}-{ranks}-{repeat}"
                    record = run_once(exe, scene, ranks, outdir, tmp / "log.txt")
                    runs[name][ranks].append(record)
                    print(f"{name} {ranks} rank(s) #{repeat}: wall {record['wall_seconds']:.1f} s,"
                          f" step {medians([record])['seconds']:.2f} s", flush=True)  # fmt: skip
    per_step = {
        name: {str(r): medians(runs[name][r]) for r in args.ranks} for name in versions
    }  # fmt: skip
    result["per_step_medians"] = per_step
    result["runs"] = runs  # with every run's summary rows
    result["ratio_new_over_baseline"] = {
        str(r): per_step["new"][str(r)]["seconds"] / per_step["baseline"][str(r)]["seconds"]
        for r in args.ranks
    }
    if {1, 2} <= set(args.ranks):
        result["speedup_2_over_1"] = {
            name: per_step[name]["1"]["seconds"] / per_step[name]["2"]["seconds"]
            for name in versions
        }
    result["largest_relative_difference"] = {
        str(r): largest_difference(runs["new"][r], runs["baseline"][r]) for r in args.ranks
    }
    result["load_average_after"] = os.getloadavg()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    keys = ("ratio_new_over_baseline", "largest_relative_difference")
    print(json.dumps({k: result[k] for k in keys}))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
