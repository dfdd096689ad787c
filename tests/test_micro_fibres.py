"""Fibre-reinforced walls in the micro model (docs/fibres.md; docs/model.md, fibre-reinforced
walls): a director per cell, each half of a shared wall with its own cell's tensor, the walls
around the cell (or its own halves) as the feedback's cue, the director in the checkpoint and in
cells.csv.

Models are built in process on COMM_WORLD; per-cell values (G, the director) are replicated on
every rank, so the checks hold unchanged under mpirun. Small tissues (Nx <= 16), one P2 element
across a wall. ROUND_OFF: the micro LU's relative round-off on these <= 10^4 dofs (measured
~1e-11 in test_micro.py, whose ROUND_OFF this is).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
import ufl
from cli_helpers import (
    RANK0,
    call,
    serial_and_mpirun_runs,
    shared_dir,
    stopped_and_straight_runs,
    write,
)
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from plantgrowth.meshes.tissue import TissueLayout
from plantgrowth.models import fibres, growth
from plantgrowth.models.macro.model import macro_model
from plantgrowth.models.micro.around import WallsAround, around_map, neighbours, side_pairs
from plantgrowth.models.micro.director import nearest_sides, padded_outlines
from plantgrowth.models.micro.model import MicroModel, scene_cell
from plantgrowth.runner.timeloop import run_model
from plantgrowth.scene import parse_scene
from plantgrowth.scene.toml_text import dict_to_toml

COMM = MPI.COMM_WORLD
ROUND_OFF = 1e-8  # module docstring
FIBRES = {"fibre_stiffness": 5.0, "fibre_angle": 90.0}
ZERO = {"fibre_stiffness": {"expr": "0 * x1"}, "fibre_angle": 45.0}
"""Fibres of stiffness 0 given as an expression: the run takes the fibred code path."""


def _data(walls: dict | None = None, **tables) -> dict:
    data = {"model": "micro", "growth": {"law": "strain"}, "time": {"t_max": 3, "dt": 1}}
    data["micro"] = {"nx": 4, "resolution": 1}
    for name, entries in tables.items():
        data[name] = data.get(name, {}) | entries
    return data | ({"walls": walls} if walls else {})


def _steps(model: MicroModel, n: int) -> list[np.ndarray]:
    """G of n steps of length 1 (exp integrator), the director turned after each."""
    Fg, out = model.initial_growth(), []
    for _ in range(n):
        G = model.step(Fg).G
        model.end_step(1.0)
        out.append(G)
        Fg = growth.advance(Fg, G, 1.0, "exp")
    return out


# --- consequence (1): fibre_stiffness = 0 is the paper's micro model ----------------------------


@pytest.mark.parametrize("kinematics", ["linear", "finite"])
def test_zero_fibre_stiffness_reproduces_the_isotropic_micro_run(kinematics):
    """E_f = 0 through the fibred code path (director, tangents, C_w, a turning director) gives
    the isotropic run's G over two steps and its summary measures, to the LU's round-off."""
    common = {"kinematics": kinematics}
    feedback = {"feedback": {"cue": "stress", "rate": 1.0}}
    plain = MicroModel(parse_scene(_data() | common), COMM)
    fibred = MicroModel(parse_scene(_data(ZERO) | common | feedback), COMM)
    assert fibred.director is not None and plain.director is None
    G_plain, G_fibred = _steps(plain, 2), _steps(fibred, 2)
    scale = np.abs(G_plain[-1]).max()
    assert scale > 0.0
    for a, b in zip(G_plain, G_fibred, strict=True):
        assert np.abs(a - b).max() <= ROUND_OFF * scale
    Fg = plain.initial_growth()
    rows = plain.measures(Fg, G_plain[-1]), fibred.measures(Fg, G_fibred[-1])
    for key in ("area", "u1_max", "u2_max"):
        assert rows[1][key] == pytest.approx(rows[0][key], rel=ROUND_OFF)
    assert np.any(fibred.director.angle != 45.0)  # the director turned, to no effect


# --- homogeneous fibred tissue against the macro formula ----------------------------------------


@pytest.fixture(scope="module")
def macro_rate() -> np.ndarray:
    """The macro model's G at t = 0 of the same homogeneous fibred tissue (consequence (4),
    checked against the cell's own tensors in test_macro_fibres.py); cell_resolution 4 so that
    the cell problem's discretisation error (~1e-3) is below the micro boundary layer's."""
    data = _data(FIBRES, tissue={"h": 0.5, "H": 1.0})
    data |= {"model": "macro", "accuracy": {"cell_tolerance": 0.0, "cell_resolution": 4}}
    data.pop("micro")
    model = macro_model(parse_scene(data), COMM)
    return model.step(model.initial_growth()).G[0]


def test_homogeneous_fibred_tissue_grows_across_the_fibres_toward_the_macro_rate(macro_rate):
    """a = 90, E_f / E = 5, strain law: the micro tissue grows faster across the fibres (x1)
    than along them, and its mean rates approach the macro formula's like 1 / Nx, the cut and
    free boundary layers' share of the cells. Measured relative errors (g11, g22): Nx = 4:
    (5.1%, 29%), 8: (2.6%, 15%), 16: (1.3%, 7.5%): each halves; the margins ask at least
    1.6 per doubling and the measured g11 / g22 of at least 2.7 (macro: 3.35) to exceed 2."""
    errors = []
    for nx in (4, 8, 16):
        model = MicroModel(parse_scene(_data(FIBRES)), COMM, nx)
        Fg = model.initial_growth()
        row = model.measures(Fg, model.step(Fg).G)
        g = np.array([row["growth_rate_11"], row["growth_rate_22"]])
        assert g[0] > 2.0 * g[1] > 0.0
        errors.append(np.abs(g / np.diag(macro_rate) - 1.0))
        print(f"Nx = {nx}: micro {g}, macro {np.diag(macro_rate)}, errors {errors[-1]}")
    for coarse, fine in zip(errors, errors[1:], strict=False):
        assert np.all(fine * 1.6 <= coarse)
    assert np.all(errors[-1] < [0.02, 0.1])


# --- feedback ------------------------------------------------------------------------------------


def _walls_around(model: MicroModel) -> WallsAround:
    """The walls around each cell of a model's mesh, each triangle on the side of its cell's
    hexagon nearest to its midpoint (as MicroDirector assigns them)."""
    tissue, n_owned, cells = model.tissue, model.n_owned, model.cell_id
    hexagons, counts = padded_outlines(tissue)
    midpoints = dmesh.compute_midpoints(model.mesh, 2, np.arange(n_owned, dtype=np.int32))
    side = nearest_sides(hexagons[cells], counts[cells], midpoints[:, :2])
    Q0 = fem.FunctionSpace(model.mesh, ("DG", 0))
    areas = fem.petsc.assemble_vector(fem.form(ufl.TestFunction(Q0) * ufl.dx))
    return WallsAround(tissue, model.cell_id, side, model._owned_rows(areas.array, Q0), COMM)


CUE_ROUND_OFF = 1e-11
"""Relative round-off of a cell's averaged wall stress or strain (the director test below)."""


