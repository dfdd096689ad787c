"""The micro tissue's biological cells as polygons: ``cells.xdmf`` and ``cells.csv``.

A cell's polygon is its mid-line polygon (docs/model.md sections 2, 7; a cut cell's above
x2 = 0), whose vertices are wall junctions (or, on the tissue's edge, points of its outer surface).
``cells.xdmf`` holds the polygons' edges as 2-node lines over the reference vertices, with the
displacement u at the vertices and the cell id per line: ParaView's Warp By Vector draws the
deformed polygons (straight edges between the moved vertices; the walls' bowing between
junctions is not drawn).

``cells.csv`` has one row per cell and written step (:data:`CELL_COLUMNS`): the centroid and
area of the cell (its own walls and void) at reference (the polygon's) and deformed (the exact
integrals of forms/cell_measures.py, which sum to the tissue's area in summary.csv), its
reference walls' mid-line length and number of neighbours, and tr G,
anisotropy and growth direction of the cell's growth rate (:mod:`plantgrowth.base.principal`).
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem, geometry
from mpi4py import MPI

from plantgrowth.base import principal
from plantgrowth.meshes.cell_tissue import CellTissue
from plantgrowth.models.micro.water import WaterState
from plantgrowth.models.step import SideMesh

CELL_COLUMNS = [
    "step", "t", "cell", "x1_ref", "x2_ref", "x1", "x2", "area_ref", "perimeter_ref",
    "neighbours", "area",
    "trG", "growth_anisotropy", "growth_direction_1", "growth_direction_2",
]  # fmt: skip
FIBRE_CELL_COLUMNS = ["fibre_angle"]
"""cells.csv's columns of fibred scenes: the director angle (degrees) the step used."""
WATER_CELL_COLUMNS = ["P", "psi", "water", "inflow"]
"""cells.csv's columns of scenes with ``[hydraulics]``: turgor, water potential, water held and
net inflow rate (plantgrowth/models/micro/water.py)."""


def polygon_centroids(points: np.ndarray, polygons: list[np.ndarray]) -> tuple[np.ndarray, ...]:
    """Signed areas (n,) and centroids (n, 2) of polygons given as vertex index arrays."""
    areas, centroids = np.empty(len(polygons)), np.empty((len(polygons), 2))
    for i, loop in enumerate(polygons):
        p, q = points[loop], points[np.roll(loop, -1)]
        cross = p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]
        areas[i] = 0.5 * cross.sum()
        centroids[i] = ((p + q) * cross[:, None]).sum(axis=0) / (6.0 * areas[i])
    return areas, centroids


class PointValues:
    """Values of a vector function at fixed points, identical on every rank (collective).

    Each point is evaluated by the lowest rank that owns a cell containing it; the values are
    then summed over the ranks (every point has exactly one evaluating rank).
    """

    def __init__(self, u: fem.Function, points: np.ndarray) -> None:
        msh = u.function_space.mesh
        self.comm: MPI.Comm = msh.comm
        self.x = np.column_stack([points, np.zeros(len(points))])
        n_owned = msh.topology.index_map(msh.topology.dim).size_local
        tree = geometry.BoundingBoxTree(msh, msh.topology.dim)
        colliding = geometry.compute_colliding_cells(
            msh, geometry.compute_collisions(tree, self.x), self.x
        )
        cells = np.full(len(points), -1, dtype=np.int32)
        for i in range(len(points)):
            owned = colliding.links(i)[colliding.links(i) < n_owned]
            if len(owned):
                cells[i] = owned.min()
        rank = np.where(cells >= 0, self.comm.rank, self.comm.size).astype(np.int64)
        first = np.empty_like(rank)
        self.comm.Allreduce(rank, first, op=MPI.MIN)
        if np.any(first == self.comm.size):
            missing = self.x[np.argmax(first == self.comm.size), :2]
            raise RuntimeError(f"cell outline vertex {missing} lies outside the walls mesh")
        self.mine = np.flatnonzero(first == self.comm.rank)
        self.cells = cells[self.mine]
        self.shape = (len(points), u.function_space.dofmap.index_map_bs)

    def __call__(self, u: fem.Function) -> np.ndarray:
        """(n_points, block size) values of ``u`` (a function on the same space)."""
        values = np.zeros(self.shape)
        if len(self.mine):
            values[self.mine] = u.eval(self.x[self.mine], self.cells)
        return self.comm.allreduce(values, op=MPI.SUM)


