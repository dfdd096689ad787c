"""Runs that are killed, interrupted or fail leave readable outputs, and ``--resume`` finishes
them exactly as an uninterrupted run would.

The scene is the reference stress scene with an extensibility gradient (so Fg varies in space and
the cell problems change every step), t_max = 40, cell_resolution = 1 and the exact cell path
(cell_tolerance = 0: the surrogate would make the steps so fast that a kill after five steps could
land after the last one): about 0.08 s per step, 4-5 s a run. Subprocess tests are
``skip_in_parallel``; the parallel ones start ``mpirun -n 2`` themselves, in a session of their
own so that ``os.killpg`` reaches mpirun and its ranks. The ``--resume`` argument checks and the
failing-solve test run in-process (also under mpirun).

Tolerances: a resumed run repeats the uninterrupted run's arithmetic (the cell problems are solved
at their rounded keys, so an empty cache after the restart changes nothing): 1e-10 relative leaves
room only for round-off; the parallel run differs from the serial one by the LU factorization
(MUMPS vs PETSc LU, ~1e-14 relative). That holds for the float64 state (state.h5); the fields are
float32, the float64 values rounded once, so values that agree to 1e-10 may still differ there
by one float32 unit in the last place (2**-23 relative).
"""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import meshio
import numpy as np
import pytest
from cli_helpers import finish, processes_mentioning, start
from mpi4py import MPI

from plantgrowth.cli import main
from plantgrowth.models.linear import SolveReport
from plantgrowth.models.macro import problem as macro_problem
from plantgrowth.runner.output import StateFile
from plantgrowth.scene.limits import MACRO_RTOL

pytestmark = pytest.mark.mpi  # scripts/README.md, "Tests": every test also runs on 2 ranks

N_STEPS = 40
SCENE = """\
model = "macro"
[tissue]
width = 6.928203230275509
height = 3.0
h = 0.1
H = 1.0
[growth]
law = "stress"
eta = {from = 0.5, to = 2.0}
[time]
t_max = 40.0
dt = 1.0
[accuracy]
cell_resolution = 1
cell_tolerance = 0.0
"""
EVERY = 7  # output.every of the sparse runs: fields at 0, 7, ..., 35 and 40
STEP_DATASETS = ("u", "Fg", "G", "sigma_hom", "coarse/E1111", "coarse/E2212")
NOT_COMPARED = ("n_cell_solves", "residual")  # the cache restarts empty; round-off
RTOL = 1e-10
ULP32 = 2.0**-23
ITERATIVE_RTOL = 2 * 100 * MACRO_RTOL
"""A run on CG + BoomerAMG resumes to its solver's tolerance, not to round-off: the first step
after the restart starts from u = 0 with a new multigrid hierarchy where the uninterrupted run
started from the projection onto its last solutions with a kept one. Each solve's error is
within 4 macro_rtol in u and 100 macro_rtol in the largest elastic strain (a maximum of grad u;
plantgrowth.scene.limits.MACRO_RTOL), so the two runs agree within twice the latter (measured
with GAMG at the default 1e-8: 1.2e-7 in elastic_strain_max, 6.5e-9 in u1_max, 1.6e-10 in the
state's G; at 1e-7, with BoomerAMG, 8.7e-6 in elastic_strain_max)."""


# --- helpers ------------------------------------------------------------------------------------


def run(argv: list[str], cwd: Path, ranks: int = 1) -> tuple[int, str]:
    return finish(start(argv, cwd, ranks), cwd)


