"""The region a tissue of cells covers (issue 34): its outline, its fine mesh, and the cell that
holds each point (per-cell values as a field on that region).

The region is the union of the cells' mid-line polygons. Its mesh is built as the honeycomb's
outline mesh is (:func:`meshes.tissue.build_outline_mesh`: the polygons fragmented by gmsh, so
the triangles conform to every cell side and each lies in one cell); a regular honeycomb given
as cells thus gets the very mesh of today's micro tissue's outline. A per-cell value is a field
constant on each cell's polygon (:func:`cell_of_points`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from .cell_polygons import CellPolygons
from .cell_shapes import CellShapes
from .geometry_error import GeometryError
from .tissue import build_outline_mesh


def tissue_outline(cells: CellPolygons) -> np.ndarray:
    """(k, 2) the exterior of the union of the cells' polygons, counter-clockwise, the first
    point not repeated (shapely's ``unary_union``); a GeometryError unless the cells form one
    connected region."""
    from shapely.geometry import Polygon  # here: only the tissues of cells load shapely
    from shapely.geometry.polygon import orient
    from shapely.ops import unary_union

    union = unary_union([Polygon(cells.polygon(i)) for i in range(cells.n_cells)])
    if union.geom_type != "Polygon":
        raise GeometryError(
            f"tissue.cells: the cells form {len(union.geoms)} separate regions, not one tissue"
        )
    return np.array(orient(union, 1.0).exterior.coords)[:-1]


@dataclass(frozen=True)
class _Loops:
    """The cells as :func:`meshes.tissue.build_outline_mesh` reads a layout: ``n_cells`` and
    each cell's polygon (``hexagon(i)``)."""

    cells: CellPolygons

    @property
    def n_cells(self) -> int:
        return self.cells.n_cells

    def hexagon(self, cell_id: int) -> np.ndarray:
        return self.cells.polygon(cell_id)


def build_cells_outline_mesh(
    cells: CellPolygons, h: float, comm: MPI.Comm = MPI.COMM_WORLD, model_rank: int = 0
):
    """Mesh (edges about h) of the region the cells cover, conforming to every cell side:
    ``(mesh, cell_tags, facet_tags)`` as :func:`meshes.tissue.build_outline_mesh`."""
    return build_outline_mesh(_Loops(cells), h, comm, model_rank)


def cell_of_points(cells: CellPolygons, points: np.ndarray) -> np.ndarray:
    """(n,) the index of the cell whose polygon holds each point (crossing-number test; a point
    on a shared side goes to one of its cells); a point in no polygon (round-off on the tissue's
    boundary) goes to the cell of the nearest centroid."""
    points = np.asarray(points, dtype=float)[:, :2]
    out = np.full(len(points), -1)
    for i in range(cells.n_cells):
        p = cells.polygon(i)
        low, high = p.min(axis=0), p.max(axis=0)
        near = np.flatnonzero(np.all((points >= low) & (points <= high), axis=1) & (out < 0))
        if not near.size:
            continue
        x, y = points[near, 0:1], points[near, 1:2]
        a, b = p, np.roll(p, -1, axis=0)
        straddles = (a[:, 1] > y) != (b[:, 1] > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            crossing = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
        inside = np.sum(straddles & (x < crossing), axis=1) % 2 == 1
        out[near[inside]] = i
    lost = np.flatnonzero(out < 0)
    if lost.size:
        centroids = cells.centroids
        distance = np.linalg.norm(points[lost, None, :] - centroids[None], axis=2)
        out[lost] = np.argmin(distance, axis=1)
    return out


@dataclass(frozen=True)
class CellShapeField:
    """Each cell's Fg0 (:mod:`meshes.cell_shapes`) as a field on the region the cells cover:
    constant on each cell's polygon."""

    cells: CellPolygons
    shapes: CellShapes

    def __call__(self, points: np.ndarray) -> np.ndarray:
        """(n, 2, 2) Fg0 of the cell holding each point (n, 2)."""
        return self.shapes.Fg0[cell_of_points(self.cells, points)]