@pytest.mark.mpi
@pytest.mark.parametrize("walls", ["around", "own"])
@pytest.mark.parametrize("cue", ["stress", "strain"])
def test_each_director_turns_toward_its_cue(cue, walls):
    """With E_f = 0 the director does not act on the mechanics, so its cue is the isotropic
    run's: the wall stress or elastic strain of a run without fibres, averaged over the walls
    around each cell (``walls = "around"``, both halves of each shared wall) or over its own
    halves, a cut bottom cell without shear. Over three steps of dt = 1 each director follows
    the exact step ``tan(a_new - a_Q) = tan(a - a_Q) exp(-k A dt)`` to what the cue's round-off
    leaves of its angle, and never moves away from a_Q. A relative round-off eps of the averaged
    tensor turns its principal axis by up to eps / A radians (A its anisotropy): each cell's
    bound is ``degrees(CUE_ROUND_OFF / A)`` with CUE_ROUND_OFF = 1e-11, the averages' round-off
    from two solves of one system on different partitions (MUMPS on 2 ranks: its A reaches
    ~1e-3 here, so about 6e-7 degrees; measured 1.1e-9 degrees on 2 ranks, 1e-12 serial)."""
    rate = 2.0
    plain = MicroModel(parse_scene(_data()), COMM)
    feedback = {"cue": cue, "rate": rate} | ({"walls": walls} if walls == "own" else {})
    fibred = MicroModel(parse_scene(_data(ZERO, feedback=feedback)), COMM)
    form = plain._wall_stress_form if cue == "stress" else plain._wall_strain_form
    around = _walls_around(plain)
    Fg, expected = plain.initial_growth(), np.full(plain.layout.n_cells, 45.0)
    for _ in range(3):
        G = plain.step(Fg).G
        if walls == "own":
            means = plain._cell_means(form)
        else:
            means = around.means(plain._tensor_rows(form))
            means[plain.layout.cut_cells, 1:3] = 0.0
        q = fibres.cue(means.reshape(-1, 2, 2))
        fibred.step(Fg)
        fibred.end_step(1.0)
        before = expected
        expected = fibres.turn_director(before, q.angle, q.anisotropy, rate, 1.0)
        bound = np.degrees(CUE_ROUND_OFF / q.anisotropy)
        assert np.all(np.abs(fibres.reduce_angle(fibred.director.angle - expected)) <= bound)
        closer = np.abs(fibres.reduce_angle(expected - q.angle))
        assert np.all(closer <= np.abs(fibres.reduce_angle(before - q.angle)) + 1e-12)
        Fg = growth.advance(Fg, G, 1.0, "exp")
    assert np.abs(expected - 45.0).max() > 1.0  # the directors did turn


