"""Where cells come from (issue 34): the generated tissue ``[tissue] cells = {voronoi = N, seed =
S, regularity = r}`` (meshes/voronoi_tissue.py), the scene key and its named errors, and
``plantgrowth.scene.tissue_cells.cell_polygons``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI

from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.meshes.tissue import TissueLayout
from plantgrowth.meshes.voronoi_tissue import SHORT_SIDE, voronoi_tissue
from plantgrowth.scene import SceneError, load_scene, parse_scene
from plantgrowth.scene.tissue_cells import cell_polygons

ROUND_OFF = 1e-12
"""Vertex agreement relative to the cell size: qhull's circumcentres and the metric's scaling
are a few ulps each (measured 9e-16 absolute on cells of size ~1)."""
CELLS = [HoneycombCell(), HoneycombCell(l1=1.5, l2=0.8, theta_deg=40.0, w=0.05)]
BASE = {"model": "micro", "growth": {"law": "none"}}


def same_loop(a: np.ndarray, b: np.ndarray) -> float:
    """Largest vertex distance of two loops with the same cyclic order (any start), inf if
    their vertex counts differ."""
    if len(a) != len(b):
        return np.inf
    start = int(np.argmin(np.linalg.norm(a - b[0], axis=1)))
    return float(np.abs(np.roll(a, -start, axis=0) - b).max())


@pytest.mark.parametrize("cell", CELLS, ids=["regular", "l1_1.5_theta_40"])
@pytest.mark.parametrize("nx", [2, 4, 8])
def test_regularity_zero_is_todays_honeycomb(cell, nx):
    tissue = voronoi_tissue(cell, nx * nx // 2, seed=7, r=0.0)
    layout = TissueLayout(cell, nx)
    assert tissue.n_cells == layout.n_cells
    scale = layout.delta_s * max(cell.l1, cell.l2)
    for i in range(layout.n_cells):
        assert same_loop(tissue.polygon(i), layout.hexagon(i)) < ROUND_OFF * scale, i
    # shared walls are shared vertices: every interior cell of the honeycomb has six neighbours
    counts = tissue.neighbour_counts.reshape(nx // 2, nx)
    assert (counts[1:-1, 1:-1] == 6).all()


@pytest.mark.parametrize("r", [0.25, 0.5, 1.0])
def test_irregular_tissue_is_seeded_valid_and_on_the_half_plane(r):
    cell = CELLS[0]
    a, b = voronoi_tissue(cell, 72, 3, r), voronoi_tissue(cell, 72, 3, r)
    assert np.array_equal(a.vertices, b.vertices)
    assert all(np.array_equal(p, q) for p, q in zip(a.cells, b.cells, strict=True))
    other = voronoi_tissue(cell, 72, 4, r)
    assert other.vertices.shape != a.vertices.shape or not np.allclose(other.vertices, a.vertices)
    a.check()
    assert a.vertices[:, 1].min() >= 0.0 and a.vertices[:, 0].min() == 0.0  # x1 from 0 too
    # the bottom row stays cut by the symmetry plane: each has a side on x2 = 0
    for i in range(12):
        assert np.count_nonzero(a.polygon(i)[:, 1] == 0.0) == 2, i
    # the cells tile the honeycomb's region up to its ragged outer boundary: the total area is
    # within the outer ring of cells' area of the regular tissue's
    regular = voronoi_tissue(cell, 72, 3, 0.0)
    outer = regular.neighbour_counts < 6
    assert abs(a.areas.sum() - regular.areas.sum()) < regular.areas[outer].sum()


def test_every_vertex_is_on_the_half_plane():
    """Seeds reflected near x2 = 0 give cells with a side on it too: exactly on it, never
    below (before every cell was cut, 5 vertices of 40 tissues lay at x2 ~ -1e-17)."""
    for seed in range(10):
        tissue = voronoi_tissue(CELLS[0], 72, seed, 1.0)
        x2 = tissue.vertices[:, 1]
        assert x2.min() == 0.0 and not ((x2 > 0.0) & (x2 < 1e-9)).any()


def test_irregularity_grows_with_r():
    tissues = [voronoi_tissue(CELLS[0], 128, 1, r) for r in (0, 0.25, 0.5, 1)]
    # the whole cells (not the bottom row, cut in half by the symmetry plane)
    spread = [np.std(t.areas[16:]) for t in tissues]
    assert spread[0] < 1e-12 * max(spread)
    assert spread[1] < spread[2] < spread[3]
    # neighbour numbers of the cells all of whose sides are walls: 6 at r = 0, varied at r = 1
    # (standard deviation 1.03 measured on 512 cells, a Poisson-Voronoi tissue's is 1.33)
    inner = [t.neighbour_counts[_inner(t)] for t in tissues]
    assert (inner[0] == 6).all() and np.std(inner[3]) > 0.5
    # no side shorter than SHORT_SIDE of the honeycomb's shortest (the bottom row's l1/2)
    for t in tissues:
        sides = np.array(list(t.sides()))
        lengths = np.linalg.norm(t.vertices[sides[:, 0]] - t.vertices[sides[:, 1]], axis=1)
        assert lengths.min() >= SHORT_SIDE * 0.5 * (4.0 / 16)


def _inner(tissue) -> np.ndarray:
    """The cells with no outer side."""
    outer = {c for cells in tissue.sides().values() if len(cells) == 1 for c in cells}
    return np.array([i for i in range(tissue.n_cells) if i not in outer])


def test_scene_key_parses_round_trips_and_builds():
    scene = parse_scene(BASE | {"tissue": {"cells": {"voronoi": 32, "seed": 2, "regularity": 0.5}}})
    assert scene.micro_nx == 8
    data = scene.to_dict()
    assert data["tissue"]["cells"] == {"voronoi": 32, "seed": 2, "regularity": 0.5}
    assert "width" not in data["tissue"]
    again = parse_scene(data)
    assert again.tissue == scene.tissue and again.micro_nx == 8
    cells = cell_polygons(again)
    assert cells.n_cells == 32
    direct = voronoi_tissue(scene.cell.at(0.0, 0.0), 32, 2, 0.5)
    assert np.array_equal(cells.vertices, direct.vertices)
    assert cell_polygons(parse_scene(BASE)) is None
    assert parse_scene(BASE | {"tissue": {"cells": {"voronoi": 8}}, "micro": {"nx": 4}}).micro_nx


BAD = [
    ({"cells": {"voronoi": 33}}, {}, "tissue.cells.voronoi = 33 is invalid"),
    ({"cells": {"voronoi": 2.5}}, {}, "tissue.cells.voronoi = 2.5 is invalid"),
    ({"cells": {"voronoi": True}}, {}, "tissue.cells.voronoi = True is invalid"),
    ({"cells": {"voronoi": 2 * 258**2}}, {}, "tissue.cells.voronoi = 133128 is invalid"),
    ({"cells": {"seed": 1}}, {}, "tissue.cells.voronoi is required"),
    ({"cells": {"voronoi": 8, "regularity": 1.5}}, {}, r"tissue.cells.regularity = 1.5 .*\[0, 1\]"),
    ({"cells": {"voronoi": 8, "regularity": -0.1}}, {}, "tissue.cells.regularity = -0.1"),
    ({"cells": {"voronoi": 8, "seed": 1.5}}, {}, "tissue.cells.seed: expected an integer"),
    ({"cells": {"voronoi": 8, "seed": -1}}, {}, "tissue.cells.seed = -1 is out of range"),
    ({"cells": {"voronoi": 8, "irregularity": 1}}, {}, "unknown key 'tissue.cells.irregularity'"),
    ({"cells": "missing.tif", "pixel_size": 1.0}, {}, "tissue.cells = .*missing.tif.*not found"),
    ({"cells": "cells.txt"}, {}, "tissue.cells = .*: not a label image"),
    ({"cells": 3}, {}, "tissue.cells: expected a table"),
    ({"cells": {"voronoi": 8}, "width": 3.0}, {}, "tissue.width: not with tissue.cells"),
    ({"cells": {"voronoi": 8}, "height": 3.0}, {}, "tissue.height: not with tissue.cells"),
    ({"cells": {"voronoi": 8}, "outline": [[0, 0], [1, 0], [1, 1]]}, {}, "tissue.outline: not"),
    ({"cells": {"voronoi": 8}, "mesh": "t.msh"}, {}, "tissue.mesh: not with tissue.cells"),
    ({"cells": {"voronoi": 8}}, {"nx": 8}, "micro.nx = 8 is not the generated tissue's.*Nx = 4"),
    ({"cells": {"voronoi": 8}, "pixel_size": 1.0}, {}, "tissue.pixel_size: only with an imported"),
    ({"pixel_size": 1.0}, {}, "tissue.pixel_size: only with an imported"),
]


@pytest.mark.parametrize("tissue, micro, message", BAD, ids=[m[:40] for *_, m in BAD])
def test_bad_cells_key_is_named(tissue, micro, message, tmp_path):
    with pytest.raises(SceneError, match=message):
        parse_scene(BASE | {"tissue": tissue, "micro": micro}, directory=tmp_path)


def test_imported_cells_need_a_pixel_size_and_no_micro_nx(tmp_path):
    (tmp_path / "cells.png").write_bytes(b"")
    with pytest.raises(SceneError, match="tissue.pixel_size is required with a label image"):
        parse_scene(BASE | {"tissue": {"cells": "cells.png"}}, directory=tmp_path)
    with pytest.raises(SceneError, match="micro.nx: not with an imported tissue.cells"):
        parse_scene(
            BASE | {"tissue": {"cells": "cells.png", "pixel_size": 0.1}, "micro": {"nx": 4}},
            directory=tmp_path,
        )


def test_generated_tissue_needs_a_constant_cell():
    scene = parse_scene(BASE | {"model": "macro", "tissue": {"cells": {"voronoi": 8}},
                                "cell": {"l1": {"from": 1.0, "to": 1.2}}})  # fmt: skip
    with pytest.raises(SceneError, match="cell.l1 is a field, but tissue.cells.voronoi"):
        cell_polygons(scene)


@pytest.mark.mpi
def test_every_rank_generates_and_imports_the_same_cells():
    """Each rank builds the cells itself (generated, or traced from the shipped image)."""
    comm = MPI.COMM_WORLD
    example = Path(__file__).resolve().parents[1] / "scenes" / "real_tissues" / "synthetic.toml"
    for tissue in (voronoi_tissue(CELLS[1], 32, 11, 0.7), cell_polygons(load_scene(example))):
        for vertices in comm.allgather(tissue.vertices):
            assert np.array_equal(vertices, tissue.vertices)
        for loops in comm.allgather([c.tolist() for c in tissue.cells]):
            assert loops == [c.tolist() for c in tissue.cells]
