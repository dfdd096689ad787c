"""Output seconds per step, 1 and 2 ranks, this checkout against a baseline (issue 23, item 2).

What one step's output costs in a run: the step file (FieldSeries.write), the model's resume
state (MacroModel.state) and state.h5 (StateFile.write), wall seconds (largest over the ranks)
and CPU seconds of the busiest rank. Each measurement builds the scene's
macro model, solves its first step once (so the fields hold a run's values, which compress as a
run's do) and then writes ``--writes`` steps, timing each part; the median over the writes and
repeats is kept. Versions and rank counts are interleaved (repeat 1: this, baseline at 1 rank,
then at 2 ranks; repeat 2 ...), so a change of the machine's load hits both. The baseline is
``git archive``'d into a temporary directory and imported through PYTHONPATH with this
checkout's venv (the same dolfinx, h5py, PETSc).

    python scripts/benchmarks/bench_output.py SCENE [--t-max T] [--baseline COMMIT]
        [--repeats 3] [--writes 4] [--out benchmarks/results/output.json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_ranks import MPI_ENV

REPO = Path(__file__).resolve().parents[2]
PYTHON = REPO / ".venv" / "bin" / "python"
PARTS = ("fields", "state", "state_file")
CPU = tuple(f"cpu_{part}" for part in PARTS)
"""The same parts in CPU seconds of the busiest rank (``time.process_time``): what the rank
itself computes, which a loaded machine does not inflate as it does wall time (it still counts
MPI's busy waiting)."""


def inner(scene_path: Path, outdir: Path, writes: int, record: Path) -> None:
    """In one (mpirun) process group: set up, one solve, ``writes`` timed outputs."""
    from mpi4py import MPI

    from plantgrowth.runner.output import FieldSeries, Schedule, StateFile, prepare_directory
    from plantgrowth.runner.scene_run import checked_domain, model_on
    from plantgrowth.scene import load_scene

    comm = MPI.COMM_WORLD
    scene = load_scene(scene_path)
    prepare_directory(outdir, comm)
    model = model_on(checked_domain(scene, comm), comm)
    series = FieldSeries(outdir, model.output_space, model.outputs, Schedule(1, writes),
                         scene.output.precision, model.side_output)  # fmt: skip
    state = StateFile(outdir, comm)
    Fg = model.initial_growth()
    G = model.step(Fg).G
    times: dict[str, list[float]] = {part: [] for part in PARTS + CPU}
    for step in range(writes):
        marks = [(time.perf_counter(), time.process_time())]
        series.write(step, float(step))
        marks.append((time.perf_counter(), time.process_time()))
        snapshot = model.state(Fg, G)
        marks.append((time.perf_counter(), time.process_time()))
        state.write(step, float(step), snapshot)
        marks.append((time.perf_counter(), time.process_time()))
        for k, (a, b) in enumerate(zip(marks, marks[1:], strict=False)):
            times[PARTS[k]].append(comm.allreduce(b[0] - a[0], op=MPI.MAX))
            times[CPU[k]].append(comm.allreduce(b[1] - a[1], op=MPI.MAX))
    if comm.rank == 0:
        dofs = model.problem.ndofs
        record.write_text(json.dumps({"dofs": dofs, "times": times}))


def measure(source: Path, ranks: int, scene: Path, writes: int, work: Path) -> dict:
    """One inner run of ``source``'s plantgrowth on ``ranks`` ranks."""
    record = work / "record.json"
    env = dict(os.environ, **MPI_ENV, PYTHONPATH=str(source))
    command = ["mpirun", "-n", str(ranks), str(PYTHON), __file__, "--inner", str(scene),
               str(work / "out"), "--writes", str(writes), "--record", str(record)]  # fmt: skip
    subprocess.run(command, env=env, check=True, capture_output=True, text=True)
    return json.loads(record.read_text())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", type=Path)
    parser.add_argument("--baseline", default="c384766")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--writes", type=int, default=4)
    parser.add_argument("--out", type=Path, default=REPO / "benchmarks/results/output.json")
    parser.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("outdir", type=Path, nargs="?", help=argparse.SUPPRESS)
    parser.add_argument("--record", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.inner:
        inner(args.scene, args.outdir, args.writes, args.record)
        return
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "baseline"
        base.mkdir()
        archive = subprocess.run(["git", "-C", str(REPO), "archive", args.baseline],
                                 check=True, capture_output=True).stdout  # fmt: skip
        subprocess.run(["tar", "-x", "-C", str(base)], input=archive, check=True)
        versions = {"now": REPO, "baseline": base}
        samples: dict[str, dict[str, list[float]]] = {}
        dofs = None
        for repeat in range(args.repeats):
            for ranks in (1, 2):
                for name, source in versions.items():
                    work = Path(tmp) / f"{name}_{ranks}_{repeat}"
                    work.mkdir()
                    result = measure(source, ranks, args.scene.resolve(), args.writes, work)
                    dofs = result["dofs"]
                    key = f"{name}, {ranks} rank(s)"
                    for part, values in result["times"].items():
                        samples.setdefault(key, {}).setdefault(part, []).extend(values)
                    print(key, {p: round(statistics.median(v), 3) for p, v in
                                result["times"].items()}, flush=True)  # fmt: skip
    medians = {}
    for key, parts in samples.items():
        totals = [sum(x) for x in zip(*(parts[p] for p in PARTS), strict=True)]
        medians[key] = {p: statistics.median(v) for p, v in parts.items()}
        medians[key]["total"] = statistics.median(totals)
    from plantgrowth.base.machine import machine_description

    out = {"machine": machine_description(), "scene": str(args.scene), "fine_dofs": dofs,
           "baseline": args.baseline, "repeats": args.repeats, "writes": args.writes,
           "load_average": os.getloadavg(), "cpus": os.cpu_count(),
           "median_seconds": medians, "samples": samples}  # fmt: skip
    args.out.write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(medians, indent=1))


if __name__ == "__main__":
    sys.exit(main())