def test_the_walls_around_a_cell_are_its_halves_and_its_neighbours_opposite_halves():
    """Nx = 6 (three rows): cell 8 (row 1, column 2, rows shifted alternately by half a cell)
    has, across its sides A B, B C, C D, D E, E F, F A, the cells 15, 14, 7, 2, 3, 9 (worked out
    by hand from the centres of docs/model.md section 7); the relation is symmetric (side k + 3
    of the cell across); the cut bottom row has nothing below it. With per-side integrals
    ``I(c, k) = 100 c + k`` the sum around cell 8 is its own six sides plus the opposite sides of
    its six neighbours, 4815 + 1503 + 1404 + 705 + 200 + 301 + 902 = 9830 (exact integers)."""
    layout = TissueLayout(scene_cell(parse_scene(_data())), 6)
    across = neighbours(layout)
    assert across[8].tolist() == [15, 14, 7, 2, 3, 9]
    for cell, sides in enumerate(across):
        for k, other in enumerate(sides):
            assert other < 0 or across[other, (k + 3) % 6] == cell
    assert np.all(across[layout.cut_cells, 3:5] == -1)
    per_side = 100.0 * np.repeat(np.arange(layout.n_cells), 6) + np.tile(np.arange(6), 18)
    assert (around_map(*side_pairs(layout)) @ per_side)[8] == 9830.0


