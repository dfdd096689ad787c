"""The micro model's tissue of cells (docs/real_tissues.md, the micro model on cells): cells given
as mid-line polygons (:class:`CellPolygons`) with their walls' thickness, pure geometry.

Each cell owns the walls between its mid-line polygon and its void, the polygon offset inward by
the wall thickness w (mitred corners), so a shared wall is 2 w thick and an outer wall w thick.
If some cells have a side on x2 = 0, that line is the symmetry plane (docs/model.md section 7):
those cells are cut, their sides on it are no walls, and their void, outline and centre are those
of the cell united with its mirror image. A cell's centre (where the scene's fields are read) is
its polygon's centroid, ``x_c = sum_k (p_k + p_k+1)(p_k x p_k+1) / (6 A)``; a cut cell's is the
mirrored cell's, on x2 = 0. The regular honeycomb (:class:`TissueLayout`) is one such tissue.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from .cell_polygons import CellPolygons, polygon_centroid
from .geometry_error import GeometryError
from .honeycomb import offset_convex_polygon, polygon_area

if TYPE_CHECKING:
    from .tissue import TissueLayout


def _is_convex(loop: np.ndarray, tol: float) -> bool:
    d = np.roll(loop, -1, axis=0) - loop
    turns = d[:, 0] * np.roll(d[:, 1], -1) - d[:, 1] * np.roll(d[:, 0], -1)
    return bool(np.all(turns >= -tol))


def inward_offset(loop: np.ndarray, w: float, name: str) -> np.ndarray:
    """The polygon ``loop`` (CCW) offset inward by w with mitred corners: the exact half-plane
    intersection for a convex polygon, shapely's ``buffer(-w, join_style="mitre")`` otherwise; a
    GeometryError naming ``name`` unless one polygon remains."""
    scale = float(np.ptp(loop, axis=0).max())
    if _is_convex(loop, 1e-12 * scale * scale):
        void = offset_convex_polygon(loop, w)
    else:
        from shapely.geometry import JOIN_STYLE, Polygon, polygon

        shape = Polygon(loop).buffer(-w, join_style=JOIN_STYLE.mitre)
        void = np.empty((0, 2))
        if shape.geom_type == "Polygon" and not shape.is_empty:
            void = np.asarray(polygon.orient(shape, 1.0).exterior.coords)[:-1]
    if len(void) < 3 or polygon_area(void) <= 0.0:
        raise GeometryError(
            f"{name}: the wall thickness w = {w:.4g} (cell.w; a generated tissue's times 4 / Nx) "
            "leaves it no void or a void in pieces: cell.w must be smaller"
        )
    return void


def _mirror_united(loop: np.ndarray, tol: float, name: str) -> np.ndarray:
    """A cut cell's polygon united with its mirror image about x2 = 0 (CCW), the two ends of
    its cut dropped where the sides through them continue straight (the honeycomb's hexagon)."""
    on = np.abs(loop[:, 1]) < tol
    n = len(loop)
    if np.count_nonzero(on != np.roll(on, 1)) != 2:
        raise GeometryError(f"{name}: a cut cell must meet x2 = 0 along one run of sides only")
    start = next(k for k in range(n) if on[k] and on[k - 1] and not on[(k + 1) % n])
    loop = np.roll(loop, -start, axis=0)  # starts where the cut ends, runs over the top
    end = next(k for k in range(1, n) if abs(loop[k, 1]) < tol)
    upper = loop[: end + 1].copy()
    upper[[0, -1], 1] = 0.0
    lower = upper[-2:0:-1] * np.array([1.0, -1.0])
    full = np.vstack([upper, lower])
    d_in, d_out = full - np.roll(full, 1, axis=0), np.roll(full, -1, axis=0) - full
    cross = d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0]
    straight = np.abs(cross) <= 1e-12 * np.linalg.norm(d_in, axis=1) * np.linalg.norm(d_out, axis=1)
    keep = np.ones(len(full), dtype=bool)
    keep[[0, end]] = ~straight[[0, end]]
    return full[keep]


