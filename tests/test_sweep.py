"""``plantgrowth sweep`` (issue 10, item 5): expansion, validation, rows equal to stand-alone runs,
failing runs, restarts after SIGKILL and SIGINT, MPI groups and job arrays.

The base scene is tiny (h = 0.35, cell_resolution = 1, t_max = 2: ~0.1 s a run); LONG's second
and fourth runs have 20 steps and an eta gradient (cell problems every step, ~0.6 s each), so a
sweep can be stopped in the middle of its second run. In-process tests call ``main`` on every
rank, so under mpirun they also run the sweep on sub-communicators; the subprocess tests
(``skip_in_parallel``) start ``mpirun -n 2`` themselves, in sessions of their own.

Tolerances: a sweep's run is ``plantgrowth run``'s code on a communicator of the same size, so
its rows equal a stand-alone run's up to round-off (1e-10 relative, the issue's bound; measured:
bitwise); a restarted sweep resumes runs exactly (1e-10, as tests/test_interruptions.py);
serial against ``mpirun -n 2``: one rank per run repeats the serial arithmetic, two ranks per
run factor with a distributed LU (round-off ~1e-12), so 1e-8 relative as for ``run``.
"""

from __future__ import annotations

import csv
import json
import os
import re
import signal
import subprocess
import time
from pathlib import Path

import pytest
from cli_helpers import ENV, PLANTGROWTH, RANK0, call, finish, shared_dir, write
from mpi4py import MPI

from plantgrowth.base.errors import InputError
from plantgrowth.cli import main
from plantgrowth.runner.rundir import DirectoryLock
from plantgrowth.scene.presets import knob
from plantgrowth.studies.sweep_directory import check_run_directory
from plantgrowth.studies.sweep_file import NUMBERS, load_sweep
from plantgrowth.studies.sweep_share import Share

TIMEOUT = 120.0  # s; a sweep here takes a few seconds, under mpirun a few more
SIZE = MPI.COMM_WORLD.size
BASE = (
    '[tissue]\nh = 0.35\n[growth]\nlaw = "stress"\n{growth}[time]\nt_max = 2\n'
    "[accuracy]\ncell_resolution = 1\n"
)
GRID = """\
base = "base.toml"
mode = "grid"
[vary]
"material.nu" = [0.2, 0.3]
"growth.eta" = [1.0, {from = 0.5, to = 2.0}]
"""
LONG = """\
base = "gradient.toml"
[vary]
"material.nu" = [0.2, 0.3]
"time.t_max" = [2, 20]
"""
COMPARED = NUMBERS + tuple(f"micro_{n}" for n in NUMBERS)
ENV_OFF = dict(ENV, PLANTGROWTH_CACHE_DIR="off")  # subprocesses: no disk cache, as conftest


def table(outdir: Path) -> list[dict[str, str]]:
    with open(outdir / "sweep.csv", newline="") as f:
        return list(csv.DictReader(f))


