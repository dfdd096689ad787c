"""Helpers for tests that drive the ``plantgrowth`` CLI (not a test module).

In-process: ``main`` on every rank (valid under mpirun; rank 0 alone prints and writes the
files that are not collective), in a directory created on rank 0 and shared. As processes: the
environment Open MPI needs as root, and the live processes of a run.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from plantgrowth.cli import main

PLANTGROWTH = str(Path(sys.executable).parent / "plantgrowth")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1",
           OMPI_MCA_btl_vader_single_copy_mechanism="none")  # fmt: skip
RANK0 = MPI.COMM_WORLD.rank == 0
RUN_TIMEOUT = 180.0  # s; the test runs take seconds, mpirun ones a few more


def shared_dir(factory, name: str) -> Path:
    """A fresh temporary directory, made on rank 0, the same path on every rank."""
    comm = MPI.COMM_WORLD
    return comm.bcast(factory.mktemp(name) if comm.rank == 0 else None, root=0)


def stopped_and_straight_runs(build, scene, directory: Path) -> list[np.ndarray]:
    """Runs ``scene`` (a model made by ``build(scene, comm)``) uninterrupted into
    ``directory/straight`` and stopped after step 1 then resumed into ``directory/stopped``
    (collective); returns the saved ``fibre_angle`` of the last step, 3, of both."""
    from plantgrowth.runner.output import StateFile
    from plantgrowth.runner.timeloop import run_model

    comm = MPI.COMM_WORLD
    straight, stopped = directory / "straight", directory / "stopped"
    for outdir in (straight, stopped):
        if comm.rank == 0:
            outdir.mkdir()
        comm.barrier()
    run_model(build(scene, comm), scene, straight, comm)
    run_model(build(scene, comm), scene, stopped, comm, n_steps=1)
    run_model(build(scene, comm), scene, stopped, comm, resume=True)
    comm.barrier()  # rank 0 writes state.h5 after the others have finished the last step
    return [StateFile(d, comm).read(3)["fibre_angle"] for d in (straight, stopped)]


def serial_and_mpirun_runs(scene: Path) -> list[Path]:
    """``mpirun -n 1`` and ``-n 2 plantgrowth run scene`` (no unit-cell cache) into
    ``ranks1``, ``ranks2`` beside the scene; their output directories (skips without mpirun)."""
    mpirun = shutil.which("mpirun")
    if mpirun is None:
        pytest.skip("mpirun not found")
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1",
               OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", PLANTGROWTH_CACHE_DIR="off")  # fmt: skip
    plantgrowth = str(Path(sys.executable).parent / "plantgrowth")
    outdirs = []
    for ranks in (1, 2):
        outdir = scene.parent / f"ranks{ranks}"
        command = [mpirun, "-n", str(ranks), plantgrowth, "run", str(scene), "-o", str(outdir)]
        done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=300)
        assert done.returncode == 0, done.stderr
        outdirs.append(outdir)
    return outdirs


def runs_and_pictures(factory, name: str, scenes: dict[str, str]) -> tuple[dict[str, Path], Path]:
    """Each scene (name -> TOML text) run in process on every rank into ``DIR/<name>``, and an
    empty ``DIR/pictures``: ({name: run directory}, the pictures' directory)."""
    directory = shared_dir(factory, name)
    out = {}
    for scene, text in scenes.items():
        write(directory / f"{scene}.toml", text)
        assert main(["run", str(directory / f"{scene}.toml"), "-o", str(directory / scene)]) == 0
        MPI.COMM_WORLD.Barrier()
        out[scene] = directory / scene
    pictures = directory / "pictures"
    if RANK0:
        pictures.mkdir()
    MPI.COMM_WORLD.Barrier()
    return out, pictures


def write(path: Path, text: str) -> None:
    """Write on rank 0 (making the parents), then let every rank see it."""
    if RANK0:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    MPI.COMM_WORLD.Barrier()


def call(argv: list, capsys) -> tuple[int, str, str]:
    """``main(argv)`` on every rank: (exit code, stdout, stderr) of this rank."""
    capsys.readouterr()
    code = main([str(a) for a in argv])
    MPI.COMM_WORLD.Barrier()  # rank 0 writes the last rows and log lines after the collectives
    out, err = capsys.readouterr()
    return code, out, err


def processes_mentioning(text: str) -> list[int]:
    """Live processes whose command line contains ``text`` (zombies are dead)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
            state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except (OSError, IndexError):
            continue
        if text in cmdline and state != "Z":
            found.append(int(entry.name))
    return found


def start(argv: list[str], cwd: Path, ranks: int = 1) -> subprocess.Popen:
    """``plantgrowth argv`` (under ``mpirun -n ranks`` if ranks > 1) in its own session; output
    to cwd/stdout.txt and cwd/stderr.txt (a pipe nobody reads could block the run)."""
    command = [PLANTGROWTH, *argv]
    if ranks > 1:
        command = ["mpirun", "-n", str(ranks), *command]
    out = open(cwd / "stdout.txt", "w")  # closed by finish()
    err = open(cwd / "stderr.txt", "w")
    proc = subprocess.Popen(
        command, cwd=cwd, stdout=out, stderr=err, env=ENV, start_new_session=True
    )
    proc.files = (out, err)  # type: ignore[attr-defined]
    return proc


def finish(proc: subprocess.Popen, cwd: Path, timeout: float = RUN_TIMEOUT) -> tuple[int, str]:
    """Wait for the process; its exit code and stderr (kill the session if it hangs)."""
    try:
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        pytest.fail(f"still running after {timeout:g} s")
    finally:
        for f in proc.files:  # type: ignore[attr-defined]
            f.close()
    return proc.returncode, (cwd / "stderr.txt").read_text()
