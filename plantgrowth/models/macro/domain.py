"""The macro model's domain: the fine mesh a run solves on, and the places where it evaluates the
scene's fields (docs/model.md sections 5, 7), built once and shared by the scene checks and the
model."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from dolfinx import mesh
from mpi4py import MPI

from plantgrowth.meshes.tissue import TissueLayout, build_outline_mesh
from plantgrowth.models.macro.boundary import Boundary, outline_boundary, shape_domain
from plantgrowth.models.macro.coarse import coarse_grid_for
from plantgrowth.models.macro.problem import mesh_bounding_box, rectangle_mesh
from plantgrowth.scene import Scene


@dataclass(frozen=True)
class MacroDomain:
    """A macro run's scene (spanning the domain's extent), fine mesh and boundary (None: the
    scene's rectangle)."""

    scene: Scene
    mesh: mesh.Mesh
    boundary: Boundary | None = None

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
    and its edges are those of the cells' outer walls (:func:`outline_boundary`)."""
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