def summary_rows(outdir: Path) -> list[dict[str, float]]:
    path = outdir / "summary.csv"
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def wait_for_rows(proc: subprocess.Popen, outdir: Path, n: int, timeout: float = 120.0) -> None:
    """Poll summary.csv until it has ``n`` data rows (the run must still be going)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            pytest.fail(f"the run ended (code {proc.returncode}) before {n} steps were written")
        try:
            if (outdir / "summary.csv").read_text().count("\n") - 1 >= n:
                return
        except FileNotFoundError:
            pass
        time.sleep(0.005)
    pytest.fail(f"no {n} summary rows after {timeout:g} s")


def kill_session(proc: subprocess.Popen, cwd: Path, marker: str) -> None:
    """SIGKILL the whole session; every process of the run (mpirun and its ranks) must be gone."""
    os.killpg(proc.pid, signal.SIGKILL)
    finish(proc, cwd)
    deadline = time.monotonic() + 10.0
    while processes_mentioning(marker) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert processes_mentioning(marker) == [], "processes of the killed run survive"


def step_files(outdir: Path) -> list[int]:
    return sorted(int(p.stem.split("_")[1]) for p in (outdir / "fields").glob("step_*.h5"))


def written(every: int) -> list[int]:
    """The steps whose fields a run to N_STEPS writes: 0, every every-th step, the last."""
    return [s for s in range(N_STEPS + 1) if s % every == 0 or s == N_STEPS]


def state_steps(outdir: Path) -> list[int]:
    """The steps state.h5 and state_previous.h5 hold."""
    return StateFile(outdir, MPI.COMM_SELF).steps()


def saved_state(outdir: Path, step: int) -> dict[str, np.ndarray]:
    return StateFile(outdir, MPI.COMM_SELF).read(step)


def check_readable(outdir: Path, every: int = 1) -> list[int]:
    """Every visible step file, both XDMF indexes, summary.csv and the state are consistent and
    readable; returns the completed steps (those with a summary row)."""
    rows = [int(r["step"]) for r in summary_rows(outdir)]
    assert rows == list(range(len(rows))) and rows, f"summary.csv rows {rows}"
    steps = step_files(outdir)
    # per step: fields, row, state; a kill between the field file and the row leaves one more
    # file than rows, a kill between the row and the state leaves the state one step behind
    expected = [s for s in written(every) if s <= rows[-1]]
    ahead = [s for s in written(every) if s <= rows[-1] + 1]
    assert steps in (expected, ahead), f"step files {steps}, summary rows up to {rows[-1]}"
    assert state_steps(outdir)[-1] in (rows[-1], rows[-1] - 1)
    with h5py.File(outdir / "fields.h5", "r") as f:
        centroids = f["Mesh/geometry"][...][f["Mesh/topology"][...]].mean(axis=1)
    # the state's cells in the order of the mesh in fields.h5, as the fields are
    midpoints = saved_state(outdir, state_steps(outdir)[-1])["midpoints"]
    mismatch = np.abs(midpoints - centroids)
    assert mismatch.max() < 1e-9, f"cells not in fields.h5's order ({mismatch.max():.3g})"
    for step in steps:
        with h5py.File(outdir / "fields" / f"step_{step:06d}.h5", "r") as f:
            assert f.attrs["step"] == step and f.attrs["t"] == step * 1.0
            for name in STEP_DATASETS:
                assert name in f, f"step {step}: no {name}"
                assert np.all(np.isfinite(f[name][...])), f"step {step}: {name} not finite"
    for xdmf in ("fields.xdmf", "coarse.xdmf"):
        root = ET.parse(outdir / xdmf).getroot()  # complete XML, or this raises
        for item in root.iter("DataItem"):
            file, dataset = item.text.strip().split(":")
            assert (outdir / file).is_file(), f"{xdmf} references a missing {file}"
            with h5py.File(outdir / file, "r") as f:
                assert dataset.lstrip("/") in f
        indexed = [int(g.get("Name").split("_")[1]) for g in root.iter("Grid")
                   if g.get("Name", "").startswith("step_")]  # fmt: skip
        # an index is rewritten right after a step file: a kill in between leaves it one behind
        assert indexed in (steps, steps[:-1]), f"{xdmf} indexes {indexed}, files {steps}"
        reader = meshio.xdmf.TimeSeriesReader(str(outdir / xdmf))
        points, cells = reader.read_points_cells()
        assert reader.num_steps == len(indexed)
        for k in range(reader.num_steps):
            t, point_data, cell_data = reader.read_data(k)
            assert t == indexed[k]
            assert point_data["u" if xdmf == "fields.xdmf" else "E1111"].shape[0] == len(points)
            if xdmf == "fields.xdmf":
                assert cell_data["Fg"][0].shape[0] == len(cells[0].data)
    return rows


def _sorted_by(points: np.ndarray, values: np.ndarray) -> np.ndarray:
    p = np.round(points[:, :2], 9)
    return values[np.lexsort((p[:, 1], p[:, 0]))]


def final_fields(outdir: Path) -> dict[str, np.ndarray]:
    """u and Fg (float32 fields) and the state's Fg and G (float64) of the last step, ordered by
    node / cell coordinates (the serial and parallel runs number them differently)."""
    with h5py.File(outdir / "fields.h5", "r") as f:
        nodes = f["Mesh/geometry"][...]
    state = saved_state(outdir, N_STEPS)
    midpoints = state["midpoints"]
    values = {f"state/{k}": _sorted_by(midpoints, state[k]) for k in ("Fg", "G")}
    with h5py.File(outdir / "fields" / f"step_{N_STEPS:06d}.h5", "r") as f:
        values["u"] = _sorted_by(nodes, f["u"][...].astype(float))
        values["Fg"] = _sorted_by(midpoints, f["Fg"][...].astype(float))
    return values


def assert_same_run(outdir: Path, reference: Path, every: int = 1, rtol: float = RTOL) -> None:
    """Rows 0..N_STEPS once each, equal to the reference's to ``rtol``; the written steps and the
    final state and fields equal."""
    rows, ref_rows = summary_rows(outdir), summary_rows(reference)
    assert [int(r["step"]) for r in rows] == list(range(N_STEPS + 1))
    for row, ref in zip(rows, ref_rows, strict=True):
        for key, value in ref.items():
            if key.startswith("seconds") or key in NOT_COMPARED:
                continue
            assert row[key] == pytest.approx(value, rel=rtol, abs=1e-300), (row["step"], key)
    assert step_files(outdir) == step_files(reference) == written(every)
    got, expected = final_fields(outdir), final_fields(reference)
    for name, value in expected.items():
        error = np.abs(got[name] - value).max() / np.abs(value).max()
        assert error <= (rtol if name.startswith("state/") else rtol + ULP32), (name, error)


# --- fixtures -----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("interruptions") / "gradient_eta.toml"
    path.write_text(SCENE)
    return path


def serial_run(scene: Path, name: str) -> Path:
    """``plantgrowth run scene`` uninterrupted, serial, into the scene's directory / name."""
    outdir = scene.parent / name
    code, err = run(["run", str(scene), "-o", str(outdir)], scene.parent)
    assert code == 0, err
    return outdir