def summary(path: Path) -> list[dict[str, float]]:
    with open(path, newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def assert_same_table(rows: list[dict], expected: list[dict], rtol: float) -> None:
    """Equal tables: text columns exactly, numbers to rtol, seconds not compared."""
    assert [r["run"] for r in rows] == [r["run"] for r in expected]
    for row, ref in zip(rows, expected, strict=True):
        assert row.keys() == ref.keys()
        for key, value in ref.items():
            if key in COMPARED and value:
                assert float(row[key]) == pytest.approx(float(value), rel=rtol), (row["run"], key)
            elif key != "seconds":
                assert row[key] == value, (row["run"], key)


def starts(run_dir: Path) -> int:
    """How many times the sweep started this run (its run.log's first lines)."""
    return sum(" -> " in line for line in (run_dir / "run.log").read_text().splitlines())


def launch(argv: list[str], cwd: Path, ranks: int = 1) -> subprocess.Popen:
    """``plantgrowth argv`` (under ``mpirun -n ranks``) in a session of its own, without the disk
    cache; output into cwd/stdout.txt and cwd/stderr.txt (see cli_helpers.start)."""
    command = [PLANTGROWTH, *argv]
    if ranks > 1:
        command = ["mpirun", "-n", str(ranks), *command]
    out, err = open(cwd / "stdout.txt", "w"), open(cwd / "stderr.txt", "w")
    proc = subprocess.Popen(
        command, cwd=cwd, stdout=out, stderr=err, env=ENV_OFF, start_new_session=True
    )
    proc.files = (out, err)  # type: ignore[attr-defined]
    return proc


def sweep_dir(factory, name: str, sweep: str = GRID, growth: str = "") -> Path:
    """A shared directory with base.toml, gradient.toml (eta gradient) and sweep.toml."""
    directory = shared_dir(factory, name)
    write(directory / "base.toml", BASE.format(growth=growth))
    write(directory / "gradient.toml", BASE.format(growth="eta = {from = 0.5, to = 2.0}\n"))
    write(directory / "sweep.toml", sweep)
    return directory


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """GRID, uninterrupted, in-process, one run per COMM_WORLD (as a stand-alone run)."""
    directory = sweep_dir(tmp_path_factory, "reference")
    argv = ["sweep", directory / "sweep.toml", "-o", directory / "out", "--ranks-per-run", SIZE]
    assert main([str(a) for a in argv]) == 0
    MPI.COMM_WORLD.Barrier()
    return directory / "out"


@pytest.fixture(scope="module")
def long_reference(tmp_path_factory) -> Path:
    """LONG, uninterrupted, in-process (for the serial kill and SIGINT tests)."""
    directory = sweep_dir(tmp_path_factory, "long_reference", LONG)
    assert main(["sweep", str(directory / "sweep.toml"), "-o", str(directory / "out")]) == 0
    MPI.COMM_WORLD.Barrier()
    return directory / "out"


# --- expansion ------------------------------------------------------------------------------------


@pytest.mark.mpi
def test_grid_runs_every_combination_first_key_slowest(tmp_path_factory):
    directory = sweep_dir(tmp_path_factory, "grid")
    sweep = load_sweep(directory / "sweep.toml")
    eta = {"from": 0.5, "to": 2.0}
    assert [run.name for run in sweep.runs] == ["run_0000", "run_0001", "run_0002", "run_0003"]
    assert [run.values for run in sweep.runs] == [
        {"material.nu": 0.2, "growth.eta": 1.0}, {"material.nu": 0.2, "growth.eta": eta},
        {"material.nu": 0.3, "growth.eta": 1.0}, {"material.nu": 0.3, "growth.eta": eta},
    ]  # fmt: skip
    scenes = [run.scene for run in sweep.runs]
    assert [s.material.nu.start for s in scenes] == [0.2, 0.2, 0.3, 0.3]
    assert [(s.growth.eta.start, s.growth.eta.end) for s in scenes] == [(1, 1), (0.5, 2)] * 2
    assert all(s.tissue.h == 0.35 and s.time.t_max == 2 for s in scenes)  # the rest from base
    assert sweep.columns() == ["run", "material.nu", "growth.eta", "status", *NUMBERS,
                               "seconds", "error"]  # fmt: skip
    assert sweep.cells(sweep.runs[1]) == {
        "material.nu": "0.2",
        "growth.eta": "{from = 0.5, to = 2.0}",
    }
    assert sweep.base == (directory / "base.toml").resolve()
    # unquoted dotted keys are TOML tables: the same sweep
    write(directory / "dotted.toml", GRID.replace('"material.nu"', "material.nu"))
    assert [run.values for run in load_sweep(directory / "dotted.toml").runs] == [
        run.values for run in sweep.runs
    ]


def test_one_at_a_time_varies_each_list_alone(tmp_path_factory):
    text = 'base = "base.toml"\nmode = "one-at-a-time"\n[vary]\n"material.nu" = [0.2, 0.25]\n'
    directory = sweep_dir(tmp_path_factory, "oat", text + '"time.t_max" = [4]\n')
    sweep = load_sweep(directory / "sweep.toml")
    assert [run.values for run in sweep.runs] == [
        {"material.nu": 0.2},
        {"material.nu": 0.25},
        {"time.t_max": 4},
    ]
    assert [(r.scene.material.nu.start, r.scene.time.t_max) for r in sweep.runs] == [
        (0.2, 2.0), (0.25, 2.0), (0.3, 4.0)
    ]  # fmt: skip
    # the columns of the keys a run does not vary show the base scene's value
    assert [sweep.cells(run) for run in sweep.runs] == [
        {"material.nu": "0.2", "time.t_max": "2.0"},
        {"material.nu": "0.25", "time.t_max": "2.0"},
        {"material.nu": "0.3", "time.t_max": "4"},
    ]


def test_a_varied_accuracy_preset_sets_the_knobs_the_base_leaves_out(tmp_path_factory):
    text = 'base = "base.toml"\n[vary]\n"accuracy.preset" = ["draft", "fine"]\n'
    sweep = load_sweep(sweep_dir(tmp_path_factory, "preset", text) / "sweep.toml")
    for run, preset in zip(sweep.runs, ["draft", "fine"], strict=True):
        accuracy, tissue = run.scene.accuracy, run.scene.tissue
        assert accuracy.preset == preset
        assert accuracy.cell_tolerance == knob(preset, "accuracy", "cell_tolerance")
        # the preset's H, clipped to [h, max(width, height)] (scene.py: h <= H)
        H = min(knob(preset, "tissue", "H"), max(tissue.width, tissue.height))
        assert tissue.H == max(H, tissue.h)
        assert tissue.h == 0.35 and accuracy.cell_resolution == 1  # the base scene's own


def test_the_shipped_example_sweep_expands():
    path = Path(__file__).parents[1] / "scenes" / "sweeps" / "nu_strain.toml"
    sweep = load_sweep(path)
    assert sweep.base == path.parents[1] / "reference_strain.toml"
    assert [(r.scene.material.nu.start, r.scene.time.t_max) for r in sweep.runs] == [
        (0.1, 10.0), (0.2, 10.0), (0.3, 10.0)
    ]  # fmt: skip
    assert all(r.scene.growth.law == "strain" for r in sweep.runs)


# --- validation: one line, exit 2, nothing written --------------------------------------------


HEAD = 'base = "base.toml"\n[vary]\n'


@pytest.mark.parametrize(
    "text, message",
    [
        ('bse = "base.toml"\n[vary]\n"material.nu" = [0.2]\n', "unknown key 'bse' (valid keys: "
         "base, mode, vary); did you mean 'base'?"),
        ('[vary]\n"material.nu" = [0.2]\n', "base is required"),
        ('base = 3\n[vary]\n"material.nu" = [0.2]\n', "base: expected the path of the base scene"),
        ('base = "nope.toml"\n[vary]\n"material.nu" = [0.2]\n', "base = 'nope.toml': no such "
         "scene file"),
        ('base = "base.toml"\nmode = "grd"\n[vary]\n"material.nu" = [0.2]\n', "mode = 'grd' is "
         "invalid: it must be one of 'grid', 'one-at-a-time'"),
        ('base = "base.toml"\n', "vary is required"),
        ('base = "base.toml"\nvary = [1]\n', "vary is required"),
        (HEAD + '"material.nu" = 0.2\n', "vary.'material.nu': expected a non-empty list of "
         "values, got 0.2"),
        (HEAD + '"material.nu" = []\n', "vary.'material.nu': expected a non-empty list"),
        (HEAD + '"material.nu" = [0.2, 0.2]\n', "vary.'material.nu' lists 0.2 twice"),
        (HEAD + '"material.nuu" = [0.2]\n', "vary: 'material.nuu' is not a scene key; did you "
         "mean 'material.nu'?"),
        (HEAD + '"nu" = [0.2]\n', "vary: 'nu' is not a scene key; did you mean 'material.nu'?"),
        (HEAD + '"material" = [0.2]\n', "vary: 'material' is not a scene key"),
        (HEAD + '"material.nu" = [0.2, 0.5]\n"time.t_max" = [4]\n', "material.nu = 0.5 is out of "
         "range: it must be finite and in (-1, 0.5) (in {sweep}: run_0001 (material.nu = 0.5, "
         "time.t_max = 4))"),
        (HEAD + '"growth.law" = ["stress", 1]\n', "growth.law: expected a string"),
        (HEAD + '"growth.eta" = [{from = 1}]\n', "growth.eta: a linear field needs both ends"),
        ("base = [\n", "invalid TOML"),
    ],
    ids=lambda x: x[:24] if isinstance(x, str) else x,
)  # fmt: skip
def test_a_bad_sweep_file_is_one_line_exit_2_and_nothing_written(
    tmp_path_factory, capsys, text, message
):
    directory = sweep_dir(tmp_path_factory, "bad", text)
    code, _, err = call(["sweep", directory / "sweep.toml", "-o", directory / "out"], capsys)
    assert code == 2
    if RANK0:
        lines = err.splitlines()
        assert len(lines) == 1 and lines[0].startswith("plantgrowth: error: "), err
        assert message.format(sweep=directory / "sweep.toml") in lines[0], err
        assert not (directory / "out").exists()


@pytest.mark.parametrize(
    "options, message",
    [
        (["--ranks-per-run", "0"], "--ranks-per-run = 0 is invalid"),
        (["--ranks-per-run", "3"], f"does not divide the number of MPI ranks, {SIZE}"),
        (["--array-index", "0"], "give --array-index and --array-count together"),
        (["--array-index", "2", "--array-count", "2"], "--array-index = 2 is out of range"),
        (["--array-index", "0", "--array-count", "0"], "--array-count = 0 is invalid"),
        (["--array-index", "0", "--array-count", "2", "--overwrite"], "--overwrite cannot"),
    ],
)
def test_bad_sweep_options_are_one_line_exit_2_and_nothing_written(
    tmp_path_factory, capsys, options, message
):
    directory = sweep_dir(tmp_path_factory, "options")
    argv = ["sweep", directory / "sweep.toml", "-o", directory / "out", *options]
    code, _, err = call(argv, capsys)
    assert code == 2
    if RANK0:
        assert err.startswith("plantgrowth: error: ") and len(err.splitlines()) == 1, err
        assert message in err and not (directory / "out").exists(), err


def test_dry_run_lists_the_runs_and_writes_nothing(tmp_path_factory, capsys):
    directory = sweep_dir(tmp_path_factory, "dry")
    argv = ["sweep", directory / "sweep.toml", "-o", directory / "out", "--dry-run",
            "--array-index", "1", "--array-count", "2"]  # fmt: skip
    code, out, _ = call(argv, capsys)
    assert code == 0
    if RANK0:
        assert [line.split()[0] for line in out.splitlines()[:-1]] == ["run_0001", "run_0003"]
        assert "4 runs (grid); element 1 of 2: 2 listed" in out
        assert not (directory / "out").exists()


# --- results ------------------------------------------------------------------------------------


@pytest.mark.mpi
def test_sweep_rows_equal_stand_alone_runs_of_their_scenes(reference, tmp_path_factory, capsys):
    rows = table(reference) if RANK0 else None
    rows = MPI.COMM_WORLD.bcast(rows, root=0)
    assert [r["status"] for r in rows] == ["done"] * 4
    assert [(r["material.nu"], r["growth.eta"]) for r in rows] == [
        ("0.2", "1.0"), ("0.2", "{from = 0.5, to = 2.0}"),
        ("0.3", "1.0"), ("0.3", "{from = 0.5, to = 2.0}"),
    ]  # fmt: skip
    directory = shared_dir(tmp_path_factory, "stand_alone")
    for row in rows:
        alone = directory / row["run"]
        code, _, err = call(["run", reference / row["run"] / "scene.toml", "-o", alone], capsys)
        assert code == 0, err
        if not RANK0:
            continue
        last = summary(alone / "summary.csv")[-1]
        assert float(row["t"]) == last["t"] == 2.0
        for key in NUMBERS:
            assert float(row[key]) == pytest.approx(last[key], rel=1e-10), (row["run"], key)
        mine = summary(reference / row["run"] / "summary.csv")
        for a, b in zip(mine, summary(alone / "summary.csv"), strict=True):
            for key in ("area", "growth_rate_11", "growth_rate_22", "u1_max", "det_Fg_min"):
                assert a[key] == pytest.approx(b[key], rel=1e-10), (row["run"], key)
    # a different eta or nu changes the numbers: the rows are not all one run's
    assert len({r["area"] for r in rows}) == 4


def test_a_failing_run_is_recorded_the_others_finish_and_it_is_retried(tmp_path_factory, capsys):
    text = HEAD + '"growth.Fg0" = [[[1, 0], [0, 1]], [[4, 0], [0, 1]], [[1.05, 0], [0, 1]]]\n'
    directory = sweep_dir(tmp_path_factory, "failing", text)
    argv = ["sweep", directory / "sweep.toml", "-o", directory / "out"]
    code, _, err = call(argv, capsys)
    assert code == 3  # Fg0 = diag(4, 1) inverts every element at step 0
    out = directory / "out"
    if RANK0:
        rows = table(out)
        assert [r["status"] for r in rows] == ["done", "failed", "done"]
        assert rows[1]["error"].startswith("step 0, t = 0: element inverted"), rows[1]["error"]
        assert rows[1]["t"] == "" and rows[0]["t"] == rows[2]["t"] == "2"
        assert rows[0]["error"] == rows[2]["error"] == ""
        assert f"see {out / 'sweep.csv'}" in err
        if SIZE == 1:  # under mpirun another rank's group may report it
            assert "run_0001 (growth.Fg0 = [[4, 0], [0, 1]]): failed: step 0" in err
    code, _, _ = call(argv, capsys)
    assert code == 3
    if RANK0:
        assert [starts(out / f"run_000{i}") for i in range(3)] == [1, 2, 1]  # retried, skipped
        assert [r["status"] for r in table(out)] == ["done", "failed", "done"]


def test_model_both_adds_micro_columns(tmp_path_factory, capsys):
    text = HEAD + '"model" = ["both"]\n[vary.micro]\nnx = [2]\n'  # a table: micro.nx
    directory = sweep_dir(tmp_path_factory, "both", text)
    write(directory / "base.toml", BASE.format(growth="") + "[micro]\nresolution = 1\n")
    code, _, err = call(["sweep", directory / "sweep.toml", "-o", directory / "out"], capsys)
    assert code == 0, err
    if RANK0:
        (row,) = table(directory / "out")
        macro = summary(directory / "out" / "run_0000" / "macro" / "summary.csv")[-1]
        micro = summary(directory / "out" / "run_0000" / "micro" / "summary.csv")[-1]
        assert float(row["area"]) == macro["area"] and float(row["micro_area"]) == micro["area"]
        assert row["model"] == "both" and row["micro.nx"] == "2" and row["micro_t"] == "2"


# --- the output directory -------------------------------------------------------------------------


def test_another_sweep_file_is_refused_and_overwrite_keeps_user_files(tmp_path_factory, capsys):
    one = HEAD + '"material.nu" = [0.2]\n'
    directory = sweep_dir(tmp_path_factory, "another", one)
    out = directory / "out"
    argv = ["sweep", directory / "sweep.toml", "-o", out]
    assert call(argv, capsys)[0] == 0
    write(out / "notes.txt", "mine\n")
    write(out / "run_0000" / "mine.txt", "mine too\n")
    write(directory / "sweep.toml", one.replace("0.2", "0.25"))
    listing = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} if RANK0 else None
    code, _, err = call(argv, capsys)
    assert code == 2
    if RANK0:
        assert err.startswith(f"plantgrowth: error: {out} holds another sweep"), err
        assert "vary.'material.nu' ([0.2] there, [0.25] here)" in err and "--overwrite" in err
        assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == listing
    assert call([*argv, "--overwrite"], capsys)[0] == 0
    if RANK0:
        assert [r["material.nu"] for r in table(out)] == ["0.25"]
        assert "nu = 0.25" in (out / "run_0000" / "scene.toml").read_text()
        assert (out / "notes.txt").read_text() == "mine\n"
        assert (out / "run_0000" / "mine.txt").read_text() == "mine too\n"
        assert starts(out / "run_0000") == 1  # the earlier run.log is gone


