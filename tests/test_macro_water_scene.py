"""The macro model's water from a scene (docs/model.md, "Water fluxes"; docs/outputs.md):
``plantgrowth run`` of a TOML scene with ``[hydraulics]`` and ``model = "macro"``, its summary
columns (the micro model's names), its fields P, psi and water_flux, serial against
``mpirun -n 2``, and the hydraulic length of a tissue supplied on one edge (docs/model.md,
"Water fluxes", consequence 4).

Small scenes: the reference tissue with h = 0.35, H = 1, P2 cell meshes with one element across a
wall, the exact cell path (cell_tolerance = 0); each scene runs once per module, in process on
COMM_WORLD (``runs``).
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import h5py
import numpy as np
import pytest
from mpi4py import MPI
from test_macro_run import read_summary

from plantgrowth.cli import main
from plantgrowth.models.macro.domain import macro_domain
from plantgrowth.models.macro.hydraulics import cell_scale
from plantgrowth.models.macro.model import model_on
from plantgrowth.models.micro.water import water_columns
from plantgrowth.results.run_results import read_results
from plantgrowth.runner.timeloop import run_model, summary_columns
from plantgrowth.scene import load_scene, parse_scene
from plantgrowth.scene.toml_text import dict_to_toml
from plantgrowth.unitcell.hydraulic_coefficients import conductivity
from plantgrowth.unitcell.solver import CellSolver

pytestmark = pytest.mark.mpi  # scripts/README.md, "Tests": every test also runs on 2 ranks

BIN = Path(sys.executable).parent
PLANTGROWTH = str(BIN / "plantgrowth")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")

PI = 0.001  # the osmotic pressure, the reference turgor
BASE = {
    "model": "macro",
    "tissue": {"h": 0.35, "H": 1.0},
    "time": {"t_max": 3, "dt": 1},
    "accuracy": {"cell_resolution": 1, "cell_tolerance": 0.0},
    "output": {"precision": "float64", "fields": ["u", "G", "P", "psi", "water_flux"]},
    "growth": {"law": "stress"},
    "regions": {"near": {"expr": "x1 < 1"}, "far": {"expr": "x1 > 5.93"},
                "everything": {"expr": "x2 > -1"}},
}
SCENES = {
    # an edge and a region supplied, the region's potential lowered at t = 2 (a drought)
    "two_supplies": {"hydraulics": {
        "osmotic": PI, "conductivity": 50.0,
        "supply": [
            {"edge": "left", "conductance": 1000.0},
            {"region": "far", "conductance": 1.0,
             "potential": {"times": [0.0, 2.0], "values": [0.0, -5e-4]}},
        ],
    }},  # fmt: skip
    # supplied on the left edge only (a stiff supply: P(0) = Pi to 1e-3), run into the
    # quasi-steady state: the storage relaxes as exp(-t f phi_L / (1/M + b^2/E)), about
    # exp(-t / 2.1) for the reference cell, so e^-7 by t = 15
    "one_edge": {
        "time": {"t_max": 15, "dt": 1},
        "output": {"precision": "float64", "fields": ["P", "water_flux"], "every": 5},
        "hydraulics": {"osmotic": PI, "conductivity": 100.0,
                       "supply": [{"edge": "left", "conductance": 1e4}]},
    },  # fmt: skip
}
BALANCE = 1e-12
"""|water_balance_error| / water: backward Euler conserves the water held exactly (m is stored
exactly in DG1), so the error is the linear solve's round-off (measured 1e-15); the tolerance of
the micro model's column (docs/outputs.md)."""
HYDRAULIC_LENGTH = 0.05
"""|measured decay length / sqrt(kappa / (phi_L (1 - phi_w))) - 1|: the 1D quasi-steady law
neglects the storage left at t = 15 (e^-7), the tissue's growth by then (kappa and the lumen
fraction change by its 6% of area) and the 2D mechanics of growth that falls along x1; measured
0.99 (docs/model.md, "Water fluxes")."""


