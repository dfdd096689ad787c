"""Collect distributed P1 / DG0 data into global arrays (for output and comparisons).

The global numbering is canonical, independent of how the mesh is partitioned: nodes sorted by
their coordinates, cells by their sorted node numbers. Serial and parallel runs, and a run
resumed on a different partition, therefore write identical arrays.
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem
from mpi4py import MPI


class MeshGather:
    """Global node/cell numbering of a triangle mesh through a P1 vector space.

    Args:
        V1: a P1 vector function space on the mesh.
        root: the rank that receives the data, or None for all ranks.
    """

    def __init__(self, V1: fem.FunctionSpace, root: int | None = 0) -> None:
        self.V1 = V1
        self.comm: MPI.Comm = V1.mesh.comm
        self.root = root
        imap = V1.dofmap.index_map
        self.n_owned_nodes = imap.size_local
        self.n_nodes = imap.size_global
        local = np.arange(imap.size_local + imap.num_ghosts, dtype=np.int32)
        self.global_index = imap.local_to_global(local)
        self.n_owned_cells = V1.mesh.topology.index_map(2).size_local
        self.n_cells = V1.mesh.topology.index_map(2).size_global
        self._node_owner = self._collect(self.global_index[: self.n_owned_nodes])
        # canonical order: computed where the data are received
        coords = self._raw_nodes(V1.tabulate_dof_coordinates()[:, :2])
        cells = V1.dofmap.list.array.reshape(-1, 3)[: self.n_owned_cells]
        triangles = self._collect(self.global_index[cells])
        self._node_order = self._cell_order = self._renumber = None
        if self._receives():
            # dof coordinates carry partition-dependent round-off: sort on rounded values
            key = np.round(coords / (1e-9 * max(np.abs(coords).max(), 1e-300)))
            self._node_order = np.lexsort((key[:, 1], key[:, 0]))
            self._renumber = np.empty_like(self._node_order)
            self._renumber[self._node_order] = np.arange(len(self._node_order))
            renumbered = np.sort(self._renumber[np.concatenate(triangles)], axis=1)
            self._cell_order = np.lexsort(renumbered.T[::-1])
            self._triangles = self._renumber[np.concatenate(triangles)][self._cell_order]

    def node_positions(self) -> np.ndarray:
        """Canonical numbers of this rank's owned nodes (with ``root=None`` only)."""
        return self._renumber[self.global_index[: self.n_owned_nodes]]

    def cell_positions(self) -> np.ndarray:
        """Canonical numbers of this rank's owned cells (with ``root=None`` only)."""
        counts = self.comm.allgather(self.n_owned_cells)
        first = sum(counts[: self.comm.rank])
        position = np.empty_like(self._cell_order)
        position[self._cell_order] = np.arange(len(self._cell_order))
        return position[first : first + self.n_owned_cells]

    def _collect(self, values: np.ndarray):
        if self.root is None:
            return self.comm.allgather(values)
        return self.comm.gather(values, root=self.root)

    def _receives(self) -> bool:
        return self.root is None or self.comm.rank == self.root

    def _raw_nodes(self, local: np.ndarray) -> np.ndarray | None:
        """Per-node values in global dof order."""
        parts = self._collect(np.asarray(local)[: self.n_owned_nodes])
        if not self._receives():
            return None
        out = np.zeros((self.n_nodes, *parts[0].shape[1:]))
        for index, part in zip(self._node_owner, parts, strict=True):
            out[index] = part
        return out

    def node_values(self, local: np.ndarray) -> np.ndarray | None:
        """Global (n_nodes, k) array, canonical order, from per-local-node values."""
        out = self._raw_nodes(local)
        return None if out is None else out[self._node_order]

    def cell_values(self, local: np.ndarray) -> np.ndarray | None:
        """Global (n_cells, k) array, canonical order, from per-local-cell values."""
        parts = self._collect(np.asarray(local)[: self.n_owned_cells])
        return np.concatenate(parts)[self._cell_order] if self._receives() else None

    def points(self) -> np.ndarray | None:
        """(n_nodes, 2) node coordinates."""
        return self.node_values(self.V1.tabulate_dof_coordinates()[:, :2])

    def triangles(self) -> np.ndarray | None:
        """(n_cells, 3) node numbers of the cells (canonical numbering)."""
        return self._triangles if self._receives() else None

    def function(self, u: fem.Function) -> np.ndarray | None:
        """Global values of a P1 (nodes) or DG0 (cells) function, shape (n, block size)."""
        dofmap = u.function_space.dofmap
        values = u.x.array.reshape(-1, dofmap.index_map_bs)
        if u.function_space.ufl_element().degree() == 0:
            return self.cell_values(values[dofmap.list.array[: self.n_owned_cells]])
        return self.node_values(values)


def dof_state(functions: list[fem.Function], root: int = 0) -> dict[str, np.ndarray]:
    """The owned nodal values of blocked Lagrange functions (any degree, one space) and their
    points, on ``root`` ({} elsewhere) in a canonical order (points sorted), for a float64
    resume state: key ``dof_points`` and one key per function name."""
    V = functions[0].function_space
    n, bs = V.dofmap.index_map.size_local, V.dofmap.index_map_bs
    local = [V.tabulate_dof_coordinates()[:n, :2]]
    local += [f.x.array[: n * bs].reshape(n, bs) for f in functions]
    parts = V.mesh.comm.gather(local, root)
    if parts is None:
        return {}
    points, *values = (np.concatenate(arrays) for arrays in zip(*parts, strict=True))
    key = np.round(points / (1e-9 * max(np.abs(points).max(), 1e-300)))
    order = np.lexsort((key[:, 1], key[:, 0]))
    names = [f.name for f in functions]
    return {"dof_points": points[order]} | {k: v[order] for k, v in zip(names, values, strict=True)}


def restore_dofs(
    functions: list[fem.Function], state: dict[str, np.ndarray], tolerance: float
) -> bool:
    """Set the functions (all local nodes, ghosts included) from :func:`dof_state`'s arrays,
    matched by point; False (nothing set) when an array is missing or some node is farther
    than ``tolerance`` from every saved point on some rank."""
    from scipy.spatial import cKDTree  # here: only a resume matches points (0.05-0.1 s import)

    V = functions[0].function_space
    if "dof_points" not in state or any(f.name not in state for f in functions):
        return False
    distance, index = cKDTree(state["dof_points"]).query(V.tabulate_dof_coordinates()[:, :2])
    ok = V.mesh.comm.allreduce(bool(np.max(distance, initial=0.0) <= tolerance), op=MPI.LAND)
    if ok:
        for f in functions:
            f.x.array[:] = state[f.name][index].reshape(-1)
            f.x.scatter_forward()
    return ok