def test_a_changed_base_scene_is_refused_a_larger_t_max_extends(tmp_path_factory, capsys):
    directory = sweep_dir(tmp_path_factory, "changed_base", HEAD + '"material.nu" = [0.2]\n')
    out = directory / "out"
    argv = ["sweep", directory / "sweep.toml", "-o", out]
    assert call(argv, capsys)[0] == 0
    write(directory / "base.toml", BASE.format(growth="") + "[pressure]\nP1 = 0.002\n")
    code, _, err = call(argv, capsys)
    assert code == 2
    if RANK0:
        assert f"{out / 'run_0000'} ran another scene (pressure.P1 differ)" in err, err
    write(directory / "base.toml", BASE.format(growth="").replace("t_max = 2", "t_max = 3"))
    assert call(argv, capsys)[0] == 0
    if RANK0:
        assert [int(r["step"]) for r in summary(out / "run_0000" / "summary.csv")] == [0, 1, 2, 3]
        assert table(out)[0]["t"] == "3" and starts(out / "run_0000") == 2


def test_a_run_that_is_starting_is_not_taken_for_foreign_files(tmp_path_factory):
    """Another job-array element's run writes .scene.toml.tmp just before its scene.toml: the
    directory check of an element starting meanwhile must let it be (CI caught this race); a
    run directory with other plantgrowth files and no scene.toml is still refused."""
    directory = sweep_dir(tmp_path_factory, "starting", HEAD + '"material.nu" = [0.2]\n')
    (run,) = load_sweep(directory / "sweep.toml").runs
    run_dir = directory / "out" / run.name
    write(run_dir / ".scene.toml.tmp", "")
    check_run_directory(run_dir, run)
    write(run_dir / "summary.csv", "step,t\n")
    with pytest.raises(InputError, match="holds plantgrowth files but no scene.toml"):
        check_run_directory(run_dir, run)


