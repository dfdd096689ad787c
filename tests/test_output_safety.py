"""One run per output directory, no silent overwrite, and ``--resume`` that appends to run.log
and extends a finished run (issue 8, section 3).

The subprocess tests (``skip_in_parallel``; the ``mpirun2`` cases start ``mpirun -n 2``
themselves) freeze the first run with SIGSTOP while the second one starts, so the overlap does
not depend on timing. The in-process tests call ``main`` on every rank, so under mpirun they
also check that rank 0 alone takes the lock and every rank gets its answer.

Tolerances: an extended run repeats the longer run's arithmetic (cell problems at rounded keys):
1e-10 relative leaves room only for round-off.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from cli_helpers import (
    ENV,
    PLANTGROWTH,
    RANK0,
    call,
    finish,
    processes_mentioning,
    shared_dir,
    start,
    write,
)
from mpi4py import MPI

from plantgrowth.runner.rundir import LOCK_NAME, earlier_outputs, remove_earlier_outputs

TIMEOUT = 120.0  # s; a run of SCENE takes ~3 s serial, ~5 s on 2 ranks


def scene_text(t_max: int, extra: str = "", eta: str = "{from = 0.5, to = 2.0}") -> str:
    """A small macro scene; by default with an eta gradient (cell problems every step)."""
    return (
        f'[tissue]\nh = 0.5\n[growth]\nlaw = "stress"\neta = {eta}\n'
        f"[time]\nt_max = {t_max}\ndt = 1\n[accuracy]\ncell_resolution = 1\n{extra}"
    )


FAST_STEPS = 40
"""Subprocess runs: a homogeneous scene (one cell problem per run, ~0.03 s a step)."""


def steps(outdir: Path) -> list[int]:
    with open(outdir / "summary.csv", newline="") as f:
        return [int(row["step"]) for row in csv.DictReader(f)]


def rows(outdir: Path) -> list[dict[str, float]]:
    with open(outdir / "summary.csv", newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def listing(directory: Path) -> dict[str, bytes]:
    return {str(p.relative_to(directory)): p.read_bytes() for p in directory.rglob("*")
            if p.is_file()}  # fmt: skip


# --- one run per output directory (subprocesses) ------------------------------------------------


def wait_for_rows(proc: subprocess.Popen, outdir: Path, n: int) -> None:
    deadline = time.monotonic() + TIMEOUT
    while time.monotonic() < deadline:
        assert proc.poll() is None, f"the run ended (code {proc.returncode}) before {n} steps"
        try:
            if len(steps(outdir)) >= n:
                return
        except (FileNotFoundError, ValueError, KeyError):
            pass
        time.sleep(0.01)
    pytest.fail(f"no {n} summary rows after {TIMEOUT:g} s")


def signal_all(pids: list[int], signum: int) -> None:
    for pid in pids:
        try:
            os.kill(pid, signum)
        except ProcessLookupError:
            pass


@pytest.mark.skip_in_parallel
@pytest.mark.parametrize("ranks", [1, 2], ids=["serial", "mpirun2"])
def test_a_second_run_into_a_busy_directory_is_refused_and_the_first_finishes(tmp_path, ranks):
    """The issue's case: two runs into one DIR both exited 0 and interleaved summary.csv. The
    second (with or without --overwrite) must exit 2 naming the running process; the first
    must finish with every step once, in order."""
    scene, outdir = tmp_path / "scene.toml", tmp_path / "busy"
    scene.write_text(scene_text(FAST_STEPS, eta="1.0"))
    first = start(["run", str(scene), "-o", str(outdir)], tmp_path, ranks)
    wait_for_rows(first, outdir, 2)
    frozen = processes_mentioning(str(outdir))
    signal_all(frozen, signal.SIGSTOP)  # the first run holds the directory, mid-run
    try:
        assert first.poll() is None and len(steps(outdir)) < FAST_STEPS, "frozen too late"
        holder = json.loads((outdir / LOCK_NAME).read_text())
        assert holder["pid"] in frozen
        seconds = [
            subprocess.Popen(
                [PLANTGROWTH, "run", str(scene), "-o", str(outdir), *extra], env=ENV,
                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            )
            for extra in ([], ["--overwrite"])
        ]  # fmt: skip
        for second in seconds:
            _, err = second.communicate(timeout=TIMEOUT)
            assert second.returncode == 2, err
            lines = err.splitlines()
            assert len(lines) == 1 and lines[0].startswith("plantgrowth: error: "), err
            assert "in use by another plantgrowth run" in lines[0]
            assert f"pid {holder['pid']} " in lines[0] and "run " in lines[0]
    finally:
        signal_all(frozen, signal.SIGCONT)
    code, err = finish(first, tmp_path)
    assert code == 0, err
    assert steps(outdir) == list(range(FAST_STEPS + 1))
    assert sorted(p.name for p in (outdir / "fields").iterdir()) == [
        f"step_{k:06d}.h5" for k in range(FAST_STEPS + 1)
    ]
    assert not (outdir / LOCK_NAME).exists()  # released at the end


@pytest.mark.skip_in_parallel
def test_a_killed_run_leaves_a_lock_that_does_not_block_resume(tmp_path):
    """SIGKILL leaves the lock file, but the kernel has dropped the lock: --resume proceeds; a
    plain new run is refused as an earlier run, not as a busy one. (Under mpirun:
    test_interruptions.py's SIGKILL-and-resume test, which now passes through the lock.)"""
    scene, outdir = tmp_path / "scene.toml", tmp_path / "killed"
    scene.write_text(scene_text(FAST_STEPS, eta="1.0"))
    proc = start(["run", str(scene), "-o", str(outdir)], tmp_path)
    wait_for_rows(proc, outdir, 3)
    os.killpg(proc.pid, signal.SIGKILL)
    finish(proc, tmp_path)
    assert (outdir / LOCK_NAME).exists()
    again = subprocess.run([PLANTGROWTH, "run", scene, "-o", outdir], capture_output=True,
                           text=True, env=ENV, timeout=TIMEOUT)  # fmt: skip
    assert again.returncode == 2 and "holds an earlier run" in again.stderr, again.stderr
    resume = start(["run", str(scene), "--resume", str(outdir)], tmp_path)
    code, err = finish(resume, tmp_path)
    assert code == 0, err
    assert steps(outdir) == list(range(FAST_STEPS + 1))
    assert not (outdir / LOCK_NAME).exists()


@pytest.mark.mpi
def test_a_lock_held_by_a_live_process_refuses_the_run(tmp_path_factory, capsys):
    """In-process (under mpirun: rank 0 takes the lock, every rank returns 2): a directory
    whose lock another live process holds is refused, naming it, with nothing written; once
    that process is gone the run goes ahead."""
    directory = shared_dir(tmp_path_factory, "held")
    scene, outdir = directory / "scene.toml", directory / "out"
    write(scene, scene_text(1))
    holder = None
    if RANK0:
        outdir.mkdir()
        code = (
            "import fcntl, json, os, sys, time\n"
            f"fd = os.open({str(outdir / LOCK_NAME)!r}, os.O_RDWR | os.O_CREAT)\n"
            "fcntl.flock(fd, fcntl.LOCK_EX)\n"
            "os.write(fd, json.dumps({'host': 'h', 'pid': os.getpid(), 'command': 'holder',"
            " 'started': 'now'}).encode())\n"
            "print('locked', flush=True)\ntime.sleep(120)\n"
        )
        holder = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
        assert holder.stdout.readline().strip() == "locked"
    try:
        before = listing(outdir) if RANK0 else None
        code, _, err = call(["run", scene, "-o", outdir], capsys)
        assert code == 2
        if RANK0:
            assert err.startswith("plantgrowth: error: ") and len(err.splitlines()) == 1, err
            assert f"pid {holder.pid} on host h" in err and "holder" in err
            assert listing(outdir) == before
    finally:
        if holder is not None:
            holder.kill()
            holder.wait()
    MPI.COMM_WORLD.Barrier()
    assert call(["run", scene, "-o", outdir], capsys)[0] == 0
    if RANK0:
        assert steps(outdir) == [0, 1] and not (outdir / LOCK_NAME).exists()


# --- no silent overwrite ------------------------------------------------------------------------


@pytest.mark.mpi
def test_an_earlier_run_is_refused_and_overwrite_removes_only_plantgrowth_files(
    tmp_path_factory, capsys
):
    directory = shared_dir(tmp_path_factory, "overwrite")
    long, short, outdir = directory / "long.toml", directory / "short.toml", directory / "out"
    write(long, scene_text(3))
    write(short, scene_text(1))
    assert call(["run", long, "-o", outdir], capsys)[0] == 0
    write(outdir / "notes.txt", "my notes\n")
    write(outdir / "fields" / "mine.h5", "my own file\n")
    before = listing(outdir) if RANK0 else None

    code, _, err = call(["run", short, "-o", outdir], capsys)
    assert code == 2
    if RANK0:
        assert err.startswith(f"plantgrowth: error: {outdir} holds an earlier run"), err
        assert "--overwrite" in err and f"--resume {outdir}" in err
        assert listing(outdir) == before  # nothing changed

    assert call(["run", short, "-o", outdir, "--overwrite"], capsys)[0] == 0
    if RANK0:
        assert steps(outdir) == [0, 1]
        assert sorted(p.name for p in (outdir / "fields").iterdir()) == [
            "mine.h5", "step_000000.h5", "step_000001.h5",
        ]  # fmt: skip
        assert (outdir / "notes.txt").read_text() == "my notes\n"
        assert (outdir / "fields" / "mine.h5").read_text() == "my own file\n"
        assert "long.toml" not in (outdir / "run.log").read_text()  # the old log is gone


def test_a_directory_with_only_user_files_is_not_an_earlier_run(tmp_path_factory, capsys):
    directory = shared_dir(tmp_path_factory, "user_files")
    scene, outdir = directory / "scene.toml", directory / "out"
    write(scene, scene_text(1))
    write(outdir / "README.txt", "results of the experiment go here\n")
    assert call(["run", scene, "-o", outdir], capsys)[0] == 0
    if RANK0:
        assert (outdir / "README.txt").read_text() == "results of the experiment go here\n"


def test_overwrite_and_resume_together_are_refused(tmp_path_factory, capsys):
    directory = shared_dir(tmp_path_factory, "both_flags")
    scene = directory / "scene.toml"
    write(scene, scene_text(1))
    write(directory / "out" / "scene.toml", scene_text(1))
    code, _, err = call(["run", scene, "--resume", directory / "out", "--overwrite"], capsys)
    assert code == 2
    if RANK0:
        assert "--overwrite" in err and "--resume" in err and len(err.splitlines()) == 1


def test_a_comparison_directory_is_an_earlier_run_too(tmp_path_factory, capsys):
    """compare.csv and nx<N>/{macro,micro} are plantgrowth's; a user's file among them is not:
    a new comparison is refused, and removing the earlier one keeps the user's files."""
    directory = shared_dir(tmp_path_factory, "compare_dir")
    scene, outdir = directory / "scene.toml", directory / "cmp"
    write(scene, scene_text(1, "[micro]\nnx = 4\nresolution = 1\n"))
    layout = {
        "compare.csv": "nx\n4\n", "scene.toml": "", "run.log": "", "nx4/macro/summary.csv": "",
        "nx4/macro/fields/step_000000.h5": "", "nx4/micro/fields.xdmf": "",
        "nx8/micro/fields.h5": "",
    }  # fmt: skip
    mine = {"nx4/mine.txt": "keep", "nx8/micro/fields/notes.txt": "keep", "plot.png": "keep"}
    for name, text in (layout | mine).items():
        write(outdir / name, text)
    before = listing(outdir) if RANK0 else None
    code, _, err = call(["compare", scene, "--nx", "4", "-o", outdir], capsys)
    assert code == 2
    if RANK0:
        assert "holds an earlier run" in err and "--overwrite" in err, err
        assert listing(outdir) == before
        assert sorted(str(p.relative_to(outdir)) for p in earlier_outputs(outdir)) == sorted(layout)
        remove_earlier_outputs(outdir)
        assert sorted(listing(outdir)) == sorted(mine)
        assert not (outdir / "nx4" / "macro").exists() and not (outdir / "nx8" / "macro").exists()


# --- resume -------------------------------------------------------------------------------------


def _cut_last_step(outdir: Path) -> None:
    """What a kill between steps leaves: the last step's file and summary row gone."""
    if RANK0:
        last = steps(outdir)[-1]
        (outdir / "fields" / f"step_{last:06d}.h5").unlink()
        lines = (outdir / "summary.csv").read_text().splitlines(keepends=True)
        (outdir / "summary.csv").write_text("".join(lines[:-1]))
    MPI.COMM_WORLD.Barrier()


@pytest.mark.mpi
def test_resume_appends_to_run_log(tmp_path_factory, capsys):
    directory = shared_dir(tmp_path_factory, "resume_log")
    scene, outdir = directory / "scene.toml", directory / "out"
    write(scene, scene_text(3))
    assert call(["run", scene, "-o", outdir], capsys)[0] == 0
    _cut_last_step(outdir)
    before = (outdir / "run.log").read_text() if RANK0 else None
    assert call(["run", scene, "--resume", outdir], capsys)[0] == 0
    if RANK0:
        text = (outdir / "run.log").read_text()
        assert text.startswith(before), "the log of the interrupted run must be kept"
        added = text[len(before) :]
        assert "resuming after step 2 (t = 2)" in added
        assert "step 3/3" in added
        # the run ends with "done" and the final result line (issue 21, item 8)
        last_two = added.rstrip().splitlines()[-2:]
        assert last_two[0].endswith(f"done: {outdir}") and " result: t = 3: area " in last_two[1]


def test_a_finished_run_is_extended_by_a_larger_t_max(tmp_path_factory, capsys):
    directory = shared_dir(tmp_path_factory, "extend")
    short, long = directory / "short.toml", directory / "long.toml"
    write(short, scene_text(2))
    write(long, scene_text(4))
    extended, whole = directory / "extended", directory / "whole"
    assert call(["run", short, "-o", extended], capsys)[0] == 0
    assert call(["run", long, "-o", whole], capsys)[0] == 0
    assert call(["run", long, "--resume", extended], capsys)[0] == 0
    if RANK0:
        got, expected = rows(extended), rows(whole)
        assert [int(r["step"]) for r in got] == [0, 1, 2, 3, 4]
        for row, ref in zip(got, expected, strict=True):
            for key in ("t", "area", "growth_rate_11", "growth_rate_22", "u1_max", "det_Fg_min"):
                assert row[key] == pytest.approx(ref[key], rel=1e-10), (row["step"], key)
        assert "t_max = 4.0" in (extended / "scene.toml").read_text()
        assert "extending the run to time.t_max = 4" in (extended / "run.log").read_text()


@pytest.mark.parametrize(
    "extra, t_max, expected",
    [
        ("[material]\nE = 2.0\n", 4, "differs from the one the run started with in material.E, "
         "time.t_max; only a larger time.t_max may change"),
        ("[material]\nE = 2.0\n[cell]\nw = 0.06\n", 2, "in cell.w, material.E;"),
        ("", 1, "time.t_max = 1 is smaller than the run's 2"),
    ],
    ids=["E_and_t_max", "E_and_w", "smaller_t_max"],
)  # fmt: skip
def test_resume_refuses_other_changes_naming_the_keys(
    tmp_path_factory, capsys, extra, t_max, expected
):
    directory = shared_dir(tmp_path_factory, "resume_other")
    scene, changed, outdir = directory / "a.toml", directory / "b.toml", directory / "out"
    write(scene, scene_text(2))
    write(changed, scene_text(t_max, extra))
    assert call(["run", scene, "-o", outdir], capsys)[0] == 0
    before = listing(outdir) if RANK0 else None
    code, _, err = call(["run", changed, "--resume", outdir], capsys)
    assert code == 2
    if RANK0:
        assert err.startswith(f"plantgrowth: error: --resume {outdir}: "), err
        assert len(err.splitlines()) == 1 and expected in err, err
        assert listing(outdir) == before
