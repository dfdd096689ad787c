"""A tissue given as cells (issue 34): the mid-line polygons of its walls, sharing vertices.

Pure numpy. Each cell is a counter-clockwise loop of indices into one vertex table, so two
neighbours' shared wall is the same pair of vertices, run in opposite directions. A side of one
cell only is an outer wall. This is the form every source of cells (a generated Voronoi tissue,
a segmented image, a polygon table, the regular honeycomb) is turned into, and what the micro
model meshes and the macro model reads its cells' shapes from.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry_error import GeometryError
from .honeycomb import polygon_area


def polygon_centroid(p: np.ndarray) -> np.ndarray:
    """(2,) area centroid of a polygon (k, 2): ``sum (p_i + p_j) a_i / (3 sum a_i)``,
    ``a_i = x_i y_j - x_j y_i``, j = i + 1 (not the vertices' mean)."""
    q = np.roll(p, -1, axis=0)
    cross = p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]
    return ((p + q) * cross[:, None]).sum(axis=0) / (3.0 * cross.sum())


@dataclass(frozen=True)
class CellPolygons:
    """Attributes:
    vertices: (n_v, 2) positions, in the scene's length unit.
    cells: one (k_i,) int array per cell: its vertices, counter-clockwise, the first not repeated.
    labels: (n_cells,) each cell's id in its source (an image's label, a table's id, or 0..n-1).
    """

    vertices: np.ndarray
    cells: tuple[np.ndarray, ...]
    labels: np.ndarray

    @classmethod
    def from_loops(
        cls, loops: list[np.ndarray], labels: np.ndarray | None = None, tol: float | None = None
    ) -> CellPolygons:
        """Cells from coordinate loops (each (k, 2), counter-clockwise); vertices closer than
        ``tol`` (default 1e-9 of the tissue's extent) are one vertex, shared by their cells."""
        loops = [np.asarray(p, dtype=float).reshape(-1, 2) for p in loops]
        if not loops:
            raise GeometryError("a tissue needs at least one cell")
        stacked = np.vstack(loops)
        if tol is None:
            tol = 1e-9 * max(float(np.ptp(stacked, axis=0).max()), 1e-300)
        _, first, ids = np.unique(
            np.round(stacked / tol), axis=0, return_index=True, return_inverse=True
        )
        ids = ids.reshape(-1)
        splits = np.cumsum([len(p) for p in loops])[:-1]
        cells = tuple(np.asarray(c, dtype=np.int64) for c in np.split(ids, splits))
        labels = np.arange(len(loops)) if labels is None else np.asarray(labels)
        return cls(stacked[first], cells, labels)

    @property
    def n_cells(self) -> int:
        return len(self.cells)

    def polygon(self, i: int) -> np.ndarray:
        """(k, 2) mid-line polygon of cell i, counter-clockwise."""
        return self.vertices[self.cells[i]]

    @property
    def areas(self) -> np.ndarray:
        """Each cell's mid-line polygon area (shoelace)."""
        return np.array([polygon_area(self.polygon(i)) for i in range(self.n_cells)])

    @property
    def perimeters(self) -> np.ndarray:
        """Each cell's mid-line perimeter."""
        return np.array(
            [np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1).sum()
             for p in (self.polygon(i) for i in range(self.n_cells))]
        )  # fmt: skip

    @property
    def centroids(self) -> np.ndarray:
        """(n_cells, 2) each polygon's centroid (area-weighted, not the vertices' mean)."""
        return np.array([polygon_centroid(self.polygon(i)) for i in range(self.n_cells)])

    @property
    def on_symmetry_plane(self) -> np.ndarray:
        """(n_cells,) bool: the cells with a side on x2 = 0 (both ends within 1e-9 of the
        tissue's extent of it)."""
        tol = 1e-9 * float(np.ptp(self.vertices, axis=0).max())
        low = np.abs(self.vertices[:, 1]) <= tol
        return np.array([bool(np.any(low[c] & low[np.roll(c, -1)])) for c in self.cells])

    def sides(self) -> dict[tuple[int, int], list[int]]:
        """Undirected side (sorted vertex pair) -> the cells that have it (one or two)."""
        out: dict[tuple[int, int], list[int]] = {}
        for cell, loop in enumerate(self.cells):
            for a, b in zip(loop, np.roll(loop, -1), strict=True):
                out.setdefault((min(int(a), int(b)), max(int(a), int(b))), []).append(cell)
        return out

    @property
    def neighbour_counts(self) -> np.ndarray:
        """How many distinct cells share at least one side with each cell."""
        neighbours: list[set[int]] = [set() for _ in range(self.n_cells)]
        for found in self.sides().values():
            if len(found) == 2:
                neighbours[found[0]].add(found[1])
                neighbours[found[1]].add(found[0])
        return np.array([len(s) for s in neighbours])

    def check(self) -> None:
        """A GeometryError unless every cell has at least 3 vertices, positive area, and every
        side belongs to one or two cells (two cells' shared side run in opposite directions)."""
        for i, loop in enumerate(self.cells):
            if len(loop) < 3 or len(set(loop.tolist())) != len(loop):
                raise GeometryError(f"cell {self.labels[i]}: needs >= 3 distinct vertices")
        bad = np.flatnonzero(self.areas <= 0.0)
        if bad.size:
            raise GeometryError(
                f"cell {self.labels[bad[0]]}: its polygon must be counter-clockwise with area > 0"
            )
        for (a, b), found in self.sides().items():
            if len(found) > 2:
                labels = ", ".join(str(self.labels[c]) for c in found)
                raise GeometryError(f"side {a}-{b} belongs to more than two cells ({labels})")
