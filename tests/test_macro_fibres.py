"""Fibre-reinforced walls in the macro model (docs/fibres.md; docs/model.md, fibre-reinforced
walls): the director per fine cell, its cell problems on both paths, the output field
``fibre_direction``, summary.csv's ``fibre_order``/``fibre_angle_mean``, resume and mpirun.

Small scenes: h = 0.35 to 0.5, H = 1 or 2, P2 cell meshes with one element across a wall, at most
three steps. Tolerances: ROUND_OFF as in test_macro_exact_solutions.py (the macro LU's relative
error on these 10^3 dofs, measured <= 1e-11, and the independent cell solve repeats the run's own
to round-off); serial against mpirun 1e-8 as in test_macro_run.py (only the macro LU and the
order of the reductions differ).
"""

from __future__ import annotations

import csv
import tomllib
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import (
    RANK0,
    serial_and_mpirun_runs,
    shared_dir,
    stopped_and_straight_runs,
    write,
)
from mpi4py import MPI

from plantgrowth.base.errors import SceneError
from plantgrowth.base.gather import MeshGather
from plantgrowth.models import growth
from plantgrowth.models.fibres import cue as fibres_cue
from plantgrowth.models.fibres import reduce_angle
from plantgrowth.models.macro.model import MacroModel, macro_model
from plantgrowth.runner.timeloop import run_model, summary_columns
from plantgrowth.scene import parse_scene
from plantgrowth.unitcell.solver import CellSolver

ROUND_OFF = 1e-9  # LU round-off of the macro and cell solves (module docstring)
COMM = MPI.COMM_WORLD
FIBRES = {"fibre_stiffness": 5.0, "fibre_angle": 90.0}


def _scene(walls: dict | None = None, **tables):
    data = {
        "tissue": {"h": 0.35, "H": 1.0},
        "pressure": {"P1": 0.001},
        "growth": {"law": "strain", "eta": 1.5},
        "time": {"t_max": 3.0, "dt": 1.0},
        "accuracy": {"cell_resolution": 1, "key_tolerance": 1e-12, "cell_tolerance": 0.0},
        "output": {"fields": ["u", "fibre_direction"] if walls else ["u"]},
    }
    for key, table in tables.items():
        data[key] = data.get(key, {}) | table
    return parse_scene(data | ({"walls": walls} if walls else {}))


def _relative(a: np.ndarray, b: np.ndarray) -> float:
    """max |a - b| / max |b| over all ranks."""
    error = COMM.allreduce(float(np.abs(a - b).max(initial=0.0)), op=MPI.MAX)
    return error / COMM.allreduce(float(np.abs(b).max(initial=0.0)), op=MPI.MAX)


def _two_steps(model: MacroModel) -> tuple[np.ndarray, np.ndarray] | None:
    """G of the second step (after one exp step of dt = 1) and u then, gathered on rank 0 in
    the mesh's canonical order (two meshes of one scene may be partitioned differently)."""
    Fg = model.initial_growth()
    G = model.step(Fg).G
    G = model.step(growth.advance(Fg, G, 1.0, "exp")).G
    n = model.problem.n_owned
    gather = MeshGather(model.problem.V)
    return gather.cell_values(G[:n].reshape(n, 4)), gather.function(model.problem.u)


# --- consequence (1): fibre_stiffness = 0 is the paper's model ----------------------------------


@pytest.mark.mpi
@pytest.mark.parametrize("cell_tolerance", [0.0, 1e-3])
def test_zero_fibre_stiffness_reproduces_the_isotropic_run(cell_tolerance):
    """A fibre_stiffness field that is 0 throughout the tissue (an expression, so the run takes
    the fibred code path: director, fibres passed to the cell problems) gives the isotropic
    run's G and u to round-off, on the exact path and the surrogate's, in a scene whose Fg and
    E vary (the gradient of E)."""
    tables = dict(material={"E": {"from": 0.5, "to": 2.0}},
                  accuracy={"cell_tolerance": cell_tolerance})  # fmt: skip
    plain = macro_model(_scene(**tables), COMM)
    zero = {"fibre_stiffness": {"expr": "where(x1 < 100, 0, 1)"}, "fibre_angle": 30.0}
    fibred = macro_model(_scene(zero, **tables), COMM)
    assert fibred.director is not None and plain.director is None
    (G0, u0), (G1, u1) = _two_steps(plain), _two_steps(fibred)
    if RANK0:
        assert np.abs(G0).max() > 1e-3  # the scene grows
        assert np.abs(G1 - G0).max() <= 1e-12 * np.abs(G0).max()
        assert np.abs(u1 - u0).max() <= 1e-12 * np.abs(u0).max()


