"""A scene's cells (issue 34): ``[tissue] cells`` generated or imported, as a checked
:class:`~plantgrowth.meshes.cell_polygons.CellPolygons` in the scene's length unit."""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from plantgrowth.base.errors import SceneError
from plantgrowth.meshes.cell_polygons import CellPolygons
from plantgrowth.meshes.geometry_error import GeometryError
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.meshes.voronoi_tissue import voronoi_tissue
from plantgrowth.scene.cells_spec import GeneratedCells, ImportedCells, imported_cells

if TYPE_CHECKING:
    from plantgrowth.scene.schema import Scene


@lru_cache(maxsize=8)
def _generated(spec: GeneratedCells, cell: HoneycombCell) -> CellPolygons:
    return voronoi_tissue(cell, spec.voronoi, spec.seed, spec.regularity)


def cell_polygons(scene: Scene) -> CellPolygons | None:
    """The scene's cells (None without ``tissue.cells``): a generated tissue of the scene's
    (constant) cell geometry, or an imported one; a SceneError names a bad geometry or file.
    The same cells give the same (cached) object: do not modify it."""
    spec = scene.tissue.cells
    if spec is None:
        return None
    if not isinstance(spec, GeneratedCells):
        return imported_cells(spec)
    for key in ("l1", "l2", "theta", "w"):
        if not getattr(scene.cell, key).is_constant:
            raise SceneError(
                f"cell.{key} is a field, but tissue.cells.voronoi generates its tissue from "
                "one honeycomb cell: give constant cell.l1, cell.l2, cell.theta and cell.w"
            )
    try:
        return _generated(spec, scene.cell.at(0.0, 0.0))
    except GeometryError as e:
        raise SceneError(str(e)) from None


def cut_cells(scene: Scene, cells: CellPolygons) -> np.ndarray | None:
    """(n,) bool: the cells the symmetry plane x2 = 0 cuts (each the half of a cell mirrored
    about it), the same for the micro and the macro model: a generated tissue's bottom row
    (labels < Nx: seeds on x2 = 0); another generated cell with a side on x2 = 0 meets its own
    mirror image there across a wall, a whole cell. None for an imported tissue, which cannot
    tell the two apart: every cell with a side on x2 = 0 is then taken as cut."""
    spec = scene.tissue.cells
    return cells.labels < spec.nx if isinstance(spec, GeneratedCells) else None


def cells_at_nx(scene: Scene, nx: int) -> Scene:
    """The scene at ``nx`` cells per row (a command's own ``--nx``, ``plantgrowth compare``): a
    generated tissue regenerated with ``Nx^2 / 2`` cells, its seed and regularity kept (the same
    r at every Nx; the seeds' draws differ with the count), and ``micro.nx = nx``; a scene
    without cells unchanged. An imported tissue has its own cells: SceneError."""
    spec = scene.tissue.cells
    if spec is None:
        return scene
    if isinstance(spec, ImportedCells):
        raise SceneError(
            f"--nx {nx}: tissue.cells = '{spec.path}' is an imported tissue with its own cells; "
            "a comparison at chosen Nx needs no cells or generated ones "
            "(tissue.cells = {voronoi = N, seed = S, regularity = r}); run model = \"both\" on it"
        )
    cells = replace(spec, voronoi=nx * nx // 2)
    return replace(scene, tissue=replace(scene.tissue, cells=cells), micro_nx=nx)
