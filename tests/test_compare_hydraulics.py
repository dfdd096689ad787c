"""Micro against macro with water fluxes (docs/micro_vs_macro.md, "With water fluxes").

``plantgrowth compare`` of a small hydraulic scene: the reference cell, stress law, Pi = 0.001,
L = L_s = 100, supplied on its left edge only, Nx = 4 and 8, one P2 element across a micro
wall, the draft preset, t = 0 and t = 1 (one water step: the turgor is then 0.54-0.92 of Pi,
lowest far from the supply). One compare per module (``comparison``), a few seconds.

Theory and measurements (docs/micro_vs_macro.md): the displacement errors are O(delta) (the
cell corrector). The turgor error this early is the thin walls' storage error (its finding 2:
the micro turgor above the macro one in the whole tissue, not in a layer), which falls slower
than delta at these Nx: rate 0.40 from Nx = 4 to 8 here, 0.69 over Nx = 4..16 at t = 3 (and
1.31 by t = 10 with kappa held). The test asks a rate of at least 0.25, about 60% of the rate
measured here: that the error clearly falls, not an order the theory gives.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
import ufl
from cli_helpers import shared_dir
from dolfinx import fem
from mpi4py import MPI

from plantgrowth.cli import main
from plantgrowth.meshes.cell_walls import wall_network
from plantgrowth.meshes.tissue import TissueLayout
from plantgrowth.models.macro.domain import macro_domain
from plantgrowth.models.macro.hydraulics import cell_scale
from plantgrowth.models.micro.model import scene_cell
from plantgrowth.scene import parse_scene
from plantgrowth.scene.toml_text import dict_to_toml
from plantgrowth.studies.compare import COLUMNS, run_compare

NXS = (4, 8)
SCENE = {
    "model": "micro", "growth": {"law": "stress"},
    "hydraulics": {"osmotic": 0.001, "conductivity": 100.0,
                   "supply": [{"edge": "left", "conductance": 100.0}]},
    "time": {"t_max": 1.0, "dt": 1.0}, "micro": {"resolution": 1},
    "accuracy": {"preset": "draft"},
}  # fmt: skip
RANKS = 1e-8  # a distributed compare against a serial one: the LU (MUMPS on 2 ranks), the
# partitions and the reductions' order differ; the micro model's own serial-vs-mpirun bound
ROUND_OFF = 1e-12  # both models start at P = Pi + psi_0 = 0.001 exactly, a constant the macro
# P1 field interpolates at the cell centres to round-off (measured 6e-17 and 9e-17)


def write_scene(directory: Path, name: str, data: dict) -> Path:
    path = directory / f"{name}.toml"
    if MPI.COMM_WORLD.rank == 0:
        path.write_text(dict_to_toml(data))
    MPI.COMM_WORLD.Barrier()
    return path


@pytest.fixture(scope="module")
def comparison(tmp_path_factory) -> list[dict[str, float]]:
    """compare.csv's rows of ``plantgrowth compare SCENE --nx 4 8``."""
    base = shared_dir(tmp_path_factory, "compare_water")
    out = base / "out"
    scene = write_scene(base, "water", SCENE)
    assert main(["compare", str(scene), "--nx", *map(str, NXS), "-o", str(out), "-q"]) == 0
    MPI.COMM_WORLD.Barrier()  # rank 0 writes compare.csv
    with open(out / "compare.csv", newline="") as f:
        return [{k: float(v) for k, v in row.items() if v != ""} for row in csv.DictReader(f)]


def test_the_table_carries_turgor_beside_u(comparison):
    """err_P at t = 0 is round-off (both models start in equilibrium with psi_0) and at t = 1
    a difference the one-edge supply makes visible (the turgor is then 0.54-0.92 of Pi across
    the tissue: an err_P that stayed at round-off would not measure it; measured 0.41, 0.31)."""
    assert list(comparison[0]) == [c for c in COLUMNS if c in comparison[0]]
    for row in comparison:
        assert {"err_u1", "err_u2", "err_P", "err_P_tmax"} <= set(row)
        assert row["err_P"] <= ROUND_OFF
        assert 1e-3 < row["err_P_tmax"] < 1.0