@pytest.mark.mpi
def test_a_sweep_is_refused_while_another_holds_the_directory(tmp_path_factory, capsys):
    """An exclusive lock (a sweep, or a run) refuses job-array elements, a shared one (array
    elements) refuses a plain sweep but not another element."""
    directory = sweep_dir(tmp_path_factory, "held", HEAD + '"material.nu" = [0.2, 0.25]\n')
    out = directory / "out"
    plain = ["sweep", directory / "sweep.toml", "-o", out]
    element = [*plain, "--array-index", "0", "--array-count", "2"]
    for shared, refused, allowed in [(False, element, None), (True, plain, element)]:
        lock = None
        if RANK0:
            out.mkdir(exist_ok=True)
            lock = DirectoryLock(out, shared=shared)
        try:
            code, _, err = call(refused, capsys)
            assert code == 2
            if RANK0:
                assert "is in use by another plantgrowth run" in err, err
            if allowed:
                assert call(allowed, capsys)[0] == 0
        finally:
            if lock is not None:
                lock.release()
    if RANK0:
        assert [r["status"] for r in table(out)] == ["done", "pending"]


# --- restarts -----------------------------------------------------------------------------------


def wait_for_steps(proc: subprocess.Popen, run_dir: Path, n: int) -> None:
    """Poll until the run has ``n`` summary rows (its sweep still going)."""
    deadline = time.monotonic() + TIMEOUT
    path = run_dir / "summary.csv"
    while not path.exists() or path.read_text().count("\n") <= n:
        assert proc.poll() is None, f"the sweep ended (code {proc.returncode}) too early"
        assert time.monotonic() < deadline, f"{run_dir.name} has no {n} steps"
        time.sleep(0.005)