@pytest.fixture(scope="module")
def reference(scene_file) -> Path:
    """The uninterrupted serial run."""
    return serial_run(scene_file, "reference")


@pytest.fixture(scope="module")
def sparse_scene(scene_file) -> Path:
    """The scene with output.every = EVERY."""
    path = scene_file.parent / "every.toml"
    path.write_text(SCENE + f"[output]\nevery = {EVERY}\n")
    return path


@pytest.fixture(scope="module")
def sparse_reference(sparse_scene) -> Path:
    """The uninterrupted serial run with output.every = EVERY."""
    return serial_run(sparse_scene, "sparse_reference")


def _kill_and_check(scene_file: Path, tmp_path: Path, ranks: int, every: int = 1) -> Path:
    outdir = tmp_path / f"killed_{ranks}"
    proc = start(["run", str(scene_file), "-o", str(outdir)], tmp_path, ranks)
    wait_for_rows(proc, outdir, 5)
    kill_session(proc, tmp_path, str(outdir))
    steps = check_readable(outdir, every)
    assert 5 <= len(steps) <= N_STEPS, "killed too late to test anything"
    return outdir


# --- SIGKILL, then --resume ---------------------------------------------------------------------


@pytest.mark.skip_in_parallel
@pytest.mark.parametrize("ranks", [1, 2], ids=["serial", "mpirun2"])
def test_sigkill_leaves_readable_steps_and_resume_matches(scene_file, reference, tmp_path, ranks):
    outdir = _kill_and_check(scene_file, tmp_path, ranks)
    # the run continues after the newest saved state; the rows up to it are kept as they were
    kept = summary_rows(outdir)[: state_steps(outdir)[-1] + 1]
    code, err = run(["run", str(scene_file), "--resume", str(outdir)], tmp_path, ranks)
    assert code == 0, err
    assert "Traceback" not in err
    assert check_readable(outdir) == list(range(N_STEPS + 1))
    assert summary_rows(outdir)[: len(kept)] == kept
    assert_same_run(outdir, reference)


