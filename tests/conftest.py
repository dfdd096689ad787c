"""Shared pytest configuration (dolfinx style), valid in serial and under mpirun."""

import gc
import os
import zlib

import handler_leaks
import mpi_singleton_env
import pytest

# Before MPI starts here: a pytest-xdist worker (scripts/test.sh runs the serial phase on 2 of them)
# inherits the controller's Open MPI singleton settings, with which neither its own MPI nor an
# mpirun it launches would start.
mpi_singleton_env.forget_inherited()

from mpi4py import MPI  # noqa: E402

# No on-disk cell cache unless a test sets its own: results must not depend on what earlier runs
# (or monkeypatched mutants) left in ~/.cache, and tests write nothing there. Set here, before the
# test modules are imported, because they copy os.environ for their subprocesses at import.
os.environ["PLANTGROWTH_CACHE_DIR"] = "off"


MPI_SAMPLE = 20
"""1 in MPI_SAMPLE of the tests not marked ``mpi`` is marked ``mpi_sample``: scripts/test.sh runs
``mpi or mpi_sample`` on 2 ranks (scripts/README.md, "Tests"). 20: the sample adds about 60
tests and a fifth of the 2-rank phase's time to the ~290 ``mpi`` tests."""


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Mark ``mpi_sample`` the tests, not ``mpi`` nor ``skip_in_parallel``, whose node id's CRC-32
    is 0 modulo MPI_SAMPLE: a fixed, uniform pseudo-random sample (the same on every rank and in
    every run, independent of what a test does). A module that chooses its 2-rank variants
    itself (a module-level ``ON_2_RANKS``, tests/test_hard_cases.py) is left out."""
    for item in items:
        if item.get_closest_marker("mpi") or item.get_closest_marker("skip_in_parallel"):
            continue
        if hasattr(getattr(item, "module", None), "ON_2_RANKS"):
            continue
        if zlib.crc32(item.nodeid.encode()) % MPI_SAMPLE == 0:
            item.add_marker(pytest.mark.mpi_sample)


def pytest_runtest_setup(item):
    """Skip tests marked ``skip_in_parallel`` when running on more than one MPI rank."""
    if item.get_closest_marker("skip_in_parallel") and MPI.COMM_WORLD.size > 1:
        pytest.skip("skipped in parallel (MPI.COMM_WORLD.size > 1)")


@pytest.fixture(autouse=True)
def _collect_garbage_and_sync():
    """On more than one rank, after each test: free PETSc/dolfinx objects collectively (a
    parallel object freed by one rank's collector and not the other's can hang a collective
    destroy, MUMPS's above all), then synchronise ranks. On one rank there is nothing to
    synchronise, and Python's own collector frees what a test left: a full collection walks
    every live object (a worker's heap holds a few hundred thousand after some modules), and
    after each of 2,000 tests it cost 350 s of core time, a third of the serial phase
    (scripts/README.md, "Tests")."""
    yield
    if MPI.COMM_WORLD.size > 1:
        gc.collect()
        MPI.COMM_WORLD.Barrier()


@pytest.fixture(autouse=True)
def _no_logging_handler_left():
    """Fail a test that leaves a handler on the ``plantgrowth`` or root logger, or one on a closed
    stream (tests/handler_leaks.py); what it added is removed, so the next test starts clean."""
    before = handler_leaks.handlers()
    yield
    problems = handler_leaks.leaks(before)
    handler_leaks.remove_added(before)
    if problems:
        pytest.fail("logging handlers left behind: " + "; ".join(problems), pytrace=False)


@pytest.fixture
def mpi_tmp_path(request, tmp_path_factory):
    """A fresh temporary directory shared by all ranks (created on rank 0, path broadcast).

    Lives under pytest's basetemp, never in the source tree.
    """
    comm = MPI.COMM_WORLD
    path = None
    if comm.rank == 0:
        name = request.node.name.replace("[", "_").replace("]", "_")[:30]
        path = tmp_path_factory.mktemp(name)
    path = comm.bcast(path, root=0)
    return path


@pytest.fixture
def surrogate_lookups(monkeypatch):
    """The number of queries of each stop-square lookup pass of the stretch surrogate
    (``LatticeSurrogate._found``), in call order; the list fills as the test runs."""
    from plantgrowth.unitcell import surrogate

    counts: list[int] = []
    original = surrogate.LatticeSurrogate._found

    def counting(self, ids, s, strict=False, quiet=None):
        counts.append(len(ids))
        return original(self, ids, s, strict, quiet)

    monkeypatch.setattr(surrogate.LatticeSurrogate, "_found", counting)
    return counts