def recorded(out: Path, run: str) -> str:
    """The status in the run's result.json ("" if none)."""
    path = out / run / "result.json"
    return json.loads(path.read_text())["status"] if path.exists() else ""


@pytest.mark.skip_in_parallel
def test_a_killed_sweep_resumes_without_rerunning_finished_runs(long_reference, tmp_path):
    """SIGKILL while run_0001 (20 steps) is past its third step, after run_0000 finished."""
    directory = sweep_dir(_Factory(tmp_path), "killed", LONG)
    out = directory / "out"
    proc = launch(["sweep", str(directory / "sweep.toml"), "-o", str(out)], directory)
    wait_for_steps(proc, out / "run_0001", 3)
    os.killpg(proc.pid, signal.SIGKILL)
    finish(proc, directory)
    runs = [f"run_000{i}" for i in range(4)]
    assert [recorded(out, run) for run in runs] == ["done", "", "", ""], "killed too late"
    assert [r["status"] for r in table(out)] == ["done", "pending", "pending", "pending"]
    mtime = (out / "run_0000" / "summary.csv").stat().st_mtime_ns
    kept = summary(out / "run_0001" / "summary.csv")
    assert main(["sweep", str(directory / "sweep.toml"), "-o", str(out)]) == 0
    assert (out / "run_0000" / "summary.csv").stat().st_mtime_ns == mtime  # not run again
    assert [starts(out / run) for run in runs] == [1, 2, 1, 1]
    log = (out / "run_0001" / "run.log").read_text()
    # continued, not redone: from the last row, or the one before when the kill fell between a
    # step's summary row and its resume state (state.h5 is written last)
    resumed = int(re.search(r"resuming after step (\d+) ", log).group(1))
    assert resumed in (int(kept[-1]["step"]), int(kept[-1]["step"]) - 1)
    assert summary(out / "run_0001" / "summary.csv")[: resumed + 1] == kept[: resumed + 1]
    assert_same_table(table(out), table(long_reference), rtol=1e-10)