# --- consequence (4): homogeneous, unloaded tissue ----------------------------------------------


@pytest.fixture(scope="module")
def fibred_cell():
    """The fibred reference cell's tensors at Fg = I (E = 1, nu = 0.3, E_f / E = 5, a = 90),
    solved on COMM_SELF independently of the run."""
    scene = _scene(FIBRES)
    solver = CellSolver(scene.cell.at(0.0, 0.0), 1, MPI.COMM_SELF, fibres=True)
    return solver.solve(np.eye(2), 1.0, 0.3, fibre_stiffness=5.0, fibre_angle=90.0)


@pytest.mark.mpi
@pytest.mark.parametrize("cell_tolerance", [0.0, 1e-3])
def test_homogeneous_strain_law_grows_fastest_across_the_fibres(fibred_cell, cell_tolerance):
    """Consequence (4) through the scene keys: every fine cell's G is the formula's from the
    fibred cell's own tensors, to the solvers' round-off (the surrogate at Fg = I sits on a
    lattice point: exact), and the tissue grows fastest across the fibres (a = 90: along x1)."""
    model = macro_model(_scene(FIBRES, accuracy={"cell_tolerance": cell_tolerance}), COMM)
    G = model.step(model.initial_growth()).G
    expected = growth.homogeneous_strain_rate(fibred_cell, 0.001, 1.5)  # consequence (4)
    print(f"G = {expected.tolist()}, run's relative error {_relative(G, expected[None]):.2e}")
    assert _relative(G, expected[None]) <= ROUND_OFF
    assert expected[0, 0] > 1.5 * expected[1, 1] > 0.0  # measured 3.3 times faster along x1
    assert abs(expected[0, 1]) <= ROUND_OFF * expected[0, 0]  # orthotropic (consequence 3)


@pytest.mark.mpi
@pytest.mark.parametrize("kinematics", ["linear", "finite"])
def test_homogeneous_stress_law_grows_isotropically(kinematics):
    """Under the stress law sigma_hom = (1 - phi_w) P1 I whatever the walls (docs/model.md
    section 4), so a fibred tissue still grows isotropically with linear kinematics: G = g I in
    every cell, to round-off. With finite kinematics the lumens' water is a follower pressure,
    so the fibred (anisotropic) walls carry S_w = (1 - phi_w) P1 det(Fe) C_e^-1 (docs/model.md
    section 10 (2) as amended): G is still the same in every cell (Newton converged to 1e-10
    relative, far below the 1e-9 asked), and departs from g I by at most the elastic strain
    (measured 0.27% against a largest |Ee| of a few percent)."""
    scene = _scene(FIBRES, growth={"law": "stress", "eta": 1.5}).replace(kinematics=kinematics)
    model = macro_model(scene, COMM)
    result = model.step(model.initial_growth())
    G = result.G[: model.problem.n_owned]
    g = G[:, 0, 0]
    assert COMM.allreduce(float(g.min(initial=np.inf)), op=MPI.MIN) > 0.0
    g_max = COMM.allreduce(float(g.max(initial=-np.inf)), op=MPI.MAX)
    if kinematics == "linear":
        assert _relative(G, g[:, None, None] * np.eye(2)[None]) <= ROUND_OFF
        assert _relative(g, np.full_like(g, g_max)) <= ROUND_OFF
        return
    assert _relative(G, G[:1]) <= ROUND_OFF  # uniform: the tissue is homogeneous
    departure = _relative(G, g[:, None, None] * np.eye(2)[None])
    assert 0.0 < departure <= result.elastic_strain.value


# --- consequence (5): feedback --------------------------------------------------------------------


def _run_rows(scene, directory: Path) -> tuple[list[dict[str, float]] | None, MacroModel]:
    """run_model's summary rows (rank 0; None elsewhere) and the model after the run."""
    if RANK0:
        directory.mkdir()
    COMM.barrier()
    model = macro_model(scene, COMM)
    run_model(model, scene, directory, COMM)
    return (_rows(directory / "summary.csv") if RANK0 else None), model