def read_fields(outdir: Path, step: int) -> dict[str, np.ndarray]:
    """Every field of one written step and the mesh's points, by name ("points", ...)."""
    with h5py.File(outdir / "fields.h5", "r") as f:
        out = {"points": f["Mesh/geometry"][...], "triangles": f["Mesh/topology"][...]}
    with h5py.File(outdir / "fields" / f"step_{step:06d}.h5", "r") as f:
        return out | {name: f[name][...] for name in f}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """name -> (scene path, output directory, summary rows), each scene run once on first use."""
    comm = MPI.COMM_WORLD
    root = Path(comm.bcast(str(tmp_path_factory.mktemp("water")) if comm.rank == 0 else None))
    done: dict[str, tuple[Path, Path, list[dict[str, float]]]] = {}

    def get(name: str):
        if name not in done:
            path, outdir = root / f"{name}.toml", root / name
            if comm.rank == 0:
                path.write_text(dict_to_toml(BASE | SCENES[name]))  # tables replaced whole
            comm.Barrier()
            assert main(["run", str(path), "-o", str(outdir)]) == 0
            comm.Barrier()  # rank 0 writes the last summary row after the last collective
            done[name] = (path, outdir, read_summary(outdir / "summary.csv"))
        return done[name]

    return get


def test_a_scene_without_hydraulics_has_no_water_columns():
    text = dict_to_toml({k: v for k, v in BASE.items() if k != "output"})
    scene = parse_scene(tomllib.loads(text))
    assert scene.hydraulics is None
    assert not set(summary_columns(scene)) & {"turgor_mean", "water", "water_balance_error"}


def test_a_water_model_builds_no_solver_of_u_alone():
    """With ``[hydraulics]`` the water step solves u and P together: the problem of u alone
    builds no forms, matrix or solver (issue 35's cost); with the turgor given it does."""
    world = MPI.COMM_WORLD
    base = {k: v for k, v in BASE.items() if k != "output"}
    for tables, built in ((SCENES["two_supplies"], False), ({"pressure": {"P1": PI}}, True)):
        scene = parse_scene(base | tables)
        model = model_on(macro_domain(scene, world), world)
        assert (model.problem.ksp is not None) == built
        assert (model.water is None) == built


def test_the_macro_summary_has_the_micro_models_water_columns(runs):
    path, _, rows = runs("two_supplies")
    columns = water_columns(load_scene(path).hydraulics)
    assert columns[-2:] == ["inflow.edge.left", "inflow.region.far"]
    assert all(set(columns) <= set(row) for row in rows)
    first = rows[0]  # the initial equilibrium: P = Pi + psi_0 everywhere
    for name in ("turgor_mean", "turgor_min", "turgor_max"):
        assert first[name] == pytest.approx(PI, rel=1e-12), name
    assert first["water_balance_error"] == 0.0 and first["inflow.edge.left"] == 0.0
    for row in rows:  # a region's turgor: P's mean over its triangles (exact for P1)
        assert row["everything.turgor_mean"] == pytest.approx(row["turgor_mean"], rel=1e-12)


def test_the_water_balance_closes_to_round_off(runs):
    _, _, rows = runs("two_supplies")
    for before, row in zip(rows, rows[1:], strict=False):
        gained = row["inflow.edge.left"] + row["inflow.region.far"]  # dt = 1
        assert abs(gained) > 1e-4  # the check weighs a real flow
        assert abs(row["water_balance_error"]) <= BALANCE * row["water"]
        assert row["water"] - before["water"] == pytest.approx(gained, rel=1e-10)
    # the region's potential falls at t = 2: its inflow drops there, then rises again as the
    # tissue's psi keeps falling (without the drop it rises at every step: measured 1.5e-3,
    # 0.66e-3, 1.07e-3)
    inflow = [row["inflow.region.far"] for row in rows]
    assert inflow[0] == 0.0 and inflow[2] < 0.5 * inflow[1] and inflow[3] > inflow[2]


def test_the_fields_P_and_psi_agree_with_the_summary(runs):
    _, outdir, rows = runs("two_supplies")
    for step, row in enumerate(rows):
        f = read_fields(outdir, step)
        P, psi = f["P"][:, 0], f["psi"][:, 0]
        assert psi == pytest.approx(P - PI, abs=1e-15)
        assert P.min() == pytest.approx(row["turgor_min"], rel=1e-12)
        assert P.max() == pytest.approx(row["turgor_max"], rel=1e-12)
        assert f["water_flux"].shape == (len(f["triangles"]), 3)


def tissue_width(points: np.ndarray) -> float:
    return float(points[:, 0].max() - points[:, 0].min())