@pytest.mark.skip_in_parallel
def test_sigkill_then_resume_on_the_iterative_solver_matches_to_its_tolerance(scene_file, tmp_path):
    """solver.macro = "iterative": the killed and resumed run equals the uninterrupted one to
    ITERATIVE_RTOL (the state holds no u: the resumed step starts cold)."""
    scene = scene_file.parent / "iterative.toml"
    scene.write_text(SCENE + '[solver]\nmacro = "iterative"\n')
    reference = serial_run(scene, "iterative_reference")
    assert "macro solver: CG + BoomerAMG" in (reference / "run.log").read_text()
    outdir = _kill_and_check(scene, tmp_path, 1)
    code, err = run(["run", str(scene), "--resume", str(outdir)], tmp_path)
    assert code == 0, err
    assert_same_run(outdir, reference, rtol=ITERATIVE_RTOL)


@pytest.mark.skip_in_parallel
@pytest.mark.parametrize("ranks", [1, 2], ids=["serial", "mpirun2"])
def test_sigkill_with_output_every_resumes_to_the_same_written_steps(
    sparse_scene, sparse_reference, tmp_path, ranks
):
    """output.every = 7: the killed run leaves the written steps so far readable, and --resume
    (which continues from the state, written every step) ends with the uninterrupted run's rows,
    written steps and final state."""
    outdir = _kill_and_check(sparse_scene, tmp_path, ranks, EVERY)
    code, err = run(["run", str(sparse_scene), "--resume", str(outdir)], tmp_path, ranks)
    assert code == 0, err
    assert check_readable(outdir, EVERY) == list(range(N_STEPS + 1))
    assert_same_run(outdir, sparse_reference, EVERY)


@pytest.mark.skip_in_parallel
def test_resume_after_a_kill_between_step_file_and_summary_row(scene_file, reference, tmp_path):
    """SIGKILL can land after a step's HDF5 file is renamed into place and before its summary
    row is appended (check_readable allows that state). Simulated deterministically: drop the
    last row of a killed run (state_previous.h5 keeps the step before). The resumed run must still
    have one row per step."""
    outdir = _kill_and_check(scene_file, tmp_path, 1)
    steps = step_files(outdir)
    lines = (outdir / "summary.csv").read_text().splitlines(keepends=True)
    kept = [line for line in lines[1:] if int(float(line.split(",")[0])) < steps[-1]]
    (outdir / "summary.csv").write_text(lines[0] + "".join(kept))
    code, err = run(["run", str(scene_file), "--resume", str(outdir)], tmp_path)
    assert code == 0, err
    assert_same_run(outdir, reference)


# --- SIGINT -------------------------------------------------------------------------------------


