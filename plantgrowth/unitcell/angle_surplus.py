"""The angle surpluses of a fibred table on coarse stretch grids (issue 33, item 2; a sparse grid).

The director interpolant (:mod:`plantgrowth.unitcell.director_lattice`) answers a fibred table

    A(b, s) = I_M[S](b, s) + (I_2M - I_M)[P_1 f](b, s) + (I_4M - I_2M)[P_0 f](b, s),

with I_N the trigonometric interpolant through N angle nodes, S the nodes' own stretch
interpolants (refined to the tolerance) and P_l f the bilinear interpolant of the exact values
on the uniform stretch grid of level l (spacing ``H0 / 2^l``, the lattice's own points). The
surplus ``(I_2N - I_N) g`` of a smooth periodic g is about the error of I_N, and P_l is one
linear map for every node, so ``(I_2N - I_N)[P_l f] = P_l[(I_2N - I_N) f]`` is the stretch grid's
interpolant of a function of that small size: its error is P_l's relative error (1-2% at
l = 0 for the fibred cell, 0.4% at l = 1) times the surplus, not times f. So the new nodes of
each doubling need the few values of a coarse grid, not a stretch table refined to the
tolerance, as in a sparse grid. The grid values are asked of the stretch surrogate as ordinary
queries (a level-0 square's lower-left corner, a level-1 square's centre: the square's corners
are built and solved once, for every query and step) and read off its lattice values.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from plantgrowth.unitcell.surrogate import H0, STEP

_CORNERS = np.array([[0, 0], [1, 0], [0, 1], [1, 1]])  # a square's corners, in its spacing


def grid_squares(s: np.ndarray, level: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The level-``level`` grid squares holding the stretches s (n, 2): their lower-left
    corners in grid units (u, 2, unique), each query's square (n,) and its bilinear hats (n, 4)
    (rounded as the stretch lattice rounds, so a query on a grid line takes one square)."""
    x = s / (H0 / 2.0**level)
    base = np.floor(np.round(x, 9))
    t = np.clip(np.round(x - base, 9), 0.0, 1.0)
    squares, square = _unique_rows(base.astype(np.int64))
    tx, ty = t[:, 0:1], t[:, 1:2]
    hats = np.hstack([(1 - tx) * (1 - ty), tx * (1 - ty), (1 - tx) * ty, tx * ty])
    return squares, square.reshape(-1), hats


def _unique_rows(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(cells, axis=0, return_inverse=True)`` for (n, 2) integers, by one integer key
    per row (row-major in the rows' bounding box, so the same lexicographic order): numpy's
    row-wise unique sorts a structured view: 1.5 ms for 4,000 rows against 0.26 ms."""
    if len(cells) == 0:
        return cells.reshape(0, 2), np.zeros(0, dtype=np.int64)
    low = cells.min(axis=0)
    width = int(cells[:, 1].max() - low[1]) + 1
    keys, inverse = np.unique((cells[:, 0] - low[0]) * width + cells[:, 1] - low[1],
                              return_inverse=True)  # fmt: skip
    return np.stack([keys // width + low[0], keys % width + low[1]], axis=1), inverse


def builders(squares: np.ndarray, level: int) -> np.ndarray:
    """Stretches (u, 2) whose queries make the stretch surrogate build the squares' corners:
    a level-0 square's lower-left corner (a corner query builds its level-0 square and stops),
    a finer square's centre (built down to the square holding it, then within any tolerance
    of at least 1)."""
    return (squares + (0.5 if level else 0.0)) * (H0 / 2.0**level)


def corner_points(squares: np.ndarray, level: int) -> list[tuple[int, int]]:
    """The squares' corners (u x 4, corner order of the hats) in the lattice's finest integers."""
    corners = (squares[:, None, :] + _CORNERS[None]) * (STEP >> level)
    return [(a, b) for a, b in corners.reshape(-1, 2).tolist()]


def surplus_weights(fine: np.ndarray, coarse: np.ndarray) -> np.ndarray:
    """Weights (n, N) of ``I_N - I_N/2`` at n angles, from the cardinal functions of the
    trigonometric interpolants through the N nodes (``fine``, (n, N)) and through every other
    one of them (``coarse``, (n, N/2)): the N nodes' weights less those of every other node."""
    surplus = fine.copy()
    surplus[:, ::2] -= coarse
    return surplus


def grid_term(
    node_tables: list[tuple], squares: np.ndarray, level: int, square: np.ndarray,
    hats: np.ndarray, surplus: np.ndarray, values: Mapping,
) -> np.ndarray:  # fmt: skip
    """``sum_j surplus_j(b) P_level f_j(s)`` per query (n, m): node j's table
    ``node_tables[j]``, the query's grid square ``square`` (into ``squares``) and hats, the
    exact corner values from the lattice's ``values`` ((table, point) -> packed values).
    Per square, one product of its queries' weights ``hats_c surplus_j`` (q, 4 N) with its
    corners' values (4 N, m)."""
    points = corner_points(squares, level)
    table = np.array([[values[node, p] for node in node_tables] for p in points])  # (u 4, N, m)
    table = table.reshape(len(squares), 4 * len(node_tables), -1)
    weights = (hats[:, :, None] * surplus[:, None, :]).reshape(len(square), -1)  # (n, 4 N)
    out = np.zeros((len(square), table.shape[-1]))
    order = np.argsort(square, kind="stable")
    bounds = np.searchsorted(square[order], np.arange(len(squares) + 1))
    for u in range(len(squares)):  # a few squares
        mine = order[bounds[u] : bounds[u + 1]]
        out[mine] = weights[mine] @ table[u]
    return out
