"""Micro against macro with water fluxes (docs/micro_vs_macro.md, "With water fluxes").

``plantgrowth compare`` of a small hydraulic scene: the reference cell, stress law, Pi = 0.001,
L = L_s = 100, supplied on its left edge only, Nx = 4 and 8, one P2 element across a micro
wall, the draft preset, t = 0 and t = 1 (one water step: the turgor has fallen by 10-25% away
from the supply). One compare per module (``comparison``), a few seconds.

Theory (docs/micro_vs_macro.md): the displacement errors are O(delta) (the cell corrector);
the turgor error is dominated by a boundary layer about one cell deep (the outer cells, whose
single walls bulge, and the cells on the supplied edge), whose share of the cells is O(delta),
so its L2 norm falls no faster than delta^0.5 while the layer dominates.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
import ufl
from cli_helpers import call, shared_dir
from dolfinx import fem
from mpi4py import MPI

from plantgrowth.base.errors import SceneError
from plantgrowth.cli import main
from plantgrowth.meshes.cell_walls import wall_network
from plantgrowth.meshes.tissue import TissueLayout
from plantgrowth.models.macro.domain import macro_domain
from plantgrowth.models.macro.hydraulics import cell_scale
from plantgrowth.models.micro.model import scene_cell
from plantgrowth.scene import parse_scene
from plantgrowth.scene.toml_text import dict_to_toml
from plantgrowth.studies.compare import COLUMNS, check_comparable

NXS = (4, 8)
SCENE = {
    "model": "micro", "growth": {"law": "stress"},
    "hydraulics": {"osmotic": 0.001, "conductivity": 100.0,
                   "supply": [{"edge": "left", "conductance": 100.0}]},
    "time": {"t_max": 1.0, "dt": 1.0}, "micro": {"resolution": 1},
    "accuracy": {"preset": "draft"},
}  # fmt: skip
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
    a difference the one-edge supply makes visible (the turgor then falls by 10-25% across the
    tissue: an err_P that stayed at round-off would not measure it)."""
    assert list(comparison[0]) == [c for c in COLUMNS if c in comparison[0]]
    for row in comparison:
        assert {"err_u1", "err_u2", "err_P", "err_P_tmax"} <= set(row)
        assert row["err_P"] <= ROUND_OFF
        assert 1e-3 < row["err_P_tmax"] < 1.0


def test_errors_fall_from_nx_4_to_8(comparison):
    """From Nx = 4 to 8 (delta halves): u1 and u2 at t = 0 and t = 1 by at least 2^-0.5 (half the
    corrector's first order; measured 0.37, 0.31, 0.38, 0.31), the turgor at t = 1 by at least
    2^-0.25 (half the boundary layer's delta^0.5; measured 0.755)."""
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


def test_finite_kinematics_with_water_is_a_named_error(tmp_path_factory, capsys):
    """The macro model solves water fluxes with linear kinematics only: compare refuses the
    finite scene by name before anything is written."""
    scene = parse_scene(SCENE | {"kinematics": "finite"})
    with pytest.raises(SceneError, match="kinematics = 'linear' only, not 'finite'"):
        check_comparable(scene)
    base = shared_dir(tmp_path_factory, "compare_finite_water")
    path = write_scene(base, "finite", SCENE | {"kinematics": "finite"})
    code, _, err = call(["compare", path, "--nx", "4", "-o", base / "out"], capsys)
    assert code == 2
    if MPI.COMM_WORLD.rank == 0:
        assert "hydraulics: plantgrowth compare runs the macro model" in err
    assert not (base / "out").exists()