@pytest.mark.skip_in_parallel
def test_sigint_stops_at_a_step_end_and_resume_completes(scene_file, reference, tmp_path):
    outdir = tmp_path / "interrupted"
    proc = start(["run", str(scene_file), "-o", str(outdir)], tmp_path)
    wait_for_rows(proc, outdir, 3)
    os.killpg(proc.pid, signal.SIGINT)
    code, err = finish(proc, tmp_path)
    assert code == 130, err
    assert "Traceback" not in err
    assert "interrupted after step" in err and f"--resume {outdir}" in err, err
    steps = check_readable(outdir)
    rows = summary_rows(outdir)
    assert [int(r["step"]) for r in rows] == steps  # a clean stop: the last row is complete
    assert steps[-1] < N_STEPS
    assert f"interrupted after step {steps[-1]} " in err
    code, err = run(["run", str(scene_file), "--resume", str(outdir)], tmp_path)
    assert code == 0, err
    assert_same_run(outdir, reference)


@pytest.mark.skip_in_parallel
def test_sigint_during_set_up_exits_130_without_traceback(scene_file, tmp_path):
    """Ctrl-C before the time loop (mesh, forms, first cell problems) is still an interruption:
    exit code 130 (or death by SIGINT), not a KeyboardInterrupt traceback."""
    outdir = tmp_path / "early"
    proc = start(["run", str(scene_file), "-o", str(outdir)], tmp_path)
    deadline = time.monotonic() + 60.0
    while not (outdir / "run.log").exists() and time.monotonic() < deadline:
        time.sleep(0.002)  # run.log appears when the set-up starts
    os.killpg(proc.pid, signal.SIGINT)
    code, err = finish(proc, tmp_path)
    assert not (outdir / "fields" / "step_000001.h5").exists(), "SIGINT came too late"
    assert "Traceback" not in err, err
    # 130 from main, or death by SIGINT itself (what a shell also reports as 130)
    assert code in (130, -signal.SIGINT), err


# --- --resume argument checks and a failing run (in-process: serial and under mpirun) ---------


def _shared_dir(factory, name: str) -> Path:
    comm = MPI.COMM_WORLD
    return comm.bcast(factory.mktemp(name) if comm.rank == 0 else None, root=0)


def _write(path: Path, text: str) -> None:
    if MPI.COMM_WORLD.rank == 0:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    MPI.COMM_WORLD.Barrier()


@pytest.mark.parametrize("setup", ["no_directory", "no_scene_toml", "other_scene"])
def test_resume_needs_the_same_scene(tmp_path_factory, capsys, setup):
    directory = _shared_dir(tmp_path_factory, f"resume_{setup}")
    scene, outdir = directory / "scene.toml", directory / "run"
    _write(scene, SCENE)
    if setup == "no_scene_toml":
        _write(outdir / "fields" / "step_000000.h5", "")
    elif setup == "other_scene":
        _write(outdir / "scene.toml", SCENE.replace("cell_resolution = 1", "cell_resolution = 2"))
    listing = sorted(p.name for p in directory.rglob("*"))
    capsys.readouterr()
    code = main(["run", str(scene), "--resume", str(outdir)])
    MPI.COMM_WORLD.Barrier()
    out, err = capsys.readouterr()
    assert code == 2
    assert "Traceback" not in out + err
    if MPI.COMM_WORLD.rank == 0:
        lines = err.splitlines()
        assert len(lines) == 1 and lines[0].startswith("plantgrowth: error: --resume "), err
        assert ("differs" in err) if setup == "other_scene" else ("no scene.toml" in err)
    assert sorted(p.name for p in directory.rglob("*")) == listing  # nothing written


SMALL = """\
[tissue]
h = 0.5
[growth]
law = "stress"
[time]
t_max = 4
dt = 1
[accuracy]
cell_resolution = 1
"""


