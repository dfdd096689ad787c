"""Each rank's contiguous block of a mesh's canonical node and cell order, and the exchange that
moves the rank's owned values there: what a collective HDF5 write needs (issue 23, item 2).

The canonical order is :mod:`plantgrowth.base.gather`'s (nodes sorted by their coordinates,
cells by their sorted node numbers), so a file written this way holds the same arrays whatever
the number of ranks. Rank r holds rows ``[offsets[r], offsets[r + 1])`` with
``offsets[r] = min(r ceil(n / size), n)``: blocks of equal length but the last, so that each is
one chunk of a compressed dataset (:mod:`plantgrowth.runner.h5_blocks`). One MPI Alltoallv per
field moves each owned row from the rank that computed it to the rank whose block holds it:
every rank sends and receives about n / size rows, and no rank receives them all.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from plantgrowth.base.gather import MeshGather


@dataclass(frozen=True)
class Block:
    """This rank's rows ``[start, start + len(values))`` of a global array of ``total`` rows."""

    values: np.ndarray
    start: int
    total: int

    @classmethod
    def whole(cls, values: np.ndarray, comm: MPI.Comm, root: int = 0) -> Block:
        """An array every rank holds whole, written by ``root`` alone."""
        rows = values if comm.rank == root else values[:0]
        return cls(rows, 0, len(values))

    @classmethod
    def split(cls, values: np.ndarray, comm: MPI.Comm) -> Block:
        """An array every rank holds whole, cut into the ranks' blocks."""
        offsets = block_offsets(len(values), comm.size)
        start, stop = offsets[comm.rank], offsets[comm.rank + 1]
        return cls(values[start:stop], int(start), len(values))


def block_offsets(n: int, size: int) -> np.ndarray:
    """The first row of every rank's block, and n: ``min(r ceil(n / size), n)``, r = 0..size."""
    return np.minimum(np.arange(size + 1, dtype=np.int64) * -(-n // size), n)


class _Exchange:
    """Moves the owned rows, whose canonical positions are ``positions``, to the blocks."""

    def __init__(self, positions: np.ndarray, total: int, comm: MPI.Comm) -> None:
        self.comm, self.total = comm, total
        self.offsets = block_offsets(total, comm.size)
        destination = np.searchsorted(self.offsets, positions, side="right") - 1
        self.order = np.argsort(destination, kind="stable")
        self.send = np.bincount(destination, minlength=comm.size).astype(np.int64)
        self.receive = np.empty_like(self.send)
        comm.Alltoall(self.send, self.receive)
        start = self.offsets[comm.rank]
        self.place = self._move(positions.astype(np.int64).reshape(-1, 1))[:, 0] - start

    def _move(self, rows: np.ndarray, pick: np.ndarray | None = None) -> np.ndarray:
        """Alltoallv of the rows ``rows[pick]`` (default: all), sent in :attr:`order`;
        received in rank order."""
        width = rows.shape[1]
        send = np.ascontiguousarray(rows[self.order if pick is None else pick[self.order]])
        received = np.empty((int(self.receive.sum()), width), dtype=rows.dtype)
        counts_out, counts_in = self.send * width, self.receive * width
        displs_out = np.concatenate([[0], np.cumsum(counts_out)[:-1]])
        displs_in = np.concatenate([[0], np.cumsum(counts_in)[:-1]])
        self.comm.Alltoallv([send, (counts_out, displs_out)], [received, (counts_in, displs_in)])
        return received

    def __call__(self, rows: np.ndarray, pick: np.ndarray | None = None) -> Block:
        """This rank's block of the global array whose owned rows are ``rows`` (n_owned, k),
        or ``rows[pick]`` (taken in the one gather that sends them)."""
        rows = np.asarray(rows, dtype=np.float64)
        flat = rows.reshape(len(rows), -1)
        received = self._move(flat, pick)
        block = np.empty_like(received)
        block[self.place] = received
        start = int(self.offsets[self.comm.rank])
        return Block(block.reshape(-1, *rows.shape[1:]), start, self.total)


class CanonicalBlocks:
    """P1 (node) and DG0 (cell) values of a triangle mesh, moved to the ranks' blocks of the
    canonical order; the mesh itself (canonical points and triangles) on every rank.

    Args:
        V1: a P1 vector function space on the mesh.
    """

    def __init__(self, V1: fem.FunctionSpace) -> None:
        everywhere = MeshGather(V1, root=None)
        self.comm: MPI.Comm = V1.mesh.comm
        self.n_owned_cells = everywhere.n_owned_cells
        self.points = everywhere.points()
        self.triangles = everywhere.triangles()
        self.nodes = _Exchange(everywhere.node_positions(), everywhere.n_nodes, self.comm)
        self.cells = _Exchange(everywhere.cell_positions(), everywhere.n_cells, self.comm)

    def function(self, u: fem.Function) -> Block:
        """This rank's block of a P1 (nodes) or DG0 (cells) function, (rows, block size)."""
        dofmap = u.function_space.dofmap
        values = u.x.array.reshape(-1, dofmap.index_map_bs)
        if u.function_space.ufl_element().degree() == 0:
            return self.cells(values, dofmap.list.array[: self.n_owned_cells])
        return self.nodes(values[: len(self.nodes.order)])


def root_blocks(arrays: dict[str, np.ndarray], comm: MPI.Comm, root: int = 0) -> dict[str, Block]:
    """Arrays that ``root`` alone holds (the other ranks pass {}) as blocks on every rank:
    ``root`` writes them whole."""
    shapes = comm.bcast({k: (v.shape, v.dtype) for k, v in arrays.items()}, root=root)
    return {
        k: Block(arrays[k], 0, shape[0]) if comm.rank == root
        else Block(np.empty((0, *shape[1:]), dtype), 0, shape[0])
        for k, (shape, dtype) in shapes.items()
    }  # fmt: skip