def test_one_supplied_edge_decays_over_the_hydraulic_length(runs):
    """P(x1) = P(0) cosh((W - x1) / l) / cosh(W / l) for kappa P'' = phi_L (1 - phi_w) P (tau = 0,
    the right edge sealed): l = W / arccosh(P(0) / P(W)) from the mean P on the two edges at
    t = 15, against l_h = sqrt(kappa / (phi_L (1 - phi_w))), phi_L = 2 eta (1 - phi_w) / phi_w,
    kappa = cell_scale L kappa_unit(I) (docs/model.md, "Water fluxes")."""
    path, outdir, rows = runs("one_edge")
    scene = load_scene(path)
    cell = scene.cell.at(0.0, 0.0)
    phi_w = CellSolver(cell, scene.accuracy.cell_resolution, MPI.COMM_SELF).solve(
        np.eye(2), 1.0, 0.3
    ).phi_w
    phi_L = 2.0 * 1.0 * (1.0 - phi_w) / phi_w  # eta = 1
    kappa = cell_scale(scene.micro_nx) * 100.0 * conductivity(cell, np.eye(2))[0, 0]
    expected = math.sqrt(kappa / (phi_L * (1.0 - phi_w)))
    f = read_fields(outdir, len(rows) - 1)
    x1, P = f["points"][:, 0], f["P"][:, 0]
    W = tissue_width(f["points"])
    left, right = P[x1 < x1.min() + 1e-9].mean(), P[x1 > x1.max() - 1e-9].mean()
    measured = W / math.acosh(left / right)
    print(f"decay length {measured:.4f}, hydraulic length {expected:.4f}, "
          f"ratio {measured / expected:.4f}")  # fmt: skip
    assert measured / expected == pytest.approx(1.0, abs=HYDRAULIC_LENGTH)
    # the supply's own resistance: P(0) below Pi by the inflow over L_s times the edge's grown
    # length, between H = 3 and 1.2 H (its G22 stays below 0.008: less than 13% by t = 15)
    last = rows[-1]
    drop = last["inflow.edge.left"] / (1e4 * 3.0)
    print(f"P(0) below Pi by {PI - left:.3e}, inflow / (L_s H) = {drop:.3e}")
    assert drop / 1.2 < PI - left < drop
    # turgor and growth fall with the distance from the supply
    assert last["far.trG"] < 0.1 * last["near.trG"]
    assert last["far.turgor_mean"] < 0.1 * last["near.turgor_mean"]
    columns, at = np.unique(np.round(x1, 9), return_inverse=True)  # the mesh's node columns
    column_means = np.bincount(at, P) / np.bincount(at)
    assert len(columns) > 10 and np.all(np.diff(column_means) < 0.0)
    assert np.all(f["water_flux"][:, 0] > 0.0), "water runs away from the supplied edge"


@pytest.mark.skip_in_parallel
@pytest.mark.parametrize("name", ["two_supplies"])
def test_mpirun_reproduces_the_serial_summary(runs, name, tmp_path):
    """``mpirun -n 2 plantgrowth run`` against the serial run, every column but the timings, the
    solver's residual and the balance error (round-off, checked by its bound) to 1e-8 of the
    column's largest value over the run (a column zero by symmetry at t = 0 is round-off there):
    only the LU (MUMPS on 2 ranks) and the order of the reductions differ (~1e-14)."""
    mpirun = shutil.which("mpirun")
    if mpirun is None:
        pytest.skip("mpirun not found")
    path, _, serial = runs(name)
    outdir = tmp_path / "mpirun"
    command = [mpirun, "-n", "2", PLANTGROWTH, "run", str(path), "-o", str(outdir)]
    done = subprocess.run(command, capture_output=True, text=True, env=ENV, timeout=600)
    assert done.returncode == 0, done.stderr
    assert "on 2 rank(s)" in (outdir / "run.log").read_text()
    parallel = read_summary(outdir / "summary.csv")
    assert len(parallel) == len(serial)
    compared = [c for c in serial[0] if not c.startswith("seconds")
                and c not in ("water_balance_error", "residual")]  # fmt: skip
    scale = {c: max(abs(row[c]) for row in serial) for c in compared}
    worst = 0.0
    for a, b in zip(serial, parallel, strict=True):
        assert abs(b["water_balance_error"]) <= BALANCE * b["water"]
        for column in compared:
            assert abs(b[column] - a[column]) <= 1e-8 * scale[column], column
            if scale[column] > 0.0:
                worst = max(worst, abs(b[column] - a[column]) / scale[column])
    print(f"{name}: largest relative serial-vs-mpirun difference {worst:.2e}")


def test_render_and_the_field_table_read_P_and_psi_at_the_nodes(runs):
    """P and psi are node fields (P1): the table has a row per node with the written values, and
    render draws them (and the flux, a vector per triangle, as arrows)."""
    _, outdir, rows = runs("two_supplies")
    table = read_results(outdir).field_table("P")
    f = read_fields(outdir, len(rows) - 1)
    assert np.array_equal(table["node"], np.arange(len(f["points"])))
    assert np.array_equal(table["P"], f["P"][:, 0])
    for name in ("P", "psi", "water_flux"):  # collective: rank 0 draws
        picture = outdir.parent / f"two_supplies_{name}.png"  # not in the run (refused)
        assert main(["render", str(outdir), "--field", name, "-o", str(picture), "--force"]) == 0
        assert picture.stat().st_size > 0


