"""Malformed inputs end in exit code 2 and one line ``plantgrowth: error: ...`` naming the field,
with no traceback and nothing written (tests/malformed_inputs.py generates them).

In-process: 300 seeded cases through ``plantgrowth.cli.main`` (valid under mpirun: every rank calls
``main``, rank 0 alone prints; each case has its own directory, created on rank 0 and shared, which
is also the working directory so that a default ``results/`` output would be seen). Then one case
of nine classes as real subprocesses of the CLI (``skip_in_parallel``), and the three sizes that
have no upper bound (``cell --resolution``, ``compare --nx``, ``compare --resolution``) with a time
limit: they must be refused at once, not tried.
"""

from __future__ import annotations

from pathlib import Path

import malformed_inputs as mi
import pytest
from mpi4py import MPI

from plantgrowth.cli import main

SEED = 20240611
N_IN_PROCESS = 300
CASES = [c for c in mi.generate(SEED, N_IN_PROCESS) if not c.isolate]
SUBPROCESS_TIMEOUT = 20.0  # s; refusing an input takes ~1-2 s (interpreter, imports)


def test_generator_is_seeded_and_covers_every_class():
    again = [c for c in mi.generate(SEED, N_IN_PROCESS) if not c.isolate]
    assert [(c.name, c.argv, c.files) for c in again] == [(c.name, c.argv, c.files) for c in CASES]
    assert {c.cls for c in mi.generate(SEED, 1200)} == set(mi.CLASSES)
    assert mi.generate(SEED + 1, 50) != mi.generate(SEED, 50)


def _case_dir(factory, case: mi.Case) -> Path:
    comm = MPI.COMM_WORLD
    return comm.bcast(factory.mktemp(case.name[:40]) if comm.rank == 0 else None, root=0)


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_bad_input_in_process(case, tmp_path_factory, monkeypatch, capsys):
    comm = MPI.COMM_WORLD
    directory = _case_dir(tmp_path_factory, case)
    argv = case.materialize(directory) if comm.rank == 0 else None
    argv = comm.bcast(argv, root=0)
    before = mi.snapshot(directory) if comm.rank == 0 else None
    monkeypatch.chdir(directory)
    capsys.readouterr()
    code = main(argv)
    comm.Barrier()  # rank 0 checks the directory after every rank has returned
    out, err = capsys.readouterr()
    if comm.rank == 0:
        found = mi.problems(case, directory, code, out, err, before)
        assert not found, f"{case.name}: argv {argv}:\n" + "\n".join(found)
    else:
        assert code == case.code
        assert err == "" and "Traceback" not in out


SUBPROCESS_CLASSES = ("wrong_type", "nonfinite", "wall_too_thick", "binary_garbage", "bad_mesh",
                      "toml_syntax", "cli_cell", "cli_parse", "output_dir")  # fmt: skip
SUBPROCESS_CASES = mi.one_per_class(SEED, SUBPROCESS_CLASSES) + mi.unbounded_cases()


@pytest.mark.skip_in_parallel
@pytest.mark.parametrize("case", SUBPROCESS_CASES, ids=[c.name for c in SUBPROCESS_CASES])
def test_bad_input_subprocess(case, tmp_path):
    """Exit code 2 at the process level, no traceback, nothing written; a size without an upper
    bound (``unbounded_cases``) must be refused within the time limit, not tried."""
    argv = case.materialize(tmp_path)
    before = mi.snapshot(tmp_path)
    code, out, err = mi.run_cli(argv, tmp_path, SUBPROCESS_TIMEOUT)
    found = mi.problems(case, tmp_path, code, out, err, before)
    assert not found, f"{case.name}: argv {argv}:\n" + "\n".join(found)
