"""The macro model's domain: the fine mesh a run solves on, and the places where it evaluates the
scene's fields (docs/model.md sections 5, 7), built once and shared by the scene checks and the
model."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from dolfinx import mesh
from mpi4py import MPI

from plantgrowth.base.errors import SceneError
from plantgrowth.meshes.cell_outline import (
    CellShapeField,
    build_cells_outline_mesh,
    tissue_outline,
)
from plantgrowth.meshes.cell_polygons import CellPolygons
from plantgrowth.meshes.cell_shapes import cell_shapes
from plantgrowth.meshes.tissue import TissueLayout, build_outline_mesh
from plantgrowth.models.macro.boundary import (
    Boundary,
    cells_boundary,
    outline_boundary,
    shape_domain,
)
from plantgrowth.models.macro.coarse import coarse_grid_for
from plantgrowth.models.macro.problem import mesh_bounding_box, rectangle_mesh
from plantgrowth.scene import Scene
from plantgrowth.scene.cells_spec import ImportedCells
from plantgrowth.scene.fields import Field
from plantgrowth.scene.tissue_cells import cell_polygons, cells_at_nx, cut_cells


@dataclass(frozen=True)
class MacroDomain:
    """A macro run's scene (spanning the domain's extent), fine mesh and boundary (None: the
    scene's rectangle), and for a tissue given as cells each cell's shape (None: the unit
    cell's everywhere)."""

    scene: Scene
    mesh: mesh.Mesh
    boundary: Boundary | None = None
    cell_shape: CellShapeField | None = None

    def places(self) -> tuple[np.ndarray, np.ndarray]:
        """Collective: the coarse nodes whose cell problems the run solves (replicated; a
        non-rectangular tissue leaves some out: :func:`coarse.active_nodes`) and this rank's
        owned fine-cell midpoints, both (n, 2)."""
        msh = self.mesh
        owned = np.arange(msh.topology.index_map(2).size_local, dtype=np.int32)
        midpoints = mesh.compute_midpoints(msh, 2, owned)[:, :2]
        H = self.scene.tissue.H
        grid, _, active = coarse_grid_for(*mesh_bounding_box(msh), H, midpoints, msh.comm)
        return grid.nodes[active], midpoints


def macro_domain(scene: Scene, comm: MPI.Comm, nx: int | None = None) -> MacroDomain:
    """The macro model's domain: the scene's rectangle, outline or mesh file, or, next to a
    micro tissue of ``nx`` cells per row (``model = "both"``: the scene's micro.nx), the region
    its cells cover, with the scene's fields spanning that region's extent
    (docs/model.md section 7) and its ``micro.nx`` set to ``nx``: with water fluxes the macro
    model's cells are those cells (``cell_scale = 4 / nx``, docs/model.md "The cells' size"),
    and its edges are those of the cells' outer walls (:func:`outline_boundary`). A scene with
    ``tissue.cells`` runs on those cells (:func:`cells_domain`), alone or beside the micro
    model on the same cells; with ``nx``, a generated tissue is regenerated at nx cells per row
    (:func:`plantgrowth.scene.tissue_cells.cells_at_nx`), as the micro side is."""
    if nx is not None:
        scene = cells_at_nx(scene, nx)
    cells = cell_polygons(scene)
    if cells is not None:
        return cells_domain(scene, cells, comm)
    if nx is None and scene.model != "both":
        if scene.tissue.shape is not None:
            return MacroDomain(scene, *shape_domain(scene, comm))
        return MacroDomain(scene, rectangle_mesh(scene, comm))
    layout = TissueLayout(scene.cell.at(0.0, 0.0), scene.micro_nx if nx is None else nx)
    msh = build_outline_mesh(layout, scene.tissue.h, comm)[0]
    tissue_scene = scene.over_extent(*layout.bounding_box)
    return MacroDomain(
        dataclasses.replace(tissue_scene, micro_nx=layout.nx), msh, outline_boundary(msh, layout)
    )


def cells_domain(scene: Scene, cells: CellPolygons, comm: MPI.Comm) -> MacroDomain:
    """The macro model's domain of a tissue given as cells (docs/model.md "The macro model from
    cells"): the region the cells cover, meshed conforming to their sides with edges about
    ``tissue.h``, the scene's fields spanning its extent, and each cell's shape Fg0 against the
    scene's unit cell scaled to the cells' mean area (:func:`meshes.cell_shapes.cell_shapes`;
    the cells cut by the symmetry plane are the micro model's, :func:`cut_cells`).
    The cell geometry must be constant (it is the hexagon the shapes are measured against);
    an imported tissue's ``cell.w``, in the scene's length unit, becomes ``w / delta`` in the
    unit cell (:func:`unit_cell_walls`)."""
    varying = [key for key in ("l1", "l2", "theta", "w")
               if not getattr(scene.cell, key).is_constant]  # fmt: skip
    if varying:
        raise SceneError(
            f"cell.{varying[0]} is a field, but a tissue given as cells needs a constant cell "
            "geometry (each cell's shape is measured against that hexagon)"
        )
    cells.check()
    tissue_outline(cells)  # one connected tissue, else a named error
    shapes = cell_shapes(cells, scene.cell.at(0.0, 0.0), cut=cut_cells(scene, cells))
    if isinstance(scene.tissue.cells, ImportedCells):
        scene = unit_cell_walls(scene, shapes.delta)
    msh = build_cells_outline_mesh(cells, scene.tissue.h, comm)[0]
    width, height = (float(x) for x in cells.vertices.max(axis=0))
    boundary = cells_boundary(msh, cells)
    return MacroDomain(
        scene.over_extent(width, height), msh, boundary, CellShapeField(cells, shapes)
    )


def unit_cell_walls(scene: Scene, delta: float) -> Scene:
    """An imported tissue's scene with ``cell.w`` made relative to the unit cell: ``w / delta``,
    so that the unit cell scaled by the cells' mean size delta has the walls ``w`` thick in the
    scene's length unit, as the micro model's (docs/real_tissues.md)."""
    w = float(scene.cell.w(0.0, 0.0)) / delta
    try:
        cell = dataclasses.replace(
            scene.cell, w=Field(w, w, scene.tissue.width, scene.tissue.height)
        )
    except SceneError as e:
        raise SceneError(
            f"tissue.cells: cell.w over the cells' mean size delta = {delta:.4g} is the unit "
            f"cell's wall thickness: {e}"
        ) from None
    return dataclasses.replace(scene, cell=cell)
