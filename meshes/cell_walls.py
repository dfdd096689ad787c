"""The wall network of a micro tissue (docs/model.md sections 7, 12): which cells share which
mid-line segment, and which outer walls lie on which edge of the tissue (pure numpy).

Segments are the sides of the cells' mid-line hexagons (the bottom row cut at x2 = 0; the cut
itself, on the symmetry plane, is no wall). A side that two cells have is a shared wall; a side
of one cell only is an outer wall, on the edge its outward normal n and its cell's place name:
"top" for the top row's outer walls facing up (n2 > 0), else "left" (n1 < 0) or "right".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .tissue import TissueLayout

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


def wall_network(layout: TissueLayout) -> WallNetwork:
    """The shared and outer walls of the cells of ``layout``."""
    loops = [layout.hexagon(i) for i in range(layout.n_cells)]
    stacked = np.vstack(loops)
    scale = 1e-9 * np.abs(stacked).max()
    # a vertex of several cells is one point: merge to round-off, as the cell outlines do
    _, ids = np.unique(np.round(stacked / scale), axis=0, return_inverse=True)
    ids = ids.reshape(-1)
    sides: dict[tuple[int, int], list[tuple[int, np.ndarray]]] = {}
    start = 0
    for cell, loop in enumerate(loops):
        n = len(loop)
        for k in range(n):
            p, q = loop[k], loop[(k + 1) % n]
            if abs(p[1]) < scale and abs(q[1]) < scale:
                continue  # the cut on the symmetry plane
            key = tuple(sorted((int(ids[start + k]), int(ids[start + (k + 1) % n]))))
            sides.setdefault(key, []).append((cell, q - p))
        start += n
    top_row = layout.nx // 2 - 1
    pairs, shared, outer_cell, outer, outer_edge = [], [], [], [], []
    for found in sides.values():
        if len(found) == 2:
            pairs.append((found[0][0], found[1][0]))
            shared.append(found[0][1])
            continue
        cell, d = found[0]
        normal = np.array([d[1], -d[0]])  # outward: the hexagons run counter-clockwise
        row = cell // layout.nx
        edge = "top" if row == top_row and normal[1] > 0.0 else "left" if normal[0] < 0 else "right"
        outer_cell.append(cell)
        outer.append(d)
        outer_edge.append(edge)
    return WallNetwork(
        np.array(pairs, dtype=np.int64).reshape(-1, 2), np.array(shared).reshape(-1, 2),
        np.array(outer_cell, dtype=np.int64), np.array(outer).reshape(-1, 2),
        np.array(outer_edge),
    )  # fmt: skip


def grown_lengths(vectors: np.ndarray, Fg: np.ndarray) -> np.ndarray:
    """``|Fg t|`` of reference vectors (m, 2), each with its growth tensor (m, 2, 2)."""
    return np.linalg.norm(np.einsum("mij,mj->mi", Fg, vectors), axis=1)
