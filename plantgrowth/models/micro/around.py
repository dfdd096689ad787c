"""The walls around each cell: the micro feedback's cue (docs/model.md, fibre-reinforced walls).

A cell's cue averages the wall stress (or elastic strain) over every wall segment of its mid-line
polygon, both halves of each shared wall, each half with its own cell's wall tensor; a wall on
the tissue's edge has only the cell's own half. Each wall triangle belongs to one cell c and to
the side k of c's whole outline nearest to it (:mod:`plantgrowth.models.micro.director`), sides
running from vertex k to vertex k + 1. The wall on side k of c is shared with the cell
d = n(c, k) across it, whose half lies on d's side o(c, k) (the honeycomb's: k + 3 mod 6). With
``I(c, k)`` the integral over c's triangles on side k, summed over every rank:

    around(c) = sum_k I(c, k) + sum_{k: d = n(c, k) exists} I(d, o(c, k))

one sparse (n_cells, S n_cells) map applied to the gathered per-side integrals (S: the most
sides of any cell's outline).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI

from plantgrowth.meshes.cell_tissue import CellTissue, as_tissue
from plantgrowth.meshes.tissue import TissueLayout
from plantgrowth.models.micro.director import nearest_sides, padded_outlines


def side_pairs(source: CellTissue | TissueLayout) -> tuple[np.ndarray, np.ndarray]:
    """(n_cells, S) the cell n(c, k) across each side k of each cell's outline, -1 at the
    tissue's edge (and below a cut cell), and (n_cells, S) the side o(c, k) of n(c, k) that is
    the same wall (-1 where none). A shared side of two cells' polygons lies on the outline side
    of each that is nearest to its midpoint."""
    tissue = as_tissue(source)
    outlines, counts = padded_outlines(tissue)
    shared = [(a, b, c) for (a, b), c in tissue.cells.sides().items() if len(c) == 2]
    neighbour = np.full(outlines.shape[:2], -1, dtype=np.int64)
    opposite = np.full(outlines.shape[:2], -1, dtype=np.int64)
    if shared:
        vertices = tissue.cells.vertices
        ends = np.array([(a, b) for a, b, _ in shared])
        midpoints = 0.5 * (vertices[ends[:, 0]] + vertices[ends[:, 1]])
        cells = np.array([c for _, _, c in shared])
        k = [nearest_sides(outlines[cells[:, j]], counts[cells[:, j]], midpoints) for j in (0, 1)]
        neighbour[cells[:, 0], k[0]], opposite[cells[:, 0], k[0]] = cells[:, 1], k[1]
        neighbour[cells[:, 1], k[1]], opposite[cells[:, 1], k[1]] = cells[:, 0], k[0]
    return neighbour, opposite


def neighbours(source: CellTissue | TissueLayout) -> np.ndarray:
    """(n_cells, S) the cell across each side of each cell's outline (:func:`side_pairs`)."""
    return side_pairs(source)[0]


def around_map(neighbour: np.ndarray, opposite: np.ndarray) -> sp.csr_matrix:
    """(n_cells, S n_cells) the 0/1 map from per-(cell, side) integrals, flattened as
    ``S cell + side``, to the sums around each cell (module docstring)."""
    n, sides_per_cell = neighbour.shape
    cells, sides = np.divmod(np.arange(n * sides_per_cell), sides_per_cell)
    d, o = neighbour.reshape(-1), opposite.reshape(-1)
    shared = d >= 0
    rows = np.concatenate([cells, cells[shared]])
    columns = np.concatenate(
        [cells * sides_per_cell + sides, d[shared] * sides_per_cell + o[shared]]
    )
    return sp.csr_matrix((np.ones(len(rows)), (rows, columns)), shape=(n, n * sides_per_cell))


class WallsAround:
    """Means over the walls around each cell from per-triangle integrals.

    Args:
        tissue: the micro tissue.
        cell_id: (n_owned,) the biological cell of each owned wall triangle.
        side: (n_owned,) the side of its cell's outline each owned triangle belongs to.
        areas: (n_owned,) the owned triangles' areas.
        comm: the mesh's communicator.
    """

    def __init__(
        self, tissue: CellTissue, cell_id: np.ndarray, side: np.ndarray, areas: np.ndarray,
        comm: MPI.Comm,
    ) -> None:  # fmt: skip
        neighbour, opposite = side_pairs(tissue)
        self._index = cell_id * neighbour.shape[1] + side
        self._n = neighbour.size
        self._comm = comm
        self._map = around_map(neighbour, opposite)
        self.area = self.sums(areas.reshape(-1, 1))[:, 0]
        """(n_cells,) the area of the walls around each cell."""

    def per_side(self, rows: np.ndarray) -> np.ndarray:
        """Collective: (n_cells * S, m) the integrals ``I(c, k)`` from this rank's per-triangle
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
