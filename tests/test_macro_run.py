"""The coupled macroscopic run (``plantgrowth run``, docs/model.md sections 4-6 and 9) on
small scenes.

Every scene runs at most once per module (the ``runs`` fixture runs it on first use), in process
through ``plantgrowth.cli.main`` on COMM_WORLD: under ``mpirun -n 2 python -m mpi4py -m pytest``
the fine mesh is distributed and the cell problems are shared among the ranks. The run's
MacroProblem, Homogenizer and cell solves are observed by wrapping the classes for the duration
of the run (nothing of the package is changed). The serial-vs-mpirun comparison starts
``mpirun -n 2 plantgrowth run`` as a subprocess and is ``skip_in_parallel``.

Small scenes: the reference tissue with h = 0.35, H = 1 (or 2 for gradient scenes), t_max = 3,
dt = 1, P2 cell meshes with one element across a wall; the whole module takes seconds. The
cell problems take their exact path (``cell_tolerance = 0``: every distinct input solved, which
the cell-call checks count), except ``gradient_E_preset``, which keeps the default preset's
surrogate for the serial-versus-mpirun check (the surrogate's own tests: test_surrogate.py).
"""

from __future__ import annotations

import csv
import math
import os
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np
import pytest
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.cli import main
from plantgrowth.forms import macro
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.models.macro import model as coupled
from plantgrowth.models.macro.problem import MacroProblem, rectangle_mesh
from plantgrowth.scene import Scene, load_scene, parse_scene
from plantgrowth.scene.presets import DEFAULT_PRESET, knob
from plantgrowth.scene.toml_text import dict_to_toml
from plantgrowth.unitcell.homogenization import Homogenizer
from plantgrowth.unitcell.solver import CellSolver

pytestmark = pytest.mark.mpi  # scripts/README.md, "Tests": every test also runs on 2 ranks

BIN = Path(sys.executable).parent
PLANTGROWTH = str(BIN / "plantgrowth")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")

BASE = {
    "tissue": {"h": 0.35, "H": 1.0},
    "time": {"t_max": 3, "dt": 1},
    "accuracy": {"cell_resolution": 1, "cell_tolerance": 0.0},
    "output": {"precision": "float64"},  # fields compared with summary rows to 1e-10
}
SCENES = {  # name -> tables merged into BASE
    # homogeneous, stress law, E != 1, eta != 1, tau > 0 (docs/model.md section 4 consistency check)
    "stress": {
        "material": {"E": 2.0},
        "growth": {"law": "stress", "eta": 1.5, "tau": 0.002},
    },
    "stress_nu0": {"material": {"E": 1.0, "nu": 0.0}, "growth": {"law": "stress"}},
    "strain_nu0": {"material": {"E": 1.0, "nu": 0.0}, "growth": {"law": "strain"}},
    "strain": {"growth": {"law": "strain"}},
    "gradient_E": {
        "tissue": {"H": 2.0},
        "material": {"E": {"from": 0.5, "to": 2.0}},
        "growth": {"law": "strain"},
    },
    "gradient_E_preset": {
        "tissue": {"H": 2.0},
        "material": {"E": {"from": 0.5, "to": 2.0}},
        "growth": {"law": "strain"},
        "accuracy": {"cell_tolerance": knob(DEFAULT_PRESET, "accuracy", "cell_tolerance")},
    },
    "gradient_P1": {
        "tissue": {"H": 2.0},
        "pressure": {"P1": {"from": 0.0005, "to": 0.002}},
        "growth": {"law": "stress"},
    },
    "no_pressure": {"pressure": {"P1": 0.0}, "growth": {"law": "stress"}},
    "none": {"growth": {"law": "none"}},
}
HOMOGENEOUS = ["stress", "stress_nu0", "strain", "strain_nu0"]
COMPARED = [  # summary columns that serial and mpirun runs must reproduce
    "area", "growth_rate_11", "growth_rate_22", "growth_rate_area",
    "u1_max", "u2_max", "det_Fg_min",
]  # fmt: skip