class CellOutlines:
    """The cells' polygons, their displacement after each step and the rows of cells.csv.

    Args:
        tissue: the micro tissue.
        u: the wall displacement (evaluated at the polygons' vertices by :meth:`update`).
    """

    fibred = False
    """Whether cells.csv has the column ``fibre_angle`` (fibred scenes)."""
    fibre_angle: np.ndarray | None = None
    """(n,) the director angles (degrees) the last step used (fibred scenes)."""
    watered = False
    """Whether cells.csv has the water columns (scenes with ``[hydraulics]``)."""
    water: WaterState | None = None
    """The last step's water (scenes with ``[hydraulics]``)."""

    @property
    def columns(self) -> list[str]:
        fibres = FIBRE_CELL_COLUMNS if self.fibred else []
        return CELL_COLUMNS + fibres + (WATER_CELL_COLUMNS if self.watered else [])

    def __init__(self, tissue: CellTissue, u: fem.Function) -> None:
        # shared vertices of neighbouring cells are one point
        self.points, self.polygons = tissue.cells.vertices, list(tissue.cells.cells)
        segments = np.vstack([np.column_stack([p, np.roll(p, -1)]) for p in self.polygons])
        segment_cell = np.repeat(np.arange(tissue.n_cells), [len(p) for p in self.polygons])
        self.area_ref, self.centroid_ref = polygon_centroids(self.points, self.polygons)
        self.perimeter_ref, self.neighbours = tissue.perimeters, tissue.cells.neighbour_counts
        self.u = u
        self._at_vertices = PointValues(u, self.points)
        self.displacement = np.zeros_like(self.points)
        self.G = np.zeros((tissue.n_cells, 2, 2))
        self.area, self.centroid = self.area_ref, self.centroid_ref
        self.side = SideMesh(
            "cells.xdmf", "Outlines", "outlines", self.points, segments,
            {"u": ("Node", 2), "cell_id": ("Cell", 1)}, {"cell_id": segment_cell.astype(float)},
        )  # fmt: skip

    def update(self, G: np.ndarray, area: np.ndarray, centroid: np.ndarray) -> None:
        """After a step's solve (collective): u at the vertices; the cells' growth rates G
        (n, 2, 2), deformed areas (n,) and centroids (n, 2)."""
        self.displacement = self._at_vertices(self.u)
        self.side.values["u"] = self.displacement
        self.G, self.area, self.centroid = G, area, centroid

    def rows(self, step: int, t: float) -> list[dict[str, float]]:
        """The rows of cells.csv for the last :meth:`update` (the same on every rank)."""
        area, centroid = self.area, self.centroid
        trG, anisotropy = principal.trace(self.G), principal.anisotropy(self.G)
        direction = principal.principal_direction(self.G)
        angle = self.fibre_angle if self.fibred else ()
        w = self.water
        water = np.column_stack([w.P, w.psi, w.water, w.inflow]) if self.watered else ()
        return [
            dict(zip(self.columns, (
                step, t, i, *self.centroid_ref[i], *centroid[i], self.area_ref[i],
                self.perimeter_ref[i], self.neighbours[i], area[i],
                trG[i], anisotropy[i], *direction[i], *angle[i : i + 1], *(water[i] if
                self.watered else ()),
            ), strict=True))
            for i in range(len(self.polygons))
        ]  # fmt: skip