@pytest.mark.parametrize(
    "cell_tolerance, kinematics", [(0.0, "linear"), (1e-3, "linear"), (1e-3, "finite")]
)
def test_stress_feedback_under_a_lateral_pull_follows_the_closed_form(
    cell_tolerance, kinematics, tmp_path_factory
):
    """A homogeneous tissue pulled along x1 (balanced tractions on left and right, no turgor):
    sigma_hom is the uniaxial stress along x1 whatever the (fibred, anisotropic) walls (finite
    kinematics: S = F^-1 P with F upper triangular, still along x1), so the
    cue is a_Q = 0 with the anisotropy A the run computes (1 up to round-off), and the director
    from 60 degrees follows ``tan a_n = tan 60 exp(-k A n dt)`` (section 11) step after step.
    Tolerance 1e-8 degrees: a_Q is the angle of sigma_12's round-off (measured 1e-11 relative:
    a_Q ~ 1e-10 degrees) and the mean angle comes from an area mean of exp(2 i a) (~1e-14)."""
    k, pull = 0.5, 1e-3
    scene = _scene(
        {"fibre_stiffness": 5.0, "fibre_angle": 60.0},
        pressure={"P1": 0.0}, growth={"law": "stress"},
        accuracy={"cell_tolerance": cell_tolerance},
        loads={"left": [-pull, 0.0], "right": [pull, 0.0]},
        feedback={"cue": "stress", "rate": k},
    ).replace(kinematics=kinematics)  # fmt: skip
    directory = shared_dir(tmp_path_factory, f"pull_{cell_tolerance}_{kinematics}")
    rows, model = _run_rows(scene, directory / "run")
    cue = fibres_cue(model._cue)
    A = COMM.allreduce(float(cue.anisotropy.min()), op=MPI.MIN)
    # sigma_22 and sigma_12 are the solver's error relative to sigma_11: the LU's round-off
    # (ROUND_OFF; measured 6e-12) or Newton's residual 1e-10 relative to the load times the
    # macro stiffness's conditioning (measured 3e-9; 1e-7 allowed)
    solver = ROUND_OFF if kinematics == "linear" else 1e-7
    assert A == pytest.approx(1.0, abs=solver)
    assert COMM.allreduce(float(np.abs(cue.angle).max()), op=MPI.MAX) <= np.degrees(solver)
    if RANK0:
        t = np.array([row["t"] for row in rows])
        expected = np.degrees(np.arctan(np.tan(np.radians(60.0)) * np.exp(-k * A * t)))
        found = np.array([row["fibre_angle_mean"] for row in rows])
        print(f"director {found.tolist()} against {expected.tolist()}")
        assert np.abs(found - expected).max() <= max(1e-8, np.degrees(solver))
        assert found[-1] < 25.0  # it did turn (21.1 degrees at t = 3)
        assert all(row["fibre_order"] == pytest.approx(1.0, abs=1e-12) for row in rows)


@pytest.mark.mpi
def test_an_isotropic_cue_leaves_the_director_unchanged(tmp_path_factory):
    """Turgor alone in a homogeneous tissue: sigma_hom = (1 - phi_w) P1 I (section 4) is
    isotropic, A = 0 up to round-off (~1e-13), so the director (30 degrees) does not turn: less
    than k A dt / 2 radians per step, 1e-9 degrees here."""
    scene = _scene(
        {"fibre_stiffness": 5.0, "fibre_angle": 30.0},
        growth={"law": "stress"}, feedback={"cue": "stress", "rate": 2.0},
    )  # fmt: skip
    directory = shared_dir(tmp_path_factory, "isotropic_cue")
    rows, model = _run_rows(scene, directory / "run")
    assert np.abs(model.director.angle - 30.0).max() <= 1e-9
    if RANK0:
        assert all(abs(row["fibre_angle_mean"] - 30.0) <= 1e-9 for row in rows)


# --- output field, summary columns --------------------------------------------------------------


@pytest.mark.mpi
def test_fibre_direction_is_the_director_per_fine_cell():
    """fibre_direction holds m = (cos a, sin a) of the scene's angle field at each fine cell's
    midpoint (a linear field: the cells see different angles), a reduced to (-90, 90] (an axis:
    the written vector never points to x1 < 0)."""
    walls = {"fibre_stiffness": 2.0, "fibre_angle": {"from": -60.0, "to": 120.0}}
    model = macro_model(_scene(walls, accuracy={"cell_tolerance": 1e-3}), COMM)
    model.step(model.initial_growth())
    problem = model.problem
    m = problem.cell_values(model.director.function)
    x1 = problem.midpoints[: problem.n_cells, 0]
    a = np.radians(reduce_angle(-60.0 + 180.0 * x1 / problem.bounding_box[0]))
    low = COMM.allreduce(float(x1.min()), op=MPI.MIN)
    high = COMM.allreduce(float(x1.max()), op=MPI.MAX)
    assert high - low > 0.9 * problem.bounding_box[0]  # angles on both sides of 90 degrees
    assert np.allclose(m, np.column_stack([np.cos(a), np.sin(a)]), rtol=0, atol=1e-12)


