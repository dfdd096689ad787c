"""Where the macro problem's boundary conditions act (docs/model.md section 4): the symmetry facets
on x2 = 0 (u2 = 0), the pinned vertex (u1 = 0, removes the x1 translation) and the edges by name
(loaded or held), as facet tags of the fine mesh; and the fine mesh of an outline or mesh-file
tissue.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from dolfinx import mesh
from mpi4py import MPI

from plantgrowth.meshes import polygon
from plantgrowth.meshes.cell_polygons import CellPolygons
from plantgrowth.meshes.geometry_error import GeometryError
from plantgrowth.meshes.msh_file import read_msh
from plantgrowth.meshes.tissue import TissueLayout
from plantgrowth.scene import Scene

RECTANGLE_SIDES = {"bottom": (1, 0.0), "left": (0, 0.0), "right": (0, None), "top": (1, None)}
"""Sides of the rectangle: (coordinate index, position; None = the far side)."""


@dataclass(frozen=True)
class Boundary:
    """The tagged boundary of a fine mesh.

    Attributes:
        facets: tags of the boundary facets.
        symmetry: the tags of the facets on the symmetry plane x2 = 0.
        edges: edge name (the keys of ``[loads]`` and ``[supports]``; those on x2 = 0 too) -> tag.
        pin: the vertex where u1 = 0.
    """

    facets: mesh.MeshTagsMetaClass
    symmetry: tuple[int, ...]
    edges: dict[str, int]
    pin: tuple[float, float]


def rectangle_boundary(msh: mesh.Mesh, width: float, height: float) -> Boundary:
    """The sides of ``[0, width] x [0, height]`` found geometrically (also the bottom of a
    micro tissue's outline, which has no loads), the origin pinned."""
    far = {0: width, 1: height}
    facets, values = [], []
    for tag, (axis, position) in enumerate(RECTANGLE_SIDES.values(), start=1):
        at = far[axis] if position is None else position
        found = mesh.locate_entities_boundary(msh, 1, lambda x, a=axis, p=at: np.isclose(x[a], p))
        facets.append(found)
        values.append(np.full(len(found), tag, dtype=np.int32))
    indices = np.concatenate(facets)
    order = np.argsort(indices)
    tags = mesh.meshtags(msh, 1, indices[order].astype(np.int32), np.concatenate(values)[order])
    names = {name: tag for tag, name in enumerate(RECTANGLE_SIDES, start=1)}
    return Boundary(tags, (names["bottom"],), names, (0.0, 0.0))


def outline_boundary(msh: mesh.Mesh, layout: TissueLayout) -> Boundary:
    """The boundary of a micro tissue's outline (:func:`meshes.tissue.build_outline_mesh`), its
    edges named as the micro model names its cells' outer walls (meshes/cell_walls.py): the
    facets on x2 = 0 ``bottom`` (the symmetry plane), the top row's facets facing up (outward
    n2 > 0) ``top``, every other ``left`` (n1 < 0) or ``right``; the origin pinned. Each facet
    lies on one cell's outer mid-line side, whose outward normal is ``(d2, -d1)`` for the side's
    vector d (the hexagons run counter-clockwise)."""
    names = {name: tag for tag, name in enumerate(RECTANGLE_SIDES, start=1)}
    facets = mesh.locate_entities_boundary(msh, 1, lambda x: np.full(x.shape[1], True))
    middle = mesh.compute_midpoints(msh, 1, facets)[:, :2]
    tol = 1e-8 * layout.delta_s
    cell, normal = np.full(len(facets), -1), np.zeros((len(facets), 2))
    for i in range(layout.n_cells):
        loop = layout.hexagon(i)
        for p, q in zip(loop, np.roll(loop, -1, axis=0), strict=True):
            d = q - p
            along = np.clip((middle - p) @ d / (d @ d), 0.0, 1.0)
            on = np.linalg.norm(middle - p - along[:, None] * d, axis=1) <= tol
            cell[on], normal[on] = i, (d[1], -d[0])
    tags = np.where(normal[:, 0] < 0.0, names["left"], names["right"])
    tags[(cell // layout.nx == layout.nx // 2 - 1) & (normal[:, 1] > 0.0)] = names["top"]
    tags[np.abs(middle[:, 1]) <= tol] = names["bottom"]
    order = np.argsort(facets)
    tagged = mesh.meshtags(msh, 1, facets[order].astype(np.int32), tags[order].astype(np.int32))
    return Boundary(tagged, (names["bottom"],), names, (0.0, 0.0))


CELLS_EDGES = {"bottom": 1, "outer": 2}
"""Facet tags of a tissue of cells' outline: the symmetry plane x2 = 0, every other edge."""


def cells_boundary(msh: mesh.Mesh, cells: CellPolygons) -> Boundary:
    """The boundary of the region a tissue of cells covers
    (:func:`meshes.cell_outline.build_cells_outline_mesh`): its facets on x2 = 0 ``bottom``
    (the symmetry plane), every other ``outer``; pinned at the left-most cell vertex on x2 = 0.
    A GeometryError if no cell has a side on x2 = 0 (nothing would hold the tissue)."""
    extent = float(np.ptp(cells.vertices, axis=0).max())
    tol = 1e-9 * extent
    on_plane = cells.vertices[np.abs(cells.vertices[:, 1]) <= tol]
    facets = mesh.locate_entities_boundary(msh, 1, lambda x: np.full(x.shape[1], True))
    low = np.abs(mesh.compute_midpoints(msh, 1, facets)[:, 1]) <= 1e-8 * extent
    if len(on_plane) < 2 or not msh.comm.allreduce(int(low.sum()), op=MPI.SUM):
        raise GeometryError(
            "tissue.cells: the macro model needs cells with a side on x2 = 0 (the symmetry "
            "plane, u2 = 0 there), and none has one"
        )
    tags = np.where(low, CELLS_EDGES["bottom"], CELLS_EDGES["outer"]).astype(np.int32)
    order = np.argsort(facets)
    tagged = mesh.meshtags(msh, 1, facets[order].astype(np.int32), tags[order])
    pin = on_plane[np.argmin(on_plane[:, 0])]
    return Boundary(tagged, (CELLS_EDGES["bottom"],), dict(CELLS_EDGES), (pin[0], 0.0))


def shape_domain(scene: Scene, comm: MPI.Comm) -> tuple[mesh.Mesh, Boundary]:
    """The fine mesh and boundary of a ``tissue.outline`` (meshed by gmsh with edges about h;
    edge i tagged ``polygon.edge_tag(i)``) or of a ``tissue.mesh`` file (its groups' tags)."""
    tissue = scene.tissue
    shape = tissue.shape
    if tissue.outline is not None:
        msh, _, facets = polygon.build_polygon_mesh(np.array(tissue.outline), tissue.h, comm)
        tags = {f"edge{i}": polygon.edge_tag(i) for i in range(len(tissue.outline))}
    else:
        msh, _, facets, tags = read_msh(tissue.mesh, comm)
    symmetry = tuple(tags[name] for name in shape.symmetry)
    edges = {name: tags[name] for name in (*shape.edges, *shape.symmetry)}
    return msh, Boundary(facets, symmetry, edges, shape.pin)


def pinned_vertices(msh: mesh.Mesh, pin: tuple[float, float]) -> np.ndarray:
    """This rank's vertices at ``pin`` (to 1e-8 of the tissue's size: mesh round-off)."""
    tol = 1e-8 * max(1.0, *(abs(p) for p in pin))
    return mesh.locate_entities(
        msh, 0, lambda x: (np.abs(x[0] - pin[0]) <= tol) & (np.abs(x[1] - pin[1]) <= tol)
    )