def test_a_resumed_run_continues_the_water_and_its_balance(runs, mpi_tmp_path):
    """Two steps, then resume to three: the resumed step's water columns, the balance error
    against the restored water included, repeat the straight run's (bit for bit on one rank;
    under mpirun a new partition changes MUMPS's round-off: 1e-12 relative, the balance error
    by its bound)."""
    path, _, rows = runs("two_supplies")
    scene, world = load_scene(path), MPI.COMM_WORLD
    cut = mpi_tmp_path / "cut"
    if world.rank == 0:
        cut.mkdir()
    world.Barrier()
    run_model(model_on(macro_domain(scene, world), world), scene, cut, world, n_steps=2)
    resumed = run_model(model_on(macro_domain(scene, world), world), scene, cut, world,
                        resume=True)  # fmt: skip
    assert [r["step"] for r in resumed] == [3]
    a, b = rows[3], resumed[0]
    assert abs(b["water_balance_error"]) <= BALANCE * b["water"]
    for key in ("turgor_mean", "turgor_min", "water", "inflow.edge.left", "inflow.region.far"):
        if world.size == 1:
            assert b[key] == a[key], key
        else:
            assert b[key] == pytest.approx(a[key], rel=1e-12), key
    if world.size == 1:
        assert b["water_balance_error"] == a["water_balance_error"]


BOTH = {
    "model": "both",
    "micro": {"nx": 4, "resolution": 1},
    "time": {"t_max": 2, "dt": 1},
    "output": {"precision": "float64", "fields": ["u", "P"]},
    "hydraulics": {"osmotic": PI, "conductivity": 50.0,
                   "supply": [{"edge": "left", "conductance": 100.0}]},
}  # fmt: skip


@pytest.mark.parametrize("kinematics", ["linear", "finite"])
def test_both_models_solve_the_water_as_each_alone(mpi_tmp_path, kinematics):
    """``model = "both"`` with ``[hydraulics]``, either kinematics: its micro side is the micro
    model's run of the scene (rows equal to a ``model = "micro"`` run's: the same solves, bit for
    bit on one rank; on two, 1e-8 relative, the micro model's serial = mpirun bound: parallel
    MUMPS's round-off on the thin walls' system differs from run to run, measured 3e-11 in
    u1_max), and its macro side, on the cells' region with their size, solves the water too: P in
    its fields, the balance closed to BALANCE, and in both models the growing tissue draws water
    from the supplied edge while its turgor falls below Pi (growth takes water faster than the
    walls conduct it)."""
    world = MPI.COMM_WORLD
    paths = {m: mpi_tmp_path / f"{m}.toml" for m in ("both", "micro")}
    if world.rank == 0:
        path = paths["both"]
        both = BASE | BOTH | {"kinematics": kinematics}
        path.write_text(dict_to_toml(both))
        micro = {"model": "micro", "output": {"precision": "float64", "fields": ["u"]}}
        paths["micro"].write_text(dict_to_toml(both | micro))  # P: the macro model's
    world.Barrier()
    for model, path in paths.items():
        assert main(["run", str(path), "-o", str(mpi_tmp_path / model)]) == 0
    world.Barrier()
    alone = read_summary(mpi_tmp_path / "micro/summary.csv")
    sides = {m: read_summary(mpi_tmp_path / f"both/{m}/summary.csv") for m in ("micro", "macro")}
    for a, b in zip(sides["micro"], alone, strict=True):
        for key in ("turgor_mean", "turgor_min", "water", "inflow.edge.left", "u1_max"):
            assert a[key] == (b[key] if world.size == 1 else pytest.approx(b[key], rel=1e-8))
    for rows in sides.values():
        assert rows[0]["turgor_mean"] == pytest.approx(PI, rel=1e-12)
        for row in rows[1:]:
            assert row["inflow.edge.left"] > 0 and row["turgor_min"] < 0.99 * PI
            assert abs(row["water_balance_error"]) <= BALANCE * row["water"]
    fields = read_fields(mpi_tmp_path / "both/macro", 2)
    assert fields["P"][:, 0].min() == pytest.approx(sides["macro"][2]["turgor_min"], rel=1e-12)