@dataclass(frozen=True)
class CellTissue:
    """Attributes:
    cells: the cells' mid-line polygons (in x2 >= 0).
    w: the walls' thickness (each cell's own half of a shared wall), in the cells' length unit.
    mesh_length: the length ``resolution`` wall elements span (:func:`tissue.wall_mesh_size`).
    name: how errors and logs name the tissue (``"Nx = 4, 8 cells"``, ``"120 given cells"``).
    honeycomb: the TissueLayout the cells are, if they are one: its own coordinates of each
        cell's hexagon, void and centre are used (equal to the general ones to round-off), so
        the honeycomb runs bit for bit as before cells could be given.
    mirrored: (n_cells,) which cells are cut by the symmetry plane (default None: every cell
        with a side on x2 = 0). A cell with a side on x2 = 0 that is not cut meets its own
        mirror image there: that side is a wall (its half w thick, u2 = 0 on the plane).
    """

    cells: CellPolygons
    w: float
    mesh_length: float
    name: str
    honeycomb: TissueLayout | None = None
    mirrored: tuple[bool, ...] | None = None

    @classmethod
    def from_cells(
        cls, cells: CellPolygons, w: float, cut: np.ndarray | None = None
    ) -> CellTissue:
        """A tissue of given cells and wall thickness w, ``cut`` (n_cells,) the cells cut by the
        symmetry plane (default: every cell with a side on it); mesh length ``min(w, l / 4)``,
        l the median side length (the honeycomb's ``min(w, min(l1, l2) / 4)``)."""
        cells.check()
        if not (np.isfinite(w) and w > 0.0):
            raise GeometryError(f"cell.w = {w!r} is invalid: the wall thickness must be > 0")
        lowest = float(cells.vertices[:, 1].min())
        if lowest < -1e-9 * float(np.abs(cells.vertices).max()):
            raise GeometryError(
                f"the cells reach x2 = {lowest:.4g}: a tissue must lie in x2 >= 0 (x2 = 0 is "
                "its symmetry plane where a cell has a side on it)"
            )
        sides = np.array(list(cells.sides()))
        lengths = np.linalg.norm(cells.vertices[sides[:, 0]] - cells.vertices[sides[:, 1]], axis=1)
        length = min(w, 0.25 * float(np.median(lengths)))
        mirrored = None if cut is None else tuple(bool(c) for c in cut)
        tissue = cls(cells, float(w), length, f"{cells.n_cells} given cells", None, mirrored)
        bad = np.flatnonzero(tissue.cut & ~tissue.on_plane)
        if bad.size:
            raise GeometryError(f"cell {cells.labels[bad[0]]} is cut but has no side on x2 = 0")
        return tissue

    @classmethod
    def from_layout(cls, layout: TissueLayout) -> CellTissue:
        """The regular honeycomb of ``layout``: its hexagons (the bottom row cut), w scaled by
        delta_s like the cells."""
        cell, d = layout.cell, layout.delta_s
        cells = CellPolygons.from_loops([layout.hexagon(i) for i in range(layout.n_cells)])
        return cls(cells, d * cell.w, d * min(cell.w, 0.25 * min(cell.l1, cell.l2)),
                   f"Nx = {layout.nx}, {layout.n_cells} cells", layout)  # fmt: skip

    @property
    def n_cells(self) -> int:
        return self.cells.n_cells

    def polygon(self, i: int) -> np.ndarray:
        """(k, 2) cell i's mid-line polygon, counter-clockwise (a cut cell's: its part above
        x2 = 0)."""
        return self.cells.polygon(i) if self.honeycomb is None else self.honeycomb.hexagon(i)

    @cached_property
    def tolerance(self) -> float:
        """Round-off of coordinates: 1e-9 of the tissue's extent."""
        return 1e-9 * float(np.abs(self.cells.vertices).max())

    @cached_property
    def on_plane(self) -> np.ndarray:
        """(n_cells,) whether each cell has a side on the symmetry plane x2 = 0."""
        return self.cells.on_symmetry_plane

    @cached_property
    def cut(self) -> np.ndarray:
        """(n_cells,) whether each cell is cut by the symmetry plane (:attr:`mirrored`)."""
        return self.on_plane if self.mirrored is None else np.array(self.mirrored)

    @property
    def cut_cells(self) -> np.ndarray:
        """Ids of the cut cells (none: the tissue has no symmetry plane)."""
        return np.flatnonzero(self.cut)

    @property
    def symmetric(self) -> bool:
        """Whether the tissue has the symmetry plane x2 = 0 (some cell has a side on it)."""
        return bool(self.on_plane.any())

    def outline(self, i: int) -> np.ndarray:
        """Cell i's whole polygon: a cut cell's united with its mirror image."""
        if (layout := self.honeycomb) is not None:
            return layout.delta_s * layout.cell.hexagon() + layout.centres[i]
        loop = self.polygon(i)
        if not self.cut[i]:
            return loop
        return _mirror_united(loop, self.tolerance, f"cell {self.cells.labels[i]}")

    def void(self, i: int) -> np.ndarray:
        """Cell i's void: its whole polygon offset inward by w (a cut cell's is open at x2 = 0:
        it reaches below)."""
        if self.honeycomb is not None:
            return self.honeycomb.void(i)
        return inward_offset(self.outline(i), self.w, f"cell {self.cells.labels[i]}")

    @cached_property
    def centres(self) -> np.ndarray:
        """(n_cells, 2) the cells' centres (module docstring)."""
        if self.honeycomb is not None:
            return self.honeycomb.centres
        centres = self.cells.centroids
        for i in self.cut_cells:
            centres[i] = [polygon_centroid(self.outline(i))[0], 0.0]
        return centres

    @cached_property
    def perimeters(self) -> np.ndarray:
        """(n_cells,) each cell's walls' mid-line length (a cut cell's side on x2 = 0 is none)."""
        out = self.cells.perimeters
        for i in self.cut_cells:
            p = self.polygon(i)
            q = np.roll(p, -1, axis=0)
            on = (np.abs(p[:, 1]) < self.tolerance) & (np.abs(q[:, 1]) < self.tolerance)
            out[i] -= np.linalg.norm(q - p, axis=1)[on].sum()
        return out

    @property
    def bounding_box(self) -> tuple[float, float]:
        """(width, height): the largest x1 and x2 of the cells (the scene's fields span
        [0, width] x [0, height])."""
        if self.honeycomb is not None:
            return self.honeycomb.bounding_box
        top = self.cells.vertices.max(axis=0)
        return float(top[0]), float(top[1])

    @cached_property
    def wall_area(self) -> float:
        """The walls' area: the polygons' less their voids' parts above x2 = 0."""
        from .tissue import clip_below

        voids = [clip_below(self.void(i)) if self.cut[i] else self.void(i)
                 for i in range(self.n_cells)]  # fmt: skip
        return float(self.cells.areas.sum() - sum(polygon_area(v) for v in voids))


def as_tissue(source: CellTissue | TissueLayout) -> CellTissue:
    """A CellTissue as it is, a TissueLayout's honeycomb as one."""
    return source if isinstance(source, CellTissue) else CellTissue.from_layout(source)