@pytest.mark.skip_in_parallel
def test_sigint_stops_the_sweep_after_a_step_and_a_restart_continues(long_reference, tmp_path):
    directory = sweep_dir(_Factory(tmp_path), "sigint", LONG)
    out = directory / "out"
    proc = launch(["sweep", str(directory / "sweep.toml"), "-o", str(out)], directory)
    wait_for_steps(proc, out / "run_0001", 3)
    os.killpg(proc.pid, signal.SIGINT)
    code, err = finish(proc, directory, TIMEOUT)
    assert code == 130, err
    assert "Traceback" not in err
    assert f"continue with: plantgrowth sweep {directory / 'sweep.toml'} -o {out}" in err
    rows = table(out)
    assert [r["status"] for r in rows] == ["done", "interrupted", "pending", "pending"]
    steps = [int(r["step"]) for r in summary(out / "run_0001" / "summary.csv")]
    assert steps == list(range(len(steps))) and 2 <= steps[-1] < 20  # 3 rows when signalled
    assert rows[1]["t"] == str(steps[-1])  # the last completed step's numbers
    assert rows[1]["error"].startswith(f"interrupted after step {steps[-1]} ")
    assert main(["sweep", str(directory / "sweep.toml"), "-o", str(out)]) == 0
    assert_same_table(table(out), table(long_reference), rtol=1e-10)