@pytest.mark.mpi
def test_fibre_columns_and_field_only_for_fibred_scenes():
    assert "fibre_order" not in summary_columns(_scene())
    assert summary_columns(_scene(FIBRES))[-2:] == ["fibre_order", "fibre_angle_mean"]
    with pytest.raises(SceneError, match=r"^output\.fields: fibre_direction is the fibre"):
        _scene(output={"fields": ["fibre_direction"]})


# --- resume and mpirun ----------------------------------------------------------------------------

RESUMED = """\
[tissue]
h = 0.5
H = 2.0
[material]
E = {from = 0.5, to = 2.0}
[pressure]
P1 = 0.001
[growth]
law = "strain"
[time]
t_max = 3
dt = 1
[accuracy]
cell_resolution = 1
[walls]
fibre_stiffness = {from = 1.0, to = 5.0, along = "x2"}
fibre_angle = {from = -45.0, to = 90.0}
[output]
fields = ["u", "fibre_direction"]
precision = "float64"
"""


def _rows(path: Path) -> list[dict[str, float]]:
    with open(path) as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


NOT_COMPARED = ("n_cell_solves", "residual")  # the cache restarts empty; round-off


FEEDBACK = '[feedback]\ncue = "strain"\nrate = 2.0\n'
"""A strain cue in the E-gradient scene: each cell's director turns its own way, continuously."""


def test_resume_equals_an_uninterrupted_fibred_run(tmp_path_factory):
    """Stopped after step 1 and resumed, a fibred run whose directors turn (a strain cue) equals
    the uninterrupted run: its summary rows (but NOT_COMPARED) to 1e-10 relative, as in
    test_interruptions.py, the same arithmetic from the same saved float64 state, which holds
    the turned director (a surrogate answer depends only on exact lattice solves); under mpirun
    each model's mesh may be partitioned differently, so the LU's round-off (~1e-14) remains."""
    directory = shared_dir(tmp_path_factory, "fibre_resume")
    scene = parse_scene(tomllib.loads(RESUMED + FEEDBACK))
    straight, stopped = directory / "straight", directory / "stopped"
    angles = stopped_and_straight_runs(macro_model, scene, directory)
    # serial: the same arithmetic, exactly; mpirun: the LU's round-off in the cue, divided by the
    # cue's anisotropy in its angle a_Q (nearly isotropic strains), measured 2.3e-8 degrees
    margin = 0.0 if COMM.size == 1 else 1e-7
    assert np.abs(angles[0] - angles[1]).max() <= margin
    if RANK0:
        a, b = _rows(straight / "summary.csv"), _rows(stopped / "summary.csv")
        assert len(a) == len(b) == 4
        for x, y in zip(a, b, strict=True):
            for column, value in x.items():
                if not column.startswith("seconds") and column not in NOT_COMPARED:
                    assert y[column] == pytest.approx(value, rel=1e-10, abs=1e-300), column
        assert 0.0 < a[-1]["fibre_order"] < 1.0  # the director field varies
        assert abs(a[-1]["fibre_angle_mean"] - a[0]["fibre_angle_mean"]) > 1e-3  # it turned


@pytest.mark.skip_in_parallel
@pytest.mark.parametrize(
    "cell_tolerance, feedback", [(0.0, ""), (1e-3, FEEDBACK)], ids=["exact", "feedback"]
)
def test_mpirun_reproduces_the_serial_fibred_run(tmp_path, cell_tolerance, feedback):
    """``mpirun -n 2 plantgrowth run`` against the serial run of a fibred scene (varying
    stiffness and angle), every summary column to 1e-8 (module docstring), the same cell
    solves."""
    text = RESUMED.replace("[accuracy]\n", f"[accuracy]\ncell_tolerance = {cell_tolerance}\n")
    text += feedback
    write(tmp_path / "scene.toml", text)
    outdirs = serial_and_mpirun_runs(tmp_path / "scene.toml")
    serial, parallel = (_rows(outdir / "summary.csv") for outdir in outdirs)
    assert len(serial) == len(parallel) == 4
    for a, b in zip(serial, parallel, strict=True):
        assert a["n_cell_solves"] == b["n_cell_solves"]
        for column in a:
            if not column.startswith("seconds"):
                assert b[column] == pytest.approx(a[column], rel=1e-8, abs=1e-14), column