def test_errors_fall_from_nx_4_to_8(comparison):
    """From Nx = 4 to 8 (delta halves): u1 and u2 at t = 0 and t = 1 by at least 2^-0.5 (half the
    corrector's first order; measured 0.37, 0.31, 0.38, 0.31), the turgor at t = 1 by at least
    2^-0.25 (the module docstring; measured 0.755)."""
    coarse, fine = comparison
    for key in ("err_u1", "err_u2", "err_u1_tmax", "err_u2_tmax"):
        assert fine[key] < 2**-0.5 * coarse[key], key
    assert fine["err_P_tmax"] < 2**-0.25 * coarse["err_P_tmax"]


@pytest.mark.mpi  # the edges are tagged on each rank's part of the outline mesh
@pytest.mark.parametrize("nx", NXS)
def test_the_macro_side_has_the_micro_tissues_cells_and_edges(nx):
    """The macro run at Nx has the micro tissue's cells (micro.nx = Nx: cell_scale 4 / Nx) and
    its supplied edges are the micro cells' outer walls (meshes/cell_walls.py), equal in length
    to round-off of the reference mid-lines (the outline mesh's facets lie on them); every
    boundary facet has an edge."""
    scene = parse_scene(SCENE)
    domain = macro_domain(scene, MPI.COMM_WORLD, nx)
    assert cell_scale(domain.scene.micro_nx) == 4.0 / nx
    network = wall_network(TissueLayout(scene_cell(scene), nx))
    boundary = domain.boundary
    ds = ufl.Measure("ds", domain=domain.mesh, subdomain_data=boundary.facets)
    one = fem.Constant(domain.mesh, 1.0)
    total = 0.0
    for edge, tag in boundary.edges.items():
        form = fem.form(one * ds(tag))
        length = MPI.COMM_WORLD.allreduce(fem.assemble_scalar(form), op=MPI.SUM)
        total += length
        if edge != "bottom":  # the symmetry plane: no micro outer walls
            on = network.outer_edge == edge
            assert length == pytest.approx(np.linalg.norm(network.outer[on], axis=1).sum(), 1e-12)
    perimeter = fem.form(one * ufl.ds(domain=domain.mesh))
    assert total == pytest.approx(MPI.COMM_WORLD.allreduce(fem.assemble_scalar(perimeter)), 1e-12)


@pytest.mark.mpi
def test_mpirun_reproduces_the_serial_turgor_error(tmp_path_factory):
    """Under mpirun: compare at Nx = 4 on all ranks (walls and macro mesh distributed, the macro
    P gathered, the cells' turgor broadcast) against the same compare on each rank alone: the
    turgor and growth-rate errors at t = 1 and the displacement errors at t = 0 to
    :data:`RANKS` relative (measured 5e-12, 3e-12, 3e-11, 3e-11). Not the displacement errors
    at t = 1: they moved by 1e-7 to 5e-7, and by 1e-7 between two 2-rank runs (the step's LU,
    MUMPS), while P and G agree to 1e-11. Serial: both are one run."""
    world = MPI.COMM_WORLD
    if world.size == 1:
        pytest.skip("a distributed compare against a serial one needs mpirun -n 2")
    base = shared_dir(tmp_path_factory, "compare_water_ranks")
    scene = parse_scene(SCENE)
    distributed = run_compare(scene, [4], base / "all", world)[0]
    alone = run_compare(scene, [4], base / f"rank{world.rank}", MPI.COMM_SELF)[0]
    for key in ("err_P_tmax", "err_G_tmax", "err_u1", "err_u2"):
        assert distributed[key] == pytest.approx(alone[key], rel=RANKS), key
