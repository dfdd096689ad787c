"""The walls around each cell: the micro feedback's cue (docs/model.md, fibre-reinforced walls).

A cell's cue averages the wall stress (or elastic strain) over every wall segment of its mid-line
hexagon, both halves of each shared wall, each half with its own cell's wall tensor; a wall on
the tissue's edge has only the cell's own half. Each wall triangle belongs to one cell c and to
the side k of c's hexagon nearest to it (:mod:`plantgrowth.models.micro.director`), sides
running from vertex k to vertex k + 1 (A B, B C, ..., F A). The wall on side k of c is shared
with the cell d across it, whose half lies on d's opposite side k + 3 (mod 6). With ``I(c, k)``
the integral over c's triangles on side k, summed over every rank:

    around(c) = sum_k I(c, k) + sum_{k: d = n(c, k) exists} I(d, k + 3)

one sparse (n_cells, 6 n_cells) map applied to the gathered per-side integrals.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI

from plantgrowth.meshes.tissue import TissueLayout

SIDES = 6


def neighbours(layout: TissueLayout) -> np.ndarray:
    """(n_cells, 6) the cell across each side k of each cell's hexagon, -1 at the tissue's edge
    (and below a cut bottom cell). The hexagon is centrally symmetric, so the cell across side k
    has its centre at twice the side's midpoint from the cell's centre (a lattice vector).
    Centres are matched on the integer grid ``(x1 / (c delta_s), x2 / ((l1 + s) delta_s))``,
    on which every cell centre lies (plantgrowth.meshes.tissue.TissueLayout.centres)."""
    vertices = layout.cell.hexagon()
    across = layout.delta_s * (vertices + np.roll(vertices, -1, axis=0))
    centres = layout.centres
    scale = layout.delta_s * np.array([layout.cell.c, layout.cell.l1 + layout.cell.s])

    def grid(x: np.ndarray) -> list[tuple[int, int]]:
        return [tuple(k) for k in np.rint(x.reshape(-1, 2) / scale).astype(np.int64).tolist()]

    ids = {k: i for i, k in enumerate(grid(centres))}
    found = grid(centres[:, None, :] + across[None])
    return np.array([ids.get(k, -1) for k in found]).reshape(-1, SIDES)


def around_map(neighbour: np.ndarray) -> sp.csr_matrix:
    """(n_cells, 6 n_cells) the 0/1 map from per-(cell, side) integrals, flattened as
    ``6 cell + side``, to the sums around each cell (module docstring)."""
    n = len(neighbour)
    cells, sides = np.divmod(np.arange(n * SIDES), SIDES)
    d = neighbour.reshape(-1)
    shared = d >= 0
    rows = np.concatenate([cells, cells[shared]])
    columns = np.concatenate([cells * SIDES + sides, d[shared] * SIDES + (sides[shared] + 3) % 6])
    return sp.csr_matrix((np.ones(len(rows)), (rows, columns)), shape=(n, n * SIDES))


class WallsAround:
    """Means over the walls around each cell from per-triangle integrals.

    Args:
        layout: the micro tissue.
        cell_id: (n_owned,) the biological cell of each owned wall triangle.
        side: (n_owned,) the side of its cell's hexagon each owned triangle belongs to.
        areas: (n_owned,) the owned triangles' areas.
        comm: the mesh's communicator.
    """

    def __init__(
        self, layout: TissueLayout, cell_id: np.ndarray, side: np.ndarray, areas: np.ndarray,
        comm: MPI.Comm,
    ) -> None:  # fmt: skip
        self._index = cell_id * SIDES + side
        self._n = layout.n_cells * SIDES
        self._comm = comm
        self._map = around_map(neighbours(layout))
        self.area = self.sums(areas.reshape(-1, 1))[:, 0]
        """(n_cells,) the area of the walls around each cell."""

    def per_side(self, rows: np.ndarray) -> np.ndarray:
        """Collective: (n_cells * 6, m) the integrals ``I(c, k)`` from this rank's per-triangle
        integrals ``rows`` (n_owned, m), summed over all ranks."""
        local = np.stack(
            [np.bincount(self._index, rows[:, j], self._n) for j in range(rows.shape[1])], axis=1
        )
        return self._comm.allreduce(local, op=MPI.SUM)

    def sums(self, rows: np.ndarray) -> np.ndarray:
        """Collective: (n_cells, m) the integrals over the walls around each cell."""
        return self._map @ self.per_side(rows)

    def means(self, rows: np.ndarray) -> np.ndarray:
        """Collective: (n_cells, m) the means over the walls around each cell."""
        return self.sums(rows) / self.area[:, None]