class _Factory:
    """tmp_path as a one-directory factory for sweep_dir (serial tests)."""

    def __init__(self, root: Path) -> None:
        self.root = root

    def mktemp(self, name: str) -> Path:
        path = self.root / name
        path.mkdir()
        return path


# --- MPI groups and job arrays --------------------------------------------------------------------


@pytest.mark.skip_in_parallel
@pytest.mark.parametrize("ranks_per_run", [1, 2])
def test_serial_equals_mpirun_2(reference, tmp_path, ranks_per_run):
    directory = sweep_dir(_Factory(tmp_path), "mpirun", GRID)
    out = directory / "out"
    argv = ["sweep", str(directory / "sweep.toml"), "-o", str(out),
            "--ranks-per-run", str(ranks_per_run)]  # fmt: skip
    proc = launch(argv, directory, ranks=2)
    code, err = finish(proc, directory, TIMEOUT)
    assert code == 0, err
    stdout = (directory / "stdout.txt").read_text()
    assert f"{2 // ranks_per_run} at a time on {ranks_per_run} rank(s)" in stdout
    assert all(f"on {ranks_per_run} rank(s)" in (out / r / "run.log").read_text().splitlines()[0]
               for r in ("run_0000", "run_0003"))  # fmt: skip
    assert_same_table(table(out), table(reference), rtol=1e-8)


