"""A naive coupled solver against the project (issue 9): whole-process wall times.

The naive solver is the project's macro loop (``MacroModel``, ``run_model``: macro solve, growth
update, output) with the cell problems done as a user would write them: at every step and every
coarse node a new ``CellSolver`` (mesh, constraint, forms) and a direct assembly of the UFL forms
of [UC_weak]/[UCw_weak] with the node's own Fg, E, nu (the reference route of
tests/test_cell_solver_fast.py, imported from there): no cache, no rounding of inputs, no
surrogate. It runs ``scenes/gradient_E_strain.toml`` with ``time.t_max`` cut to 10 (steps
t = 0..10), as does ``plantgrowth run`` with the accuracy the shipped scene resolves to
("default": the accuracy preset; were its cell_tolerance 0, as before the presets, 1e-3 would be
set) and with ``accuracy.cell_tolerance = 0`` ("exact"). Each variant is timed as the wall time
of a whole process (imports included), median of ``--repeats`` runs, after one untimed
warm-up run with t_max = 1 (JIT cache), with ``PLANTGROWTH_CACHE_DIR=off``. The naive run's
area and u are compared with the exact run's, and with one more exact run whose cache keys are
rounded to 1e-12 only (equal to round-off: the same model). Outputs go to a temporary directory.

    python scripts/benchmarks/bench_naive.py [--repeats 3] [--t-max 10] [--out FILE]
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import json
import logging
import os
import re
import statistics
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "scenes" / "gradient_E_strain.toml"
REFERENCE_TEST = REPO / "tests" / "test_cell_solver_fast.py"
WARMUP_T_MAX = 1.0
"""The shortest run of the scene (dt = 1: steps t = 0, 1), untimed, to warm the JIT cache."""
FINE_KEY_TOLERANCE = 1e-12
"""``accuracy.key_tolerance`` of the verification run: the exact path with its cache keys
rounded to round-off only."""
IMPORTS = (
    "import plantgrowth.api, plantgrowth.cli.commands, plantgrowth.runner.timeloop, "
    "plantgrowth.scene"
)
"""What ``plantgrowth run`` imports before it starts (cli.main and its ``run`` handler)."""
PHASES = ("seconds", "seconds_cells", "seconds_solve", "seconds_growth", "seconds_io")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3, help="timed runs per variant")
    parser.add_argument("--t-max", type=float, default=10.0, help="time.t_max of the runs")
    parser.add_argument(
        "--out", type=Path, default=REPO / "benchmarks/results/naive_vs_project.json"
    )
    parser.add_argument(
        "--naive",
        nargs=2,
        type=Path,
        metavar=("SCENE", "DIR"),
        help="(internal) run the naive solver on SCENE into DIR in this process",
    )
    return parser.parse_args(argv)


def scene_text(
    path: Path, t_max: float, accuracy: dict[str, float], tissue: dict[str, float] | None = None
) -> str:
    """The resolved scene of ``path`` with ``time.t_max`` and the given ``[accuracy]`` (and
    ``[tissue]``) keys."""
    import plantgrowth as pg

    with open(path, "rb") as f:
        data = tomllib.load(f)
    data.setdefault("time", {})["t_max"] = t_max
    data.setdefault("accuracy", {}).update(accuracy)
    data.setdefault("tissue", {}).update(tissue or {})
    return pg.Scene.from_dict(data, directory=path.parent).to_toml()


def _reference_route():
    """``_Reference`` of tests/test_cell_solver_fast.py: the direct assembly of the UFL forms."""
    spec = importlib.util.spec_from_file_location("cell_reference_route", REFERENCE_TEST)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module._Reference


class NaiveHomogenizer:
    """Cell problems as a user writes them: per node a new cell mesh, solver and assembly.

    Args:
        resolution: elements across a wall.
        pressure: keep K_hom and dbar[v] (P1 not zero).
        strain_averages: keep dbar[w], dbar[v] (strain law or eps_hom output).
    """

    def __init__(self, resolution: int, pressure: bool, strain_averages: bool) -> None:
        self.resolution = resolution
        self.pressure = pressure
        self.strain_averages = strain_averages
        self.solves_last_call = 0
        self.setup_seconds = 0.0  # CellSolver and reference forms
        self.solve_seconds = 0.0  # assembly, factorization, four solves, averages
        self.solves = 0
        self._Reference = _reference_route()

    def homogenize(self, geometry: np.ndarray, E: np.ndarray, nu: np.ndarray, Fg: np.ndarray):
        """``NodeTensors`` at n nodes from (n, 4) geometry, (n,) E and nu, (n, 2, 2) Fg."""
        from mpi4py import MPI

        from plantgrowth.base.tensors import voigt_matrix
        from plantgrowth.meshes.honeycomb import HoneycombCell
        from plantgrowth.unitcell.homogenization import NodeTensors
        from plantgrowth.unitcell.solver import CellSolver

        out = {"C": [], "phi_w": [], "K": [], "dbar_w": [], "dbar_v": [], "P2_matrix": []}
        for g, E_n, nu_n, Fg_n in zip(geometry, E, nu, Fg, strict=True):
            start = time.perf_counter()
            solver = CellSolver(HoneycombCell(*g), self.resolution, MPI.COMM_SELF)
            reference = self._Reference(solver)
            middle = time.perf_counter()
            r = reference.solve(Fg_n, float(E_n), float(nu_n))
            self.setup_seconds += middle - start
            self.solve_seconds += time.perf_counter() - middle
            out["C"].append(voigt_matrix(r["E_hom"]))
            out["phi_w"].append(solver.wall_area / solver.area)
            out["K"].append(r["K_hom"])
            out["dbar_w"].append(r["dbar_w"])
            out["dbar_v"].append(r["dbar_v"])
            out["P2_matrix"].append(solver.P2_matrix)
        self.solves_last_call = len(Fg)
        self.solves += len(Fg)
        kept = {"K": self.pressure, "dbar_w": self.strain_averages,
                "dbar_v": self.pressure and self.strain_averages}  # fmt: skip
        return NodeTensors(
            **{k: np.array(v) if kept.get(k, True) else None for k, v in out.items()}
        )


def run_naive(scene_path: Path, outdir: Path) -> None:
    """The coupled loop with :class:`NaiveHomogenizer`; writes ``outdir/naive.json`` (set-up and
    cell-problem seconds) next to the run's usual files."""
    from mpi4py import MPI

    import plantgrowth as pg
    from plantgrowth.models.macro.model import macro_model
    from plantgrowth.runner.output import prepare_directory
    from plantgrowth.runner.timeloop import run_model

    comm = MPI.COMM_WORLD
    if comm.size > 1:
        raise SystemExit("the naive solver runs on one rank (it solves every node itself)")
    scene = pg.load_scene(scene_path)
    prepare_directory(outdir, comm)
    start = time.perf_counter()
    model = macro_model(scene, comm)
    h = model.homogenizer
    model.homogenizer = NaiveHomogenizer(h.resolution, h.pressure, h.strain_averages)
    setup = time.perf_counter() - start
    (outdir / "scene.toml").write_text(scene.to_toml())
    run_model(model, scene, outdir, comm)
    naive = model.homogenizer
    timing = {"setup_seconds": setup, "cell_setup_seconds": naive.setup_seconds,
              "cell_solve_seconds": naive.solve_seconds, "cell_problems": naive.solves}  # fmt: skip
    (outdir / "naive.json").write_text(json.dumps(timing, indent=1) + "\n")