def test_a_turned_cell_under_a_stress_cue():
    """One cell's fibres turned by 10 degrees from its neighbours' (a = 90, E_f / E = 5, strain
    law, stress cue, k = 1, three steps of dt = 1). ``walls = "own"``: the cell's own halves of
    the shared walls carry more of their load along its director, so the cue turns past it and
    the cell turns further from its neighbours (docs/fibres.md). ``walls = "around"``: both
    halves of each wall, so the cell sees the wall loads around it.

    - A cell of the top edge (Nx = 4, cell 5): measured, the deviation from its neighbours
      (mean of the axis differences) goes 10 -> 8.22 degrees ("around") and 10 -> 13.16 ("own"):
      asked here, below 9.5 and above 11.5, half the measured change either way.
    - An interior cell (Nx = 6, cell 8, all six neighbours): measured 10 -> 10.30 ("around")
      and 10 -> 18.08 ("own"): the loop is still unstable with "around", 27 times slower. Asked
      here: "own" gains more than 4 degrees, and "around" changes by less than a tenth of it.

    Every change is 0.3 degrees or more against round-off of 1e-9 degrees (the cue's ~1e-11
    relative over its anisotropy ~1e-3), and under mpirun the same per-cell angles
    (tests/test_micro_fibres.py's mpirun checks), so the margins are the physics' alone."""
    deviation = {}
    for nx, cell in ((4, 5), (6, 8)):
        layout = TissueLayout(scene_cell(parse_scene(_data())), nx)
        x, y = layout.centres[cell]
        inside = f"((x1 - {x!r})**2 + (x2 - {y!r})**2 < 0.25)"  # radius 0.5: one cell's centre
        turned = {"fibre_stiffness": 5.0, "fibre_angle": {"expr": f"90 + 10 * {inside}"}}
        ring = neighbours(layout)[cell]
        ring = ring[ring >= 0]
        for walls in ("around", "own"):
            # "around" is the default: the scene leaves the key out
            feedback = {"cue": "stress", "rate": 1.0} | ({"walls": walls} if walls == "own" else {})
            data = _data(turned, feedback=feedback, micro={"nx": nx}, accuracy={"preset": "draft"})
            model = MicroModel(parse_scene(data), COMM)
            angle = model.director.angle
            assert fibres.reduce_angle(angle[cell] - 90.0) == 10.0  # (-90, 90]: -80
            assert np.all(np.delete(angle, cell) == 90.0)
            _steps(model, 3)
            a = model.director.angle
            deviation[nx, walls] = np.mean(fibres.reduce_angle(a[cell] - a[ring]))
    print(deviation)
    assert deviation[4, "around"] < 9.5 and deviation[4, "own"] > 11.5
    assert deviation[6, "own"] > 14.0
    assert abs(deviation[6, "around"] - 10.0) < 0.1 * (deviation[6, "own"] - 10.0)


# --- resume, cells.csv and mpirun -------------------------------------------------------------

RESUMED = _data(
    {"fibre_stiffness": {"from": 1.0, "to": 5.0, "along": "x2"},
     "fibre_angle": {"from": -45.0, "to": 80.0}},
    material={"E": {"from": 0.5, "to": 2.0}},
    feedback={"cue": "strain", "rate": 2.0},
    output={"precision": "float64"},
)  # fmt: skip
"""A fibred tissue of varying stiffness and angle whose directors turn (a strain cue)."""


NOT_COMPARED = ("residual", "newton_residual")
"""The solvers' residuals: round-off itself."""


def _rows(path: Path) -> list[dict[str, float]]:
    with open(path) as f:
        # compare.csv leaves the t_max columns empty with --first-step-only
        return [{k: float(v) if v else np.nan for k, v in row.items()} for row in csv.DictReader(f)]


def test_resume_equals_an_uninterrupted_fibred_micro_run(tmp_path_factory):
    """Stopped after step 1 and resumed, the run equals the uninterrupted one: the saved
    director and every summary column but the timings and residuals to 1e-10 relative
    (test_interruptions.py's margin: the same arithmetic from the same float64 state); under
    mpirun each model's mesh may be partitioned differently, so the LU's round-off remains
    (1e-8, as serial against mpirun, measured 1.0e-10 in u1_max); cells.csv has the director the
    step used, the scene's angle at the cell centres at step 0."""
    directory = shared_dir(tmp_path_factory, "micro_fibre_resume")
    scene = parse_scene(RESUMED)
    straight, stopped = directory / "straight", directory / "stopped"
    angles = stopped_and_straight_runs(MicroModel, scene, directory)
    margin = 1e-10 if COMM.size == 1 else 1e-8
    assert np.abs(angles[0] - angles[1]).max() <= margin * 90.0
    model = MicroModel(scene, COMM)  # collective: for the initial director below
    if not RANK0:
        return
    a, b = _rows(straight / "summary.csv"), _rows(stopped / "summary.csv")
    assert len(a) == len(b) == 4
    for x, y in zip(a, b, strict=True):
        for column, value in x.items():
            if not column.startswith("seconds") and column not in NOT_COMPARED:
                assert y[column] == pytest.approx(value, rel=margin, abs=1e-300), column
    assert abs(a[-1]["fibre_angle_mean"] - a[1]["fibre_angle_mean"]) > 1e-3  # it turned
    cells = _rows(straight / "cells.csv")
    first = [r for r in cells if r["step"] == 0]
    # the fields span the micro tissue (MicroModel.scene)
    initial = fibres.reduce_angle(model.scene.walls.fibre_angle(*model.layout.centres.T))
    assert np.abs(np.array([r["fibre_angle"] for r in first]) - initial).max() <= 1e-12
    last = np.array([r["fibre_angle"] for r in cells if r["step"] == 3])
    assert np.abs(last - initial).max() > 1e-3