@pytest.mark.parametrize("n_runs", [0, 1, 5, 12])
def test_the_job_array_and_group_split_covers_every_run_once(n_runs):
    for elements in (1, 2, 3, 5):
        for size, k in [(1, 1), (2, 1), (2, 2), (4, 2), (6, 3), (6, 1)]:
            shares = [Share(k, e, elements) for e in range(elements)]
            dealt = [i for s in shares for rank in range(0, size, k)
                     for i in s.group_runs(n_runs, rank, size)]  # fmt: skip
            assert sorted(dealt) == list(range(n_runs)), (elements, size, k)
            for s in shares:  # every rank of a group gets its group's runs
                for rank in range(size):
                    leader = rank - rank % k
                    assert s.group_runs(n_runs, rank, size) == s.group_runs(n_runs, leader, size)


@pytest.mark.mpi
def test_job_array_elements_each_run_their_share(tmp_path_factory, capsys):
    text = HEAD + '"material.nu" = [0.2, 0.25]\n"time.t_max" = [1, 2]\n'
    directory = sweep_dir(tmp_path_factory, "array", text)
    out = directory / "out"
    for element in (0, 1, 2):
        argv = ["sweep", directory / "sweep.toml", "-o", out,
                "--array-index", element, "--array-count", 3]  # fmt: skip
        code, _, err = call(argv, capsys)
        assert code == 0, err
        if RANK0:
            statuses = [r["status"] for r in table(out)]
            assert [i for i, s in enumerate(statuses) if s == "done"] == [
                i for i in range(4) if i % 3 <= element
            ]
    if RANK0:
        assert [starts(out / f"run_000{i}") for i in range(4)] == [1] * 4


@pytest.mark.skip_in_parallel
def test_concurrent_job_array_elements_share_the_directory(reference, tmp_path):
    directory = sweep_dir(_Factory(tmp_path), "concurrent", GRID)
    out = directory / "out"
    procs = []
    for element in (0, 1):
        cwd = directory / f"element_{element}"
        cwd.mkdir()
        argv = ["sweep", str(directory / "sweep.toml"), "-o", str(out),
                "--array-index", str(element), "--array-count", "2"]  # fmt: skip
        procs.append((launch(argv, cwd), cwd))
    for proc, cwd in procs:
        code, err = finish(proc, cwd, TIMEOUT)
        assert code == 0, err
    assert_same_table(table(out), table(reference), rtol=1e-10)
    assert [starts(out / f"run_000{i}") for i in range(4)] == [1] * 4