def test_failed_solve_exits_3_naming_step_time_and_cause(tmp_path_factory, monkeypatch, capsys):
    """The macro solve of step 2 'fails' (PETSc reason -3, residual NaN): exit code 3, one line
    naming the step, the time and the likely cause, and steps 0-1 on disk intact."""
    directory = _shared_dir(tmp_path_factory, "failed_solve")
    scene, outdir = directory / "small.toml", directory / "run"
    _write(scene, SMALL)
    calls = []
    solve = macro_problem.assemble_and_solve

    def failing_at_step_2(*args):
        calls.append(1)
        report = solve(*args)
        return SolveReport(reason=-3, residual=float("nan")) if len(calls) == 3 else report

    monkeypatch.setattr(macro_problem, "assemble_and_solve", failing_at_step_2)
    capsys.readouterr()
    code = main(["run", str(scene), "-o", str(outdir)])
    MPI.COMM_WORLD.Barrier()
    out, err = capsys.readouterr()
    assert len(calls) == 3  # steps 0, 1, 2: one macro solve each, the run stopped at step 2
    assert code == 3
    assert "Traceback" not in out + err
    if MPI.COMM_WORLD.rank != 0:
        assert err == ""
        return
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("plantgrowth: run failed: "), err
    message = lines[0]
    assert "step 2" in message and "t = 2" in message
    assert "linear solve failed" in message and "likely cause" in message
    assert step_files(outdir) == [0, 1]
    for step in (0, 1):
        with h5py.File(outdir / "fields" / f"step_{step:06d}.h5", "r") as f:
            assert all(np.all(np.isfinite(f[name][...])) for name in STEP_DATASETS)
    assert [int(r["step"]) for r in summary_rows(outdir)] == [0, 1]
    root = ET.parse(outdir / "fields.xdmf").getroot()
    assert [g.get("Name") for g in root.iter("Grid") if g.get("Name").startswith("step_")] == [
        "step_0",
        "step_1",
    ]
    assert "run failed" in (outdir / "run.log").read_text()


def test_resume_with_the_adaptive_integrator(mpi_tmp_path):
    """--resume redoes the last step's advance with the scene's integrator: with 'adaptive'
    (sub-steps, extra solves) the resumed run equals the uninterrupted one. The interruption is
    simulated by deleting the last step's file and summary row (state_previous.h5 keeps the step
    before, so the run continues from step 1)."""
    scene = mpi_tmp_path / "adaptive.toml"
    if MPI.COMM_WORLD.rank == 0:
        scene.write_text(
            "[tissue]\nh = 0.5\nH = 2.0\n[material]\nE = {from = 0.5, to = 2.0}\n"
            '[growth]\nlaw = "strain"\n[time]\nt_max = 6\ndt = 3\nintegrator = "adaptive"\n'
            "[accuracy]\ncell_resolution = 1\n"
        )
    MPI.COMM_WORLD.Barrier()
    whole, cut = mpi_tmp_path / "whole", mpi_tmp_path / "cut"
    assert main(["run", str(scene), "-o", str(whole)]) == 0
    assert main(["run", str(scene), "-o", str(cut)]) == 0
    if MPI.COMM_WORLD.rank == 0:
        (cut / "fields" / "step_000002.h5").unlink()
        lines = (cut / "summary.csv").read_text().splitlines(keepends=True)
        (cut / "summary.csv").write_text("".join(lines[:-1]))
    MPI.COMM_WORLD.Barrier()
    assert main(["run", str(scene), "--resume", str(cut)]) == 0
    if MPI.COMM_WORLD.rank == 0:
        assert "resuming after step 1 (t = 3)" in (cut / "run.log").read_text()
        rows, expected = summary_rows(cut), summary_rows(whole)
        assert len(rows) == len(expected) == 3
        for row, ref in zip(rows, expected, strict=True):
            for key in ("area", "growth_rate_11", "u1_max", "det_Fg_min", "substeps"):
                assert row[key] == pytest.approx(ref[key], rel=1e-10), key
