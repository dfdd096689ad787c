"""The micro model's tissue of a scene (docs/real_tissues.md, the micro model on cells): the
cells of ``[tissue] cells`` when given, else the honeycomb of ``micro.nx`` Nx cells per row.

Wall thickness: a generated tissue's (and the honeycomb's) is ``cell.w`` scaled like its cells,
``w delta_s`` with ``delta_s = 4 / Nx``; an imported tissue's is ``cell.w`` in the scene's length
unit, the unit of its cells' coordinates. A generated tissue's cut cells are its bottom row (seeds
on x2 = 0); another cell with a side on x2 = 0 meets its own mirror image there. An imported
tissue cannot tell them apart: every cell with a side on x2 = 0 is taken as cut."""

from __future__ import annotations

from typing import TYPE_CHECKING

from plantgrowth.base.errors import SceneError
from plantgrowth.meshes.cell_tissue import CellTissue
from plantgrowth.meshes.geometry_error import GeometryError
from plantgrowth.meshes.tissue import TissueLayout
from plantgrowth.scene.cells_spec import GeneratedCells
from plantgrowth.scene.tissue_cells import cell_polygons, cells_at_nx, cut_cells

if TYPE_CHECKING:
    from plantgrowth.scene.schema import Scene


def micro_tissue(scene: Scene, nx: int | None = None) -> CellTissue:
    """The scene's cells with their wall thickness (module docstring); ``nx`` (a command's own
    ``--nx``): a generated tissue regenerated at nx cells per row (:func:`cells_at_nx`), no
    cells: the honeycomb of nx (default ``micro.nx``)."""
    if nx is not None:
        scene = cells_at_nx(scene, nx)
    cells = cell_polygons(scene)
    if cells is None:
        return CellTissue.from_layout(
            TissueLayout(scene.cell.at(0.0, 0.0), scene.micro_nx if nx is None else nx)
        )
    if not scene.cell.w.is_constant:
        raise SceneError("cell.w is a field, but a tissue given as cells has one wall thickness")
    w = float(scene.cell.w(0.0, 0.0))
    spec = scene.tissue.cells
    try:
        scale = 4.0 / spec.nx if isinstance(spec, GeneratedCells) else 1.0
        return CellTissue.from_cells(cells, w * scale, cut_cells(scene, cells))
    except GeometryError as e:
        raise SceneError(f"tissue.cells: {e}") from None