def timed_run(command: list, env: dict[str, str], log: Path) -> tuple[float, float]:
    """Wall seconds and peak resident memory (MiB) of a process that must succeed (command[0]
    an absolute path); its output goes to ``log``."""
    args = [str(c) for c in command]
    with open(log, "w") as out:
        redirect = [(os.POSIX_SPAWN_DUP2, out.fileno(), 1), (os.POSIX_SPAWN_DUP2, out.fileno(), 2)]
        start = time.perf_counter()
        pid = os.posix_spawn(args[0], args, env, file_actions=redirect)
        _, status, usage = os.wait4(pid, 0)
        seconds = time.perf_counter() - start
    code = os.waitstatus_to_exitcode(status)
    if code:
        raise RuntimeError(f"{' '.join(args)} failed ({code}):\n{log.read_text()}")
    return seconds, usage.ru_maxrss / 1024  # ru_maxrss is in KiB on Linux


def summary_rows(outdir: Path) -> list[dict[str, float]]:
    with open(outdir / "summary.csv", newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def run_record(outdir: Path, wall: float, memory: float) -> dict:
    """Wall time, peak memory, per-phase totals of summary.csv and the set-up seconds of
    run.log (naive.json for the naive runs)."""
    rows = summary_rows(outdir)
    record = {"wall_seconds": wall, "max_rss_mib": memory, "steps": len(rows)}
    record.update({f"{p}_total": sum(r[p] for r in rows) for p in PHASES})
    record["cell_solves"] = int(sum(r["n_cell_solves"] for r in rows))
    if (outdir / "naive.json").exists():
        record.update(json.loads((outdir / "naive.json").read_text()))
    else:
        setup = re.search(r"set-up: ([0-9.]+) s", (outdir / "run.log").read_text())
        record["setup_seconds"] = float(setup.group(1))
    # imports, scene, run directory, JIT cache look-ups, exit: what is neither set-up nor steps
    record["rest_seconds"] = wall - record["setup_seconds"] - record["seconds_total"]
    return record


def differences(outdir: Path, reference: Path) -> dict[str, float]:
    """Largest relative differences of area (over steps) and of u at the last step."""
    import plantgrowth as pg

    rows, ref_rows = summary_rows(outdir), summary_rows(reference)
    area = max(
        abs(a["area"] - b["area"]) / abs(b["area"]) for a, b in zip(rows, ref_rows, strict=True)
    )
    u, u_ref = (pg.read_results(d).field("u") for d in (outdir, reference))  # at the last time
    return {
        "final_area": abs(rows[-1]["area"] - ref_rows[-1]["area"]) / abs(ref_rows[-1]["area"]),
        "area_any_step": area,
        "u_final": float(np.abs(u - u_ref).max() / np.abs(u_ref).max()),
    }


def basis_seconds(resolution: int, repeats: int = 5) -> float:
    """Median seconds of one ``GradientBasis`` (built by every ``CellSolver``, unused by the
    naive route) on the reference cell."""
    import ufl
    from mpi4py import MPI

    from plantgrowth.meshes.honeycomb import HoneycombCell
    from plantgrowth.meshes.unit_cell import CELL_TAGS
    from plantgrowth.unitcell.gradient_basis import GradientBasis
    from plantgrowth.unitcell.solver import CellSolver

    solver = CellSolver(HoneycombCell(), resolution, MPI.COMM_SELF)
    cell_tags = solver.unit_cell.cell_tags
    dx = ufl.Measure("dx", domain=solver.V.mesh, subdomain_data=cell_tags)(CELL_TAGS["walls"])
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        GradientBasis(solver.V, solver.mpc, solver.bcs, [dx])
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def run_variant(
    name: str, scenes: dict[str, Path], tmp: Path, repeats: int, env: dict[str, str]
) -> dict:
    """An untimed warm-up and ``repeats`` timed runs of one variant ("naive", or a
    ``plantgrowth run``); the output directory of the median run is ``tmp/<name>_median``."""

    def command(label: str, outdir: Path) -> list:
        if name == "naive":
            return [sys.executable, __file__, "--naive", scenes[label], outdir]
        return [Path(sys.executable).with_name("plantgrowth"), "run", scenes[label], "-o", outdir]

    if "warmup" in scenes:
        timed_run(command("warmup", tmp / f"{name}_warmup"), env, tmp / f"{name}_warmup.log")
    runs = []
    for k in range(repeats):
        outdir = tmp / f"{name}_{k}"
        wall, memory = timed_run(command("timed", outdir), env, tmp / f"{name}_{k}.log")
        runs.append(run_record(outdir, wall, memory))
        print(f"{name} run {k}: {wall:.2f} s", flush=True)
    median = sorted(range(repeats), key=lambda k: runs[k]["wall_seconds"])[repeats // 2]
    (tmp / f"{name}_{median}").rename(tmp / f"{name}_median")
    resolved = tomllib.loads((tmp / f"{name}_median" / "scene.toml").read_text())
    return {
        "median_wall_seconds": runs[median]["wall_seconds"],
        "accuracy": resolved["accuracy"],
        "runs": runs,
    }


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    if args.naive is not None:
        run_naive(*args.naive)
        return 0
    from plantgrowth.base.machine import machine_description

    load_before = os.getloadavg()
    exact = {"cell_tolerance": 0.0}
    variants = {"default": {}, "exact": exact, "naive": exact}
    env = dict(os.environ, PLANTGROWTH_CACHE_DIR="off")  # no on-disk cell cache
    results = {}
    with tempfile.TemporaryDirectory(prefix="plantgrowth-bench-naive-") as tmp:
        tmp = Path(tmp)
        for name, accuracy in variants.items():
            scenes = {}
            for label, t_max in (("warmup", WARMUP_T_MAX), ("timed", args.t_max)):
                scenes[label] = tmp / f"{name}_{label}.toml"
                scenes[label].write_text(scene_text(SCENE, t_max, accuracy))
            results[name] = run_variant(name, scenes, tmp, args.repeats, env)
            results[name]["accuracy_override"] = accuracy
        # the exact path without the rounding of its cache keys: equal to naive up to round-off
        fine_keys = {**exact, "key_tolerance": FINE_KEY_TOLERANCE}
        scene = tmp / "exact_fine_keys_timed.toml"
        scene.write_text(scene_text(SCENE, args.t_max, fine_keys))
        run_variant("exact_fine_keys", {"timed": scene}, tmp, 1, env)
        imports = [
            timed_run([sys.executable, "-c", IMPORTS], env, tmp / "imports.log")[0]
            for _ in range(args.repeats)
        ]
        checks = {
            f"{a}_vs_{b}": differences(tmp / f"{a}_median", tmp / f"{b}_median")
            for a, b in (("naive", "exact_fine_keys"), ("naive", "exact"), ("default", "exact"))
        }
    naive = results["naive"]["median_wall_seconds"]
    ratios = {f"naive/{k}": naive / results[k]["median_wall_seconds"] for k in ("default", "exact")}
    logging.getLogger().setLevel(logging.WARNING)  # quiet the JIT's compiler log
    basis = basis_seconds(results["exact"]["accuracy"]["cell_resolution"])
    without_basis = naive - results["naive"]["runs"][0]["cell_problems"] * basis
    result = {
        "description": "naive coupled solver (new cell mesh and solver per node and step, direct "
        "UFL assembly, no cache) against plantgrowth run, whole-process wall seconds",
        "command": "python " + " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        "scene": str(SCENE.relative_to(REPO)),
        "t_max": args.t_max,
        "repeats": args.repeats,
        "timing_notes": (
            "median wall time of a whole subprocess (imports included) per variant, after one "
            f"untimed warm-up run of t_max = {WARMUP_T_MAX:g} (JIT cache warm); "
            "PLANTGROWTH_CACHE_DIR=off in every run, so the on-disk cell cache does not help; "
            "every run writes its fields and summary.csv as plantgrowth run does. default: the "
            "shipped scene's accuracy (accuracy_override lists what was changed); exact: "
            "cell_tolerance = 0. Per run: summary.csv phase totals, set-up (run.log; naive: "
            "naive.json), rest_seconds = wall - set-up - steps (imports, scene, run directory, "
            "exit), max_rss_mib of the process."
        ),
        "seconds": {k: v["median_wall_seconds"] for k, v in results.items()},
        "ratios": ratios,
        "project_import_seconds": {
            "note": f"median wall seconds of a process that only runs {IMPORTS!r}: the part of "
            "rest_seconds that is imports",
            "seconds": statistics.median(imports),
        },
        "naive_basis_overhead": {
            "note": "every CellSolver also builds its GradientBasis, which the direct route does "
            "not use; naive seconds without it estimated as naive - cell problems x basis seconds",
            "basis_seconds": basis,
            "naive_seconds_without_basis": without_basis,
            "ratio_to_default": without_basis / results["default"]["median_wall_seconds"],
        },
        "relative_differences": {
            "note": "largest relative difference of the area over all steps and at the last "
            "step, and of u at the last step (relative to max |u|); exact_fine_keys: the exact "
            f"path with accuracy.key_tolerance = {FINE_KEY_TOLERANCE:g} (one untimed run)",
            **checks,
        },
        "variants": results,
        "load_average_1_5_15": {"before": list(load_before), "after": list(os.getloadavg())},
        "machine": machine_description(),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps({"seconds": result["seconds"], "ratios": ratios, **checks}, indent=1))
    print(f"load average before {load_before}, after {os.getloadavg()}; wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
