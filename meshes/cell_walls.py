"""The wall network of a micro tissue (docs/model.md sections 7, 12): which cells share which
mid-line segment, and which outer walls lie on which edge of the tissue (pure numpy).

Segments are the sides of the cells' mid-line polygons (a cut cell's side on the symmetry plane
x2 = 0 is no wall). A side that two cells have is a shared wall; a side of one cell only is an
outer wall, on the edge of the tissue's bounding box [x1_min, x1_max] x [x2_min, x2_max] that its
outward normal n faces ("top": n2 > 0, "left": n1 < 0, "right": n1 > 0) and, of those, the one
nearest to its midpoint (the honeycomb: the top row's walls facing up are "top", the other rows'
outer walls "left" or "right"). A wall facing none of them (n = (0, -1), a free tissue's
bottom) goes to the nearest of the three.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cell_tissue import CellTissue, as_tissue
from .tissue import TissueLayout  # noqa: TC001

EDGE_NAMES = ("left", "right", "top")


@dataclass(frozen=True)
class WallNetwork:
    """Attributes:
    pairs: (m, 2) the two cells of each shared wall.
    shared: (m, 2) each shared wall's reference mid-line vector.
    outer_cell: (k,) the cell of each outer wall.
    outer: (k, 2) each outer wall's reference mid-line vector.
    outer_edge: (k,) each outer wall's edge name (:data:`EDGE_NAMES`).
    """

    pairs: np.ndarray
    shared: np.ndarray
    outer_cell: np.ndarray
    outer: np.ndarray
    outer_edge: np.ndarray


def outer_edge(tissue: CellTissue, midpoint: np.ndarray, normal: np.ndarray) -> str:
    """The edge name of an outer wall (module docstring)."""
    low, high = tissue.cells.vertices.min(axis=0), tissue.cells.vertices.max(axis=0)
    distance = {"left": midpoint[0] - low[0], "right": high[0] - midpoint[0],
                "top": high[1] - midpoint[1]}  # fmt: skip
    facing = {"left": normal[0] < 0.0, "right": normal[0] > 0.0, "top": normal[1] > 0.0}
    names = [name for name in EDGE_NAMES if facing[name]] or list(EDGE_NAMES)
    return min(names, key=lambda name: distance[name])


def wall_network(source: CellTissue | TissueLayout) -> WallNetwork:
    """The shared and outer walls of the cells of a tissue (a TissueLayout: its honeycomb)."""
    tissue = as_tissue(source)
    vertices, tol = tissue.cells.vertices, tissue.tolerance
    sides: dict[tuple[int, int], list[tuple[int, np.ndarray]]] = {}
    for cell, loop in enumerate(tissue.cells.cells):
        for a, b in zip(loop.tolist(), np.roll(loop, -1).tolist(), strict=False):
            p, q = vertices[a], vertices[b]
            if tissue.cut[cell] and abs(p[1]) < tol and abs(q[1]) < tol:
                continue  # the cut on the symmetry plane
            sides.setdefault((min(a, b), max(a, b)), []).append((cell, q - p, 0.5 * (p + q)))
    pairs, shared, outer_cell, outer, edges = [], [], [], [], []
    for found in sides.values():
        if len(found) == 2:
            pairs.append((found[0][0], found[1][0]))
            shared.append(found[0][1])
            continue
        cell, d, midpoint = found[0]
        normal = np.array([d[1], -d[0]])  # outward: the polygons run counter-clockwise
        outer_cell.append(cell)
        outer.append(d)
        edges.append(outer_edge(tissue, midpoint, normal))
    return WallNetwork(
        np.array(pairs, dtype=np.int64).reshape(-1, 2), np.array(shared).reshape(-1, 2),
        np.array(outer_cell, dtype=np.int64), np.array(outer).reshape(-1, 2),
        np.array(edges),
    )  # fmt: skip


def grown_lengths(vectors: np.ndarray, Fg: np.ndarray) -> np.ndarray:
    """``|Fg t|`` of reference vectors (m, 2), each with its growth tensor (m, 2, 2)."""
    return np.linalg.norm(np.einsum("mij,mj->mi", Fg, vectors), axis=1)
