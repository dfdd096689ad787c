"""Cell problems at the coarse nodes, solved once per distinct input (paper Algorithm 3).

Inputs are reduced before solving, by exact invariances of the cell problems (MODEL.md 3):
- ``Fg -> Fg / sqrt(det Fg)``: scaling Fg by g scales the cell solutions by g and leaves every
  homogenized quantity unchanged;
- ``E -> 1``: E_hom scales with E, dbar[v] with 1/E; K_hom, dbar[w^ij] do not depend on E.
The reduced inputs are rounded to ``key_tolerance``; each distinct key is solved once per run
(results are cached across time steps). Keys are shared round-robin among the ranks, each solving
on ``COMM_SELF``, and the results are exchanged with one ``allgather``.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from plantgrowth.cell_solver import CellResult, CellSolver
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.tensors import voigt_matrix

log = logging.getLogger("plantgrowth")


@dataclass(frozen=True)
class NodeTensors:
    """Homogenized fields at the coarse nodes (n nodes). Absent pieces are None."""

    C: np.ndarray  # (n, 3, 3) Voigt matrix of E_hom
    phi_w: np.ndarray  # (n,)
    K: np.ndarray | None  # (n, 2, 2)
    dbar_w: np.ndarray | None  # (n, 2, 2, 2, 2)
    dbar_v: np.ndarray | None  # (n, 2, 2)
    P2_matrix: np.ndarray  # (n, 2, 2), P2vec = P2_matrix grad(P1)


def _pack(result: CellResult) -> np.ndarray:
    parts = [voigt_matrix(result.E_hom).ravel(), [result.phi_w], result.P2_matrix.ravel()]
    for optional in (result.K_hom, result.dbar_w, result.dbar_v):
        if optional is not None:
            parts.append(optional.ravel())
    return np.concatenate(parts)


class Homogenizer:
    """Solves and caches the cell problems of a run.

    Args:
        resolution: elements across a wall in each cell mesh.
        key_tolerance: absolute rounding of the reduced inputs (geometry, nu, Fg/sqrt(det Fg)).
        pressure: solve the pressure problem [UCw_weak] (only when P1 is not zero).
        strain_averages: compute dbar[w^ij], dbar[v] (strain law or eps_hom output only).
        comm: the communicator whose ranks share the cell problems.
    """

    def __init__(
        self,
        resolution: int,
        key_tolerance: float,
        pressure: bool,
        strain_averages: bool,
        comm: MPI.Comm,
    ) -> None:
        self.resolution = resolution
        self.tol = key_tolerance
        self.pressure = pressure
        self.strain_averages = strain_averages
        self.comm = comm
        self._solvers: dict[tuple, CellSolver] = {}
        self._results: dict[tuple, np.ndarray] = {}
        self.solves_last_call = 0
        self.seconds_last_call = 0.0

    def _key(self, geometry: np.ndarray, nu: float, Fg: np.ndarray) -> tuple:
        reduced = np.concatenate([geometry, [nu], (Fg / np.sqrt(np.linalg.det(Fg))).ravel()])
        return tuple(int(k) for k in np.round(reduced / self.tol))

    def _solve(self, key: tuple) -> np.ndarray:
        values = np.array(key, dtype=float) * self.tol
        geometry, nu, Fg = tuple(values[:4]), values[4], values[5:].reshape(2, 2)
        solver = self._solvers.get(geometry)
        if solver is None:
            solver = CellSolver(HoneycombCell(*geometry), self.resolution, MPI.COMM_SELF)
            self._solvers[geometry] = solver
        result = solver.solve(Fg, 1.0, nu, self.pressure, self.strain_averages)
        return _pack(result)

    def homogenize(
        self, geometry: np.ndarray, E: np.ndarray, nu: np.ndarray, Fg: np.ndarray
    ) -> NodeTensors:
        """Homogenized tensors at n nodes.

        Args:
            geometry: (n, 4) cell parameters (l1, l2, theta in degrees, w) per node.
            E, nu: (n,) wall moduli per node.
            Fg: (n, 2, 2) growth tensors per node.
        """
        start = time.perf_counter()
        keys = [self._key(g, v, F) for g, v, F in zip(geometry, nu, Fg, strict=True)]
        new = sorted(set(keys) - self._results.keys())
        mine = {k: self._solve(k) for k in new[self.comm.rank :: self.comm.size]}
        for part in self.comm.allgather(mine):
            self._results.update(part)
        self.solves_last_call = len(new)
        self.seconds_last_call = time.perf_counter() - start

        packed = np.array([self._results[k] for k in keys])
        n = len(keys)
        C = packed[:, :9].reshape(n, 3, 3) * E[:, None, None]
        phi_w = packed[:, 9]
        P2_matrix = packed[:, 10:14].reshape(n, 2, 2)
        offset = 14
        K = dbar_w = dbar_v = None
        if self.pressure:
            K = packed[:, offset : offset + 4].reshape(n, 2, 2)
            offset += 4
        if self.strain_averages:
            dbar_w = packed[:, offset : offset + 16].reshape(n, 2, 2, 2, 2)
            offset += 16
            if self.pressure:
                dbar_v = packed[:, offset : offset + 4].reshape(n, 2, 2) / E[:, None, None]
        return NodeTensors(C, phi_w, K, dbar_w, dbar_v, P2_matrix)