def scene_toml(tables: dict) -> str:
    """BASE with ``tables`` merged in, as TOML text."""
    merged = {k: dict(v) for k, v in BASE.items()}
    for name, entries in tables.items():
        merged.setdefault(name, {}).update(entries)
    return dict_to_toml(merged)


def read_summary(path: Path) -> list[dict[str, float]]:
    with open(path, newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def read_cell_field(outdir: Path, name: str, step: int) -> np.ndarray:
    """A DG0 field at one step, (n_cells_global, 9) for a 2x2 tensor (3x3 padded)."""
    with h5py.File(outdir / "fields" / f"step_{step:06d}.h5", "r") as f:
        return f[name][...]


@dataclass
class Run:
    """What one in-process run produced and what the package objects showed during it."""

    scene_path: Path
    outdir: Path
    scene: Scene
    returncode: int
    rows: list[dict[str, float]]
    active_terms: list[str]
    K_is_none: bool
    P2vec_is_none: bool
    homogenizer_pressure: bool
    homogenizer_strain_averages: bool
    cell_calls: list[tuple] = field(default_factory=list)  # over all ranks


def run_scene(directory: Path, name: str, text: str, inspect=None) -> Run:
    """Write the scene, ``main(["run", ...])`` it on COMM_WORLD, collect what it did.

    ``inspect(problem, scene)`` (collective) is called with the run's MacroProblem after the run,
    while it still holds the last step's coefficients.
    """
    comm = MPI.COMM_WORLD
    scene_path, outdir = directory / f"{name}.toml", directory / name
    if comm.rank == 0:
        scene_path.write_text(text)
    comm.Barrier()
    seen: dict = {}
    cell_calls: list[tuple] = []
    solve = CellSolver.solve

    def problem_factory(*args, **kwargs):
        seen["problem"] = MacroProblem(*args, **kwargs)
        return seen["problem"]

    def homogenizer_factory(*args, **kwargs):
        seen["homogenizer"] = Homogenizer(*args, **kwargs)
        return seen["homogenizer"]

    def recording_solve(self, Fg=None, E=1.0, nu=0.3, pressure=True, strain_averages=True):
        result = solve(self, Fg, E, nu, pressure, strain_averages)
        cell_calls.append((pressure, strain_averages, result.K_hom is None, result.dbar_w is None))
        return result

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(coupled, "MacroProblem", problem_factory)
        mp.setattr(coupled, "Homogenizer", homogenizer_factory)
        mp.setattr(CellSolver, "solve", recording_solve)
        returncode = main(["run", str(scene_path), "-o", str(outdir)])
    comm.Barrier()  # rank 0 writes the last summary row after the last collective
    problem, homogenizer = seen.pop("problem"), seen.pop("homogenizer")
    scene = load_scene(scene_path)
    if inspect is not None:
        inspect(problem, scene)
    run = Run(
        scene_path, outdir, scene, returncode, read_summary(outdir / "summary.csv"),
        list(problem.active_terms), problem.K is None, problem.P2vec is None,
        homogenizer.pressure, homogenizer.strain_averages,
        [c for part in comm.allgather(cell_calls) for c in part],
    )  # fmt: skip
    del problem, homogenizer
    return run


class _Runs:
    """Runs each scene of SCENES on first use (all ranks ask in the same order)."""

    def __init__(self, directory: Path) -> None:
        self.directory = directory
        self._done: dict[str, Run] = {}

    def __getitem__(self, name: str) -> Run:
        if name not in self._done:
            run = run_scene(self.directory, name, scene_toml(SCENES[name]))
            assert run.returncode == 0, f"scene {name} failed with code {run.returncode}"
            self._done[name] = run
        return self._done[name]


def _shared_dir(factory, name: str) -> Path:
    comm = MPI.COMM_WORLD
    return comm.bcast(factory.mktemp(name) if comm.rank == 0 else None, root=0)


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> _Runs:
    return _Runs(_shared_dir(tmp_path_factory, "macro_runs"))


def analytic_stress_rate(scene: Scene) -> float:
    """eta [(1 - phi_w)/phi_w P1 - tau]_+ (docs/model.md section 4, consistency check)."""
    g = scene.growth
    phi_w = scene.cell.at(0.0, 0.0).phi_w  # the HoneycombCell of a homogeneous scene
    return g.eta.start * max((1.0 - phi_w) / phi_w * scene.P1.start - g.tau.start, 0.0)


# --- 1. homogeneous reference scenes ------------------------------------------------------------


@pytest.mark.parametrize("name", HOMOGENEOUS)
def test_homogeneous_growth_is_uniform_and_constant(runs, name):
    """Homogeneous parameters, constant P1, no loads: G is the same in every cell and at every
    step (docs/model.md section 4). The discrete u is then linear, i.e. inside the P1 space, so the
    only deviation is the round-off of the LU solve (residual ~1e-14, see the summary): 1e-10."""
    run = runs[name]
    n_steps = run.scene.time.n_steps
    assert len(run.rows) == n_steps + 1
    for step in range(n_steps + 1):
        G = read_cell_field(run.outdir, "G", step)
        G11, G12, G21, G22 = G[:, 0], G[:, 1], G[:, 3], G[:, 4]
        scale = np.abs(G11).max()
        assert scale > 1e-3  # the scenes do grow
        for component in (G11, G22):
            assert component.max() - component.min() <= 1e-10 * scale
        assert np.abs(G12).max() <= 1e-10 * scale and np.abs(G21).max() <= 1e-10 * scale
        # the summary's means are the field's values
        row = run.rows[step]
        assert row["growth_rate_11"] == pytest.approx(G11.mean(), rel=1e-10)
        assert row["growth_rate_22"] == pytest.approx(G22.mean(), rel=1e-10)
    for column in ("growth_rate_11", "growth_rate_22", "growth_rate_area"):
        values = np.array([row[column] for row in run.rows])
        assert values.max() - values.min() <= 1e-10 * np.abs(values).max(), column
    # exp integrator with G = g I constant: det Fg(t) = exp(t tr G), exactly up to round-off
    rate = run.rows[0]["growth_rate_area"]
    for row in run.rows:
        assert row["det_Fg_min"] == pytest.approx(math.exp(row["t"] * rate), rel=1e-12)


@pytest.mark.parametrize("name", ["stress", "stress_nu0"])
def test_stress_law_rate_is_analytic(runs, name):
    """G = eta [(1 - phi_w)/phi_w P1 - tau]_+ I (docs/model.md section 4), for E = 2 and E = 1.

    The requirement is 0.5 %, but the rate is exact up to the LU round-off: the linear u with
    E_hom eps_el = -(K_hom + (phi_w - 1) I) P1 lies in the P1 space and makes the integrand of
    the weak form vanish, so sigma_hom = E_hom eps_el + K_hom P1 = (1 - phi_w) P1 I whatever the
    errors of the cell problems' E_hom and K_hom; and phi_w is the area of the polygonal walls,
    meshed exactly, so the discrete phi_w equals HoneycombCell().phi_w to round-off.
    Hence 1e-8 (measured: ~5e-15).
    """
    run = runs[name]
    expected = analytic_stress_rate(run.scene)
    assert expected > 1e-3  # a non-trivial rate (tau below the threshold)
    for row in run.rows:
        assert row["growth_rate_11"] == pytest.approx(expected, rel=1e-8)
        assert row["growth_rate_22"] == pytest.approx(expected, rel=1e-8)
    G = read_cell_field(run.outdir, "G", run.scene.time.n_steps)
    assert np.allclose(G[:, [0, 4]], expected, rtol=1e-8, atol=0)


def test_stress_and_strain_laws_agree_when_nu_is_zero(runs):
    """E = 1, nu = 0: the plane-stress wall law sigma = lam tr(e) I + 2 mu e has lam = 0 and
    mu = 1/2, so the wall stress *is* the wall strain, pointwise in every cell problem. The
    homogenized stress E_hom eps_el + K_hom P1 and the homogenized strain
    phi_w eps_el + dbar[w]:eps_el + P1 dbar[v] are then averages of the same field over Y_w,
    sigma_hom = eps_hom exactly, and the two laws drive the same G: 1e-8 is round-off headroom.
    """
    stress, strain = runs["stress_nu0"], runs["strain_nu0"]
    assert len(stress.rows) == len(strain.rows)
    for a, b in zip(stress.rows, strain.rows, strict=True):
        for column in ("growth_rate_11", "growth_rate_22", "area", "u1_max", "u2_max"):
            assert b[column] == pytest.approx(a[column], rel=1e-8), column
    assert stress.rows[0]["growth_rate_11"] > 1e-3


# --- 3. pressure gradient: the grad(P1) and P2vec body forces cancel ----------------------------

GEOMETRIES = [  # (l1, l2, theta, w): regular and one change each
    (1.0, 1.0, 30.0, 0.05),
    (1.5, 1.0, 30.0, 0.05),
    (1.0, 1.0, 45.0, 0.05),
    (1.0, 1.0, 30.0, 0.1),
]
GROWTH_TENSORS = [np.eye(2), np.diag([1.3, 0.9]), np.array([[1.1, 0.2], [0.0, 1.0]])]


def test_P2_matrix_is_void_fraction_times_identity():
    """P2vec = (1 - phi_w) grad(P1) for every geometry and growth tensor.

    With P2 = -grad(P1) . y (docs/model.md section 6) and N the wall's outward normal on the
    membrane Gamma (pointing into the void Y_c, i.e. N = -n for the void's outward normal n),
        P2vec_i = (1/|Y|) int_Gamma P2 N_i = (1/|Y|) d_j P1 int_{dY_c} y_j n_i
                = (1/|Y|) d_j P1 int_{Y_c} d_i y_j = (|Y_c|/|Y|) d_i P1 = (1 - phi_w) d_i P1,
    by the divergence theorem (int_{dY_c} y_j n_i = |Y_c| delta_ij, whatever the origin). So the
    two body forces of docs/model.md section 4, Jg (1 - phi_w) Fg^{-T} grad(P1) and
    -Jg Fg^{-T} P2vec, cancel pointwise. The matrix does not depend on Fg (it is geometric).
    Tolerance 1e-12: the void is a polygon, meshed exactly, and y_j n_i is integrated exactly on
    straight facets; what remains is the round-off of sums over the facets and triangles.
    """
    geometry = np.array([g for g in GEOMETRIES for _ in GROWTH_TENSORS])
    Fg = np.array([F for _ in GEOMETRIES for F in GROWTH_TENSORS])
    n = len(geometry)
    homogenizer = Homogenizer(1, 1e-6, False, False, MPI.COMM_WORLD)
    nt = homogenizer.homogenize(geometry, np.ones(n), np.full(n, 0.3), Fg)
    phi_w = np.array([HoneycombCell(*g).phi_w for g in geometry])
    assert np.allclose(nt.phi_w, phi_w, rtol=1e-12, atol=0)
    expected = (1.0 - phi_w)[:, None, None] * np.eye(2)
    assert np.allclose(nt.P2_matrix, expected, rtol=0, atol=1e-12)
    assert len(set(np.round(phi_w, 6))) == len(GEOMETRIES)  # the geometries do differ


def test_pressure_gradient_body_forces_cancel_in_the_macro_problem(tmp_path_factory):
    """In a run of a P1-gradient scene, after the last homogenization step (non-uniform Fg,
    interpolated phi_w and P2vec), the assembled body-force vector of
    ``macro_pressure_gradient_rhs`` vanishes to round-off, both relative to the pressure-term
    vector and to the grad(P1) term alone; cell by cell, P2vec = (1 - phi_w) grad(P1).
    Tolerance 1e-12: P2vec = (W P2_matrix) grad P1 and phi_w = W phi_w(nodes) use the same
    interpolation weights, which sum to 1, so the cancellation is exact up to round-off.
    """
    measured: dict[str, float] = {}

    def inspect(problem: MacroProblem, scene: Scene) -> None:
        msh = problem.mesh
        psi = ufl.TestFunction(problem.V)
        gradient = scene.P1.slope
        grad_P1 = ufl.as_vector([fem.Constant(msh, gradient), 0.0])
        x = ufl.SpatialCoordinate(msh)
        P1 = fem.Constant(msh, scene.P1.start) + fem.Constant(msh, gradient) * x[0]
        zero = fem.Function(problem.P2vec.function_space)
        forms = {
            "both": macro.macro_pressure_gradient_rhs(
                psi, problem.Fg, problem.phi_w, grad_P1, problem.P2vec, ufl.dx
            ),
            "grad_P1_only": macro.macro_pressure_gradient_rhs(
                psi, problem.Fg, problem.phi_w, grad_P1, zero, ufl.dx
            ),
            "pressure": macro.macro_pressure_rhs(
                psi, problem.Fg, problem.K, problem.phi_w, P1, ufl.dx
            ),
        }
        for key, form in forms.items():
            b = fem.petsc.assemble_vector(fem.form(form))
            b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            measured[key] = b.norm()
            b.destroy()
        P2vec = problem.cell_values(problem.P2vec)
        phi_w = problem.cell_values(problem.phi_w)[:, 0]
        expected = np.column_stack([(1.0 - phi_w) * gradient, np.zeros_like(phi_w)])
        measured["pointwise"] = comm.allreduce(
            float(np.abs(P2vec - expected).max()) / abs(gradient), op=MPI.MAX
        )
        Fg = problem.cell_values(problem.Fg)
        measured["Fg_spread"] = comm.allreduce(float(np.ptp(Fg[:, 0])), op=MPI.MAX)

    comm = MPI.COMM_WORLD
    directory = _shared_dir(tmp_path_factory, "gradient_P1")
    run = run_scene(directory, "gradient_P1", scene_toml(SCENES["gradient_P1"]), inspect)
    assert run.returncode == 0
    assert measured["Fg_spread"] > 1e-4  # growth is not uniform: a real test of the cancellation
    assert measured["grad_P1_only"] > 0.0 and measured["pressure"] > 0.0
    assert measured["both"] < 1e-12 * measured["grad_P1_only"]
    assert measured["both"] < 1e-12 * measured["pressure"]
    assert measured["pointwise"] < 1e-12
    print(
        f"|b(grad P1 + P2vec)| / |b(grad P1)| = {measured['both'] / measured['grad_P1_only']:.2e}, "
        f"pointwise {measured['pointwise']:.2e}"
    )


def test_active_terms_follow_the_pressure_field():
    gradient = macro_problem(_merged("gradient_P1"))
    constant = macro_problem(_merged("stress"))
    assert "pressure" in gradient.active_terms and "pressure" in constant.active_terms
    assert any(t.startswith("pressure gradient") for t in gradient.active_terms)
    assert gradient.P2vec is not None and gradient.K is not None
    assert not any("gradient" in t for t in constant.active_terms)
    assert constant.P2vec is None and constant.K is not None


def macro_problem(data: dict) -> MacroProblem:
    """The MacroProblem of a scene on its rectangle, distributed on COMM_WORLD."""
    scene = parse_scene(data)
    return MacroProblem(scene, rectangle_mesh(scene, MPI.COMM_WORLD))


def _merged(name: str) -> dict:
    merged = {k: dict(v) for k, v in BASE.items()}
    for table, entries in SCENES[name].items():
        merged.setdefault(table, {}).update(entries)
    return merged


# --- 4. pruning ---------------------------------------------------------------------------------


def test_zero_pressure_computes_no_K(runs):
    run = runs["no_pressure"]
    assert "pressure" not in run.active_terms
    assert run.K_is_none and run.P2vec_is_none
    assert run.homogenizer_pressure is False
    assert run.cell_calls, "no cell problem was solved"
    assert all(pressure is False and K_none for pressure, _, K_none, _ in run.cell_calls)
    assert "no K_hom cell problem" in (run.outdir / "run.log").read_text()
    # nothing drives growth: P1 = 0, no loads, tau = 0
    assert all(row["growth_rate_area"] == 0.0 for row in run.rows)


def test_loads_add_a_traction_term():
    unloaded = macro_problem(_merged("stress"))
    assert not any("traction" in t for t in unloaded.active_terms)
    loaded = _merged("stress") | {"loads": {"left": [-0.001, 0.0], "right": [0.001, 0.0]}}
    assert "traction on right" in macro_problem(loaded).active_terms
    zero_load = _merged("stress") | {"loads": {"top": [0.0, 0.0]}}  # zero loads are dropped
    assert not any("traction" in t for t in macro_problem(zero_load).active_terms)


def test_homogeneous_isotropic_run_solves_one_cell_problem(runs):
    """Fg = g(t) I everywhere: Fg / sqrt(det Fg) = I at every node and step, one distinct key."""
    run = runs["stress"]
    counts = [int(row["n_cell_solves"]) for row in run.rows]
    assert counts[0] == 1 and sum(counts) == 1
    assert len(run.cell_calls) == 1  # over all ranks


def test_stress_law_computes_no_strain_averages(runs):
    stress, strain = runs["stress"], runs["strain"]
    assert stress.homogenizer_strain_averages is False
    assert all(not averages and dbar_none for _, averages, _, dbar_none in stress.cell_calls)
    assert strain.homogenizer_strain_averages is True
    assert all(averages and not dbar_none for _, averages, _, dbar_none in strain.cell_calls)


def test_law_none_is_one_static_solve(runs):
    run = runs["none"]
    assert len(run.rows) == 1 and run.rows[0]["t"] == 0.0
    assert run.rows[0]["growth_rate_11"] == run.rows[0]["growth_rate_22"] == 0.0
    assert run.rows[0]["u1_max"] > 0.0  # the pressure does deform the tissue
    assert np.all(read_cell_field(run.outdir, "G", 0) == 0.0)
    assert sorted(p.name for p in (run.outdir / "fields").iterdir()) == ["step_000000.h5"]


# --- 5. serial vs mpirun -n 2 -------------------------------------------------------------------


@pytest.mark.skip_in_parallel
@pytest.mark.parametrize("name", ["stress", "gradient_E", "gradient_E_preset"])
def test_mpirun_reproduces_the_serial_summary(runs, name, tmp_path):
    """``mpirun -n 2 plantgrowth run`` against the serial in-process run of the same scene.

    1e-8 relative: the cell problems are the same (each solved once, on one rank, with the same
    LU), only the macro LU (MUMPS on 2 ranks) and the order of the reductions differ (~1e-14).
    """
    mpirun = shutil.which("mpirun")
    if mpirun is None:
        pytest.skip("mpirun not found")
    serial = runs[name]
    if name == "gradient_E":  # distinct keys at later steps: cell problems are really shared
        assert all(row["n_cell_solves"] > 1 for row in serial.rows[1:])
    outdir = tmp_path / "mpirun"
    command = [mpirun, "-n", "2", PLANTGROWTH, "run", str(serial.scene_path), "-o", str(outdir)]
    done = subprocess.run(command, capture_output=True, text=True, env=ENV, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "on 2 rank(s)" in (outdir / "run.log").read_text()
    parallel = read_summary(outdir / "summary.csv")
    assert len(parallel) == len(serial.rows)
    worst = 0.0
    for a, b in zip(serial.rows, parallel, strict=True):
        assert a["n_cell_solves"] == b["n_cell_solves"]
        for column in COMPARED:
            assert b[column] == pytest.approx(a[column], rel=1e-8, abs=1e-300), column
            worst = max(worst, abs(b[column] - a[column]) / max(abs(a[column]), 1e-300))
    print(f"{name}: largest relative serial-vs-mpirun difference {worst:.2e}")
