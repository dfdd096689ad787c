"""Start-up loads only what a command needs (issue 23, item 4): ``--version`` and ``--help``
neither MPI nor numpy, ``validate`` of a scene whose fields need no mesh neither dolfinx, PETSc,
gmsh, scipy, h5py nor matplotlib, and a run whose cell values are cached no gmsh (no mesh is
built) and no matplotlib. A command started without a launcher starts MPI isolated, leaving the
user's environment as it was (``plantgrowth/cli/mpi_start.py``); under mpirun MPI starts as
configured.

Each command runs in a fresh process (a small runner calls ``main`` and then lists the loaded
modules in a file), so nothing imported by pytest or an earlier test hides a load. Subprocess
tests: ``skip_in_parallel`` (the 2-rank case runs its own ``mpirun``).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from importlib import metadata
from pathlib import Path

import pytest
from cli_helpers import ENV

from plantgrowth.base import dist_versions

REPO = Path(__file__).resolve().parents[1]
RUNNER = """
import os, sys
from plantgrowth.cli import main
try:
    code = main(sys.argv[1:])
except SystemExit as stop:  # argparse's --help and --version
    code = stop.code
with open(os.path.join(os.environ["LOADED_DIR"], f"{os.getpid()}.txt"), "w") as f:
    f.write(" ".join(sorted(sys.modules)))
sys.exit(code)
"""
SOLVER = {"dolfinx", "dolfinx_mpc", "petsc4py.PETSc", "ufl", "basix", "gmsh", "scipy", "h5py",
          "matplotlib"}  # fmt: skip
"""What a command that solves nothing must not load (each costs 20-450 ms; dolfinx, ufl and
PETSc together about 0.5 s, gmsh 0.35-0.45 s: ``python -X importtime``)."""
NOT_EVEN_MPI = SOLVER | {"mpi4py.MPI", "numpy"}
"""``--help`` and ``--version``: not MPI_Init either (0.3-0.5 s)."""
NOT_IN_A_RUN = {"pkg_resources", "scipy.spatial", "matplotlib"}
"""What a run that does not resume never loads (issue 33, item 3): ``pkg_resources``, which ufl
and ffcx import for their version only (0.07-0.13 s; ``plantgrowth/base/dist_versions.py``),
scipy.spatial's k-d tree (0.05-0.1 s; matches saved points at a resume only), matplotlib."""
pytestmark = pytest.mark.skip_in_parallel


def loaded(argv: list[str], ranks: int = 1, env: dict | None = None) -> tuple[int, str, set]:
    """(exit code, stdout, the modules loaded on any rank) of ``plantgrowth argv`` in a fresh
    process (under ``mpirun -n ranks`` if ranks > 1); each process lists its modules in a file
    of its own (on a shared stderr the ranks' long lines would interleave)."""
    command = [sys.executable, "-c", RUNNER, *argv]
    if ranks > 1:
        command = ["mpirun", "-n", str(ranks), *command]
    with tempfile.TemporaryDirectory() as lists:
        done = subprocess.run(command, capture_output=True, text=True, cwd=REPO, timeout=300,
                              env=dict(env or ENV, LOADED_DIR=lists))  # fmt: skip
        files = list(Path(lists).iterdir())
        assert len(files) == ranks, done.stderr
        modules = set().union(*(set(f.read_text().split()) for f in files))
    return done.returncode, done.stdout, modules


def heavy(modules: set, names: set) -> set:
    """The modules of ``names`` (or their submodules) among ``modules``."""
    return {m for m in modules if any(m == n or m.startswith(n + ".") for n in names)}


@pytest.mark.parametrize(
    "argv", [["--version"], ["--help"], ["run", "--help"], ["validate", "--help"],
             ["sweep", "--help"], ["render", "--help"], ["export", "--help"],
             ["compare", "--help"]],
)  # fmt: skip
def test_help_and_version_load_neither_mpi_nor_numpy(argv):
    code, out, modules = loaded(argv)
    assert code == 0 and "plantgrowth" in out
    assert not heavy(modules, NOT_EVEN_MPI), heavy(modules, NOT_EVEN_MPI)


@pytest.mark.parametrize("ranks", [1, 2])
def test_validate_without_place_checks_loads_no_solver(ranks):
    """The reference scene's fields are constant: no mesh, so no dolfinx; on 2 ranks too,
    printing once."""
    code, out, modules = loaded(["validate", "scenes/reference_stress.toml"], ranks)
    assert code == 0 and out.count("valid macro scene") == 1, out
    assert not heavy(modules, SOLVER), heavy(modules, SOLVER)


def test_a_bad_command_line_loads_no_solver():
    code, _, modules = loaded(["validate", "no_such_scene.toml"])
    assert code == 2
    assert not heavy(modules, SOLVER), heavy(modules, SOLVER)


def test_the_runner_sees_what_a_command_loads():
    """The check above can fail: a scene whose field varies is checked on its mesh, which
    loads dolfinx and PETSc."""
    code, _, modules = loaded(["validate", "scenes/examples/soft_disc.toml"])
    assert code == 0
    assert {"dolfinx", "petsc4py.PETSc"} <= modules


