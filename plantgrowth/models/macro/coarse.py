"""The coarse mesh M of the coupled algorithm (docs/model.md section 5): cell problems live
at its nodes.

A structured triangulation of the tissue's bounding box [0, width] x [0, height] (each rectangle
split along the diagonal from its lower-right to its upper-left corner). It is small and
replicated on every rank; fine mesh data meet it through P1 interpolation weights (coarse ->
fine) and their transpose, a lumped L2 projection (fine -> coarse), both plain sparse matrices.
On a tissue that does not fill the box, only the :func:`active_nodes` take part (a node outside
the tissue weighs no fine cell, so no cell problem is solved there).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI


@dataclass(frozen=True)
class CoarseGrid:
    """Nodes ``(i dX, j dY)``, i = 0..nx, j = 0..ny, numbered ``j (nx + 1) + i``."""

    width: float
    height: float
    nx: int
    ny: int

    @classmethod
    def with_edge(cls, width: float, height: float, H: float) -> CoarseGrid:
        """The grid whose edges are closest to H (at least one cell each way)."""
        return cls(width, height, max(1, round(width / H)), max(1, round(height / H)))

    @property
    def nodes(self) -> np.ndarray:
        """(n_nodes, 2) node coordinates."""
        x = np.linspace(0.0, self.width, self.nx + 1)
        y = np.linspace(0.0, self.height, self.ny + 1)
        X, Y = np.meshgrid(x, y)
        return np.column_stack([X.ravel(), Y.ravel()])

    def _corners(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, ...]:
        """Node numbers (00, 10, 01, 11) of the rectangles (i, j)."""
        n00 = j * (self.nx + 1) + i
        return n00, n00 + 1, n00 + self.nx + 1, n00 + self.nx + 2

    @property
    def triangles(self) -> np.ndarray:
        """(2 nx ny, 3) counter-clockwise triangles: each rectangle's lower (00, 10, 01) and
        upper (11, 01, 10) triangle, the split :meth:`interpolation_matrix` uses."""
        i, j = np.meshgrid(np.arange(self.nx), np.arange(self.ny))
        n00, n10, n01, n11 = self._corners(i.ravel(), j.ravel())
        lower, upper = np.column_stack([n00, n10, n01]), np.column_stack([n11, n01, n10])
        return np.stack([lower, upper], axis=1).reshape(-1, 3)

    def interpolation_matrix(self, points: np.ndarray) -> sp.csr_matrix:
        """W with ``f(points) = W f(nodes)`` for the P1 interpolant on the coarse triangles.

        Points outside the rectangle are clamped onto it (round-off at the boundary).
        """
        dX, dY = self.width / self.nx, self.height / self.ny
        xi = np.clip(points[:, 0] / dX, 0.0, self.nx)
        eta = np.clip(points[:, 1] / dY, 0.0, self.ny)
        i = np.minimum(np.floor(xi).astype(int), self.nx - 1)
        j = np.minimum(np.floor(eta).astype(int), self.ny - 1)
        a, b = xi - i, eta - j
        n00, n10, n01, n11 = self._corners(i, j)
        lower = a + b <= 1.0
        # lower triangle (00, 10, 01); upper triangle (11, 01, 10)
        cols = np.where(lower, [n00, n10, n01], [n11, n01, n10]).T
        weights = np.where(lower, [1 - a - b, a, b], [a + b - 1, 1 - a, 1 - b]).T
        rows = np.repeat(np.arange(len(points)), 3)
        n_nodes = (self.nx + 1) * (self.ny + 1)
        return sp.csr_matrix((weights.ravel(), (rows, cols.ravel())), shape=(len(points), n_nodes))


def active_nodes(W: sp.csr_matrix, comm: MPI.Comm) -> np.ndarray:
    """Coarse nodes with a non-zero interpolation weight at some fine cell midpoint of some rank
    (a boolean mask). Every fine value is interpolated from these nodes alone, so the cell
    problems of the others are never used."""
    local = (np.asarray(abs(W).sum(axis=0)).ravel() > 0.0).astype(np.int64)
    return comm.allreduce(local, op=MPI.SUM) > 0


def coarse_grid_for(
    width: float, height: float, H: float, midpoints: np.ndarray, comm: MPI.Comm
) -> tuple[CoarseGrid, sp.csr_matrix, np.ndarray]:
    """Collective: the coarse grid of edge about H on the box [0, width] x [0, height], its P1
    weights at this rank's fine-cell ``midpoints`` (n, 2) and the :func:`active_nodes` mask."""
    grid = CoarseGrid.with_edge(width, height, H)
    W = grid.interpolation_matrix(midpoints)
    return grid, W, active_nodes(W, comm)


class NodeProjection:
    """Lumped L2 projection of cell values onto coarse nodes (paper Algorithm 1, last step).

    ``F_n = sum_c W_cn |c| F_c / sum_c W_cn |c|`` over the owned fine cells of all ranks; a node
    with no fine cell in its support (its value is never interpolated back) gets the mean.
    W's transpose and the nodes' mass ``sum_c W_cn |c|`` are made once (collective).
    Args:
        W: interpolation weights at the owned fine cells' midpoints.
        areas: owned fine cells' areas.
    """

    def __init__(self, W: sp.csr_matrix, areas: np.ndarray, comm: MPI.Comm) -> None:
        self.Wt, self.areas, self.comm = W.T, areas, comm
        self.mass = comm.allreduce(self.Wt @ areas, op=MPI.SUM)

    def __call__(self, values: np.ndarray) -> np.ndarray:
        """Collective: (n_nodes, k) node values of (n_cells, k) values per owned cell."""
        weighted = self.comm.allreduce(self.Wt @ (self.areas[:, None] * values), op=MPI.SUM)
        # a node whose triangles hold no fine cell midpoint (outside a non-rectangular tissue,
        # or a fine mesh coarser than the coarse one) weighs no fine cell: the tissue mean
        mass = self.mass
        empty = mass <= 0.0
        mean = weighted.sum(axis=0) / mass.sum()
        return np.where(empty[:, None], mean, weighted / np.where(empty, 1.0, mass)[:, None])


def project_to_nodes(
    W: sp.csr_matrix, areas: np.ndarray, values: np.ndarray, comm: MPI.Comm
) -> np.ndarray:
    """Collective: :class:`NodeProjection` of ``values`` (n_cells, k) made once."""
    return NodeProjection(W, areas, comm)(values)