@pytest.mark.mpi
def test_isotropic_micro_cells_csv_has_no_fibre_column(tmp_path_factory):
    directory = shared_dir(tmp_path_factory, "micro_plain_cells")
    if RANK0:
        (directory / "out").mkdir()
    COMM.barrier()
    scene = parse_scene(_data(time={"t_max": 1}))
    run_model(MicroModel(scene, COMM), scene, directory / "out", COMM)
    if RANK0:
        with open(directory / "out" / "cells.csv") as f:
            header = next(csv.reader(f))
        assert (
            "fibre_angle" not in header
            and "fibre_order" not in _rows(directory / "out" / "summary.csv")[0]
        )


@pytest.mark.skip_in_parallel
@pytest.mark.parametrize(
    "kinematics, cue", [("linear", "strain"), ("finite", "strain"), ("linear", "stress")]
)
def test_mpirun_reproduces_the_serial_fibred_micro_run(tmp_path, kinematics, cue):
    """``mpirun -n 2 plantgrowth run`` against the serial run: every summary and cells.csv
    column (the director among them, its cue averaged around each cell from per-side integrals
    gathered over the ranks) but the timings and the solvers' residuals (round-off itself) to
    1e-8 relative (only the LU and the order of the sums differ, as in test_micro.py)."""
    feedback = RESUMED["feedback"] | {"cue": cue}
    scene = RESUMED | {"kinematics": kinematics, "feedback": feedback}
    write(tmp_path / "scene.toml", dict_to_toml(scene))
    tables = [
        (_rows(outdir / "summary.csv"), _rows(outdir / "cells.csv"))
        for outdir in serial_and_mpirun_runs(tmp_path / "scene.toml")
    ]
    # cells.csv's growth_anisotropy, growth_direction and fibre_angle are differences of
    # nearly equal principal values: G's and the cue's round-off (~1e-11 relative) divided by
    # their anisotropy (>= 1e-3 here), so an absolute 1e-8 there
    for (serial, parallel), absolute in zip(zip(*tables, strict=True), (1e-14, 1e-8), strict=True):
        assert len(serial) == len(parallel) > 0
        for a, b in zip(serial, parallel, strict=True):
            for column in a:
                if not column.startswith("seconds") and column not in NOT_COMPARED:
                    assert b[column] == pytest.approx(a[column], rel=1e-8, abs=absolute), column


# --- plantgrowth compare --------------------------------------------------------------------------


def test_compare_of_a_fibred_tissue_converges(tmp_path_factory, capsys):
    """``plantgrowth compare --nx 4 8 --first-step-only`` of the homogeneous fibred tissue
    (a = 90, E_f / E = 5, strain law): the errors fall as in the isotropic comparison. Measured
    err_u1 1.40 -> 0.51, err_u2 5.38 -> 1.66 (fitted delta^1.46, delta^1.69; the same scene
    without fibres: 1.45, 1.70), err_G 0.148 -> 0.104; the margins ask a fitted order >= 1 for
    u1, u2 and a falling err_G and mean-rate gap."""
    directory = shared_dir(tmp_path_factory, "fibred_compare")
    data = _data(FIBRES, time={"t_max": 1})
    data.pop("model")
    data.pop("micro")
    write(directory / "fibres.toml", dict_to_toml(data))
    argv = ["compare", directory / "fibres.toml", "--nx", "4", "8", "--first-step-only", "-q"]
    code, _, err = call([*argv, "-o", directory / "out"], capsys)
    assert code == 0, err
    if not RANK0:
        return
    coarse, fine = _rows(directory / "out" / "compare.csv")
    for column in ("err_u1", "err_u2"):
        assert np.log2(coarse[column] / fine[column]) >= 1.0, column
    assert fine["err_G"] < coarse["err_G"]
    gap = [abs(r["rate_micro_t0"] / r["rate_macro_t0"] - 1.0) for r in (coarse, fine)]
    assert gap[1] < gap[0]