def test_a_run_builds_no_mesh_with_gmsh_once_its_cells_are_cached(tmp_path):
    """The reference scene (two steps, the coarsest cell mesh): the first run solves its cell
    problems on a gmsh mesh (the runner sees gmsh: the check can fail); the second finds the
    values in the cache and loads no gmsh. Neither loads what no run needs (``NOT_IN_A_RUN``)."""
    text = (REPO / "scenes/reference_stress.toml").read_text()
    scene = tmp_path / "scene.toml"
    scene.write_text(text.replace("t_max = 60.0", "t_max = 1.0").replace(
        "[accuracy]", "[accuracy]\ncell_resolution = 1"))  # fmt: skip
    env = dict(ENV, PLANTGROWTH_CACHE_DIR=str(tmp_path / "cache"))
    runs = [loaded(["run", str(scene), "-o", str(tmp_path / f"out{k}")], env=env) for k in (1, 2)]
    assert [code for code, _, _ in runs] == [0, 0]
    assert "gmsh" in runs[0][2] and not heavy(runs[1][2], {"gmsh"}), heavy(runs[1][2], {"gmsh"})
    for _, _, modules in runs:
        assert {"dolfinx", "ufl", "ffcx", "scipy.sparse"} <= modules  # what loaded them ran
        assert not heavy(modules, NOT_IN_A_RUN), heavy(modules, NOT_IN_A_RUN)


VERSIONS = """
import sys
import plantgrowth
import dolfinx.fem, ffcx, ufl
before = "pkg_resources" in sys.modules
import pkg_resources
print(before, hasattr(pkg_resources, "working_set"), ufl.__version__, ffcx.__version__,
      *(pkg_resources.get_distribution(d).version for d in ("fenics-ufl", "fenics-ffcx")))
"""


def test_ufl_and_ffcx_know_their_versions_without_pkg_resources():
    """After ``import plantgrowth`` dolfinx loads ufl and ffcx without pkg_resources, and their
    versions are pkg_resources' own (ffcx's is part of its forms' cache signature); a later
    ``import pkg_resources`` gets the real module."""
    done = subprocess.run([sys.executable, "-c", VERSIONS], capture_output=True, text=True,
                          env=ENV, timeout=120)  # fmt: skip
    before, real, ufl, ffcx, ufl_pkg, ffcx_pkg = done.stdout.split()
    assert (before, real) == ("False", "True"), done.stderr
    assert (ufl, ffcx) == (ufl_pkg, ffcx_pkg)


PROBE = """
import os
from plantgrowth.cli.mpi_start import SINGLETON_MCA, world
comm = world()
mine = " ".join([str(comm.size), str(comm.allreduce(1)),
                 *(os.environ.get(k, "-") for k in SINGLETON_MCA)])
ranks = comm.gather(mine)  # rank 0 prints them all, in one line each
if comm.rank == 0:
    print("\\n".join(ranks))
"""


def test_a_singleton_starts_mpi_without_leaving_its_settings_behind():
    """The isolated start works (a collective on the world) and the settings are gone from the
    environment afterwards, so a process started later (mpirun) gets the user's."""
    env = {k: v for k, v in ENV.items() if k not in ("OMPI_MCA_pml",)}
    done = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, env=env,
                          timeout=60)  # fmt: skip
    assert done.stdout.split() == ["1", "1", "-", "-"], done.stderr


def test_the_users_own_mpi_settings_are_kept():
    env = dict(ENV, OMPI_MCA_pml="ob1", OMPI_MCA_ess_singleton_isolated="0")
    done = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, env=env,
                          timeout=60)  # fmt: skip
    assert done.stdout.split() == ["1", "1", "0", "ob1"], done.stderr


def test_under_a_launcher_mpi_starts_as_configured():
    """mpirun -n 2: the ranks talk to each other (a singleton's settings would break that)."""
    done = subprocess.run(["mpirun", "-n", "2", sys.executable, "-c", PROBE], capture_output=True,
                          text=True, env=ENV, timeout=120)  # fmt: skip
    lines = [line.split() for line in done.stdout.splitlines() if line[:1].isdigit()]
    assert lines == [["2", "2", "-", "-"]] * 2, (done.stdout, done.stderr)


def test_the_stand_in_hands_every_other_name_to_the_real_pkg_resources(monkeypatch):
    """A module importing pkg_resources while ufl's ``__init__`` runs gets the stand-in: any name
    but ``get_distribution`` is the real module's, which then replaces the stand-in."""
    stand_in = dist_versions._StandIn("pkg_resources")
    monkeypatch.setitem(sys.modules, "pkg_resources", stand_in)
    assert stand_in.get_distribution("fenics-ufl").version == metadata.version("fenics-ufl")
    assert sys.modules["pkg_resources"] is stand_in
    working_set = stand_in.working_set
    real = sys.modules["pkg_resources"]
    assert real is not stand_in and working_set is real.working_set


def test_libgmsh_is_loaded_deep_bound_unless_a_library_is_preloaded(monkeypatch):
    """meshes/gmsh_api.py loads libgmsh with RTLD_DEEPBIND (0.13-0.16 s of CPU instead of
    0.36-0.48 after dolfinx), but not under LD_PRELOAD, whose library (an interposed malloc, a
    sanitizer) deep binding would bypass. In-process, ctypes.CDLL recorded, nothing loaded."""
    import ctypes
    import os

    from plantgrowth.meshes import gmsh_api

    loads = []
    monkeypatch.setattr(ctypes, "CDLL", lambda name, mode: loads.append((name, mode)))
    monkeypatch.delenv("LD_PRELOAD", raising=False)
    gmsh_api._load_deep_bound()
    assert len(loads) == 1 and "gmsh" in loads[0][0] and loads[0][1] & os.RTLD_DEEPBIND
    monkeypatch.setenv("LD_PRELOAD", "libsomething.so")
    gmsh_api._load_deep_bound()
    assert len(loads) == 1
