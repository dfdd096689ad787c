"""Cell problems at the coarse nodes or fine cells, solved once per distinct input (paper
Algorithm 3).

Inputs are reduced before solving, by exact invariances of the cell problems
(docs/model.md section 3):
- ``Fg -> Fg / sqrt(det Fg)``: scaling Fg by g scales the cell solutions by g and leaves every
  homogenized quantity unchanged;
- ``E -> 1``: E_hom scales with E, dbar[v] with 1/E; K_hom, dbar[w^ij] do not depend on E
  (fibred walls too: E_f = fibre_stiffness * E scales with E);
- fibre-reinforced walls (docs/model.md, "Fibre-reinforced walls"): the director angle a
  modulo 180 degrees (m and -m are one director); fibre_stiffness = 0 adds nothing to the key,
  so isotropic cells keep their keys (and their on-disk cache).
The reduced inputs are rounded to ``key_tolerance``; each distinct key is solved once per run
(results are cached across time steps). Keys are shared among the ranks by estimated cost
(:mod:`plantgrowth.unitcell.scheduler`), each solving on ``COMM_SELF``, and the results are
exchanged with one ``allgather``.

With ``cell_tolerance > 0`` the growth state goes through :mod:`plantgrowth.unitcell.surrogate`
instead (rotation split off exactly, the stretch interpolated on lattices refined to the
tolerance; a fibred table is one (geometry, nu, fibre_stiffness) and node of the angle
a - rotation angle, interpolated trigonometrically over its nodes
(:mod:`plantgrowth.unitcell.director_lattice`):
the cell problem for (R U, m) is the one for (U, R^T m) rotated by R),
backed by the on-disk cache of :mod:`plantgrowth.unitcell.cache`; every ``CHECK_EVERY``-th call
also solves one of its queries exactly and logs the surrogate's error there. A lookup costs
microseconds, so each fine cell can ask with its own Fg and E; only the cell geometry and nu,
which pick the lattice (the table), stay sampled at the coarse nodes (P1 weights).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI

from plantgrowth.base.tensors import (
    rotate_symmetric2,
    rotate_symmetric4,
    rotate_voigt,
    voigt_matrix,
    voigt_rotation,
)
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.unitcell import director_lattice, surrogate
from plantgrowth.unitcell.cache import CellCache, cache_root
from plantgrowth.unitcell.scheduler import CellScheduler
from plantgrowth.unitcell.solver import CellResult, CellSolver

log = logging.getLogger("plantgrowth")

CHECK_EVERY = 10
"""The surrogate is checked against an exact solve at one random node every this many calls."""
CHECK_LINE = "accuracy check of the interpolated cell tensors"
"""How run.log names each such check (followed by its number)."""


@dataclass(frozen=True)
class NodeTensors:
    """Homogenized fields at n points (coarse nodes or fine cells). Absent pieces are None."""

    C: np.ndarray  # (n, 3, 3) Voigt matrix of E_hom
    phi_w: np.ndarray  # (n,)
    K: np.ndarray | None  # (n, 2, 2)
    dbar_w: np.ndarray | None  # (n, 2, 2, 2, 2)
    dbar_v: np.ndarray | None  # (n, 2, 2)
    P2_matrix: np.ndarray  # (n, 2, 2), P2vec = P2_matrix grad(P1)


@dataclass(frozen=True)
class QueryLayout:
    """Which tables a rank's points ask the surrogate: query k asks ``tables[which[k]]`` for
    point ``point[k]``; ``combine`` (points x queries) weighs the answers into the points'
    values. ``weights`` and ``node`` are what it was made from."""

    weights: object
    node: np.ndarray
    tables: list[tuple]
    which: np.ndarray
    point: np.ndarray
    combine: sp.csr_matrix


def _mesh_group(key: tuple) -> tuple:
    """The solver (mesh) a rounded key or table is solved on: its geometry, and whether its walls
    are fibred (keys longer than 9 entries, tables longer than 5)."""
    fibred = len(key) in (7, 11)
    return key[:4] + (("fibres",) if fibred else ())


def _pack(result: CellResult) -> np.ndarray:
    parts = [voigt_matrix(result.E_hom).ravel(), [result.phi_w], result.P2_matrix.ravel()]
    for optional in (result.K_hom, result.dbar_w, result.dbar_v):
        if optional is not None:
            parts.append(optional.ravel())
    return np.concatenate(parts)


def water_errors(tensors: NodeTensors) -> tuple[float, float]:
    """Relative errors of the first of two points' ``b = (1 - phi_w) I - K_hom`` (Frobenius) and
    ``1/M = -tr dbar[v]`` against the second's (docs/model.md, "The unit cell's coefficients")."""
    b = (1.0 - tensors.phi_w)[:, None, None] * np.eye(2) - tensors.K
    inv_M = -np.trace(tensors.dbar_v, axis1=1, axis2=2)
    b_error = np.linalg.norm(b[0] - b[1]) / np.linalg.norm(b[1])
    return float(b_error), float(abs(inv_M[0] - inv_M[1]) / abs(inv_M[1]))


class Homogenizer:
    """Solves and caches the cell problems of a run.

    Args:
        resolution: elements across a wall in each cell mesh.
        key_tolerance: absolute rounding of the reduced inputs (geometry, nu, Fg/sqrt(det Fg)).
        pressure: solve the pressure problem [UCw_weak] (only when P1 is not zero).
        strain_averages: compute dbar[w^ij], dbar[v] (strain law or eps_hom output only).
        comm: the communicator whose ranks share the cell problems.
        cell_tolerance: relative error accepted from the surrogate (0: solve every distinct
            rounded input exactly).
        water: the run has water fluxes (pressure and strain_averages are then True): the
            surrogate's accuracy checks also log the errors of b and 1/M (:func:`water_errors`).
        interpolant: the surrogate's, "bilinear" or "c1" (``accuracy.cell_interpolant``).
    """

    def __init__(
        self,
        resolution: int,
        key_tolerance: float,
        pressure: bool,
        strain_averages: bool,
        comm: MPI.Comm,
        cell_tolerance: float = 0.0,
        water: bool = False,
        interpolant: str = "bilinear",
    ) -> None:
        self.resolution = resolution
        self.water = water
        self.tol = key_tolerance
        self.pressure = pressure
        self.strain_averages = strain_averages
        self.comm = comm
        self.scheduler = CellScheduler(comm)
        self._solvers: dict[tuple, CellSolver] = {}
        self._results: dict[tuple, np.ndarray] = {}
        self.solves_last_call = 0
        self.seconds_last_call = 0.0
        self.surrogate = None
        if cell_tolerance > 0.0:
            sizes = [9, 1, 4] + [4] * pressure + [16] * strain_averages
            sizes += [4] * (pressure and strain_averages)
            bounds = np.cumsum([0, *sizes])
            segments = [slice(bounds[0], bounds[1])] + [
                slice(a, b) for a, b in zip(bounds[3:-1], bounds[4:], strict=True)
            ]  # E_hom and the optional pieces; phi_w and P2 depend on the geometry only
            self.surrogate = surrogate.LatticeSurrogate(
                self._solve_stretch, cell_tolerance, segments, comm, self.scheduler, _mesh_group,
                interpolant, voigt=slice(0, 9),
            )
            self.angles = director_lattice.DirectorInterpolant(
                self._evaluate, self.surrogate.relative_difference, cell_tolerance, comm,
                self.surrogate.values,
            )  # fmt: skip
            fingerprint = (resolution, pressure, strain_averages)
            self.cache = CellCache(cache_root(), fingerprint, comm)
            self._loaded: set[tuple] = set()  # tables whose cached lattice is loaded
            self._calls = 0
            self._last_layout: QueryLayout | None = None
            self._rng = np.random.default_rng(0)  # the same draws on every rank
            self.checks = 0
            self.largest_checked_error = 0.0

    def _key(
        self, geometry: np.ndarray, nu: float, Fg: np.ndarray, fibre: tuple = (0.0, 0.0)
    ) -> tuple:
        """Rounded (geometry, nu, Fg / sqrt(det Fg)[, fibre_stiffness, a mod 180])."""
        reduced = np.concatenate([geometry, [nu], (Fg / np.sqrt(np.linalg.det(Fg))).ravel()])
        if round(fibre[0] / self.tol) > 0:
            reduced = np.concatenate([reduced, [fibre[0], fibre[1] % 180.0]])
        return tuple(int(k) for k in np.round(reduced / self.tol))

    def _solve(self, key: tuple) -> np.ndarray:
        values = np.array(key, dtype=float) * self.tol
        fibre = tuple(values[9:11]) if len(key) > 9 else (0.0, 0.0)
        return self._solve_exact(tuple(values[:4]), values[4], values[5:9].reshape(2, 2), fibre)

    def _solve_exact(
        self, geometry: tuple, nu: float, Fg: np.ndarray, fibre: tuple = (0.0, 0.0)
    ) -> np.ndarray:
        """Packed results of one cell problem (E = 1, fibre = (fibre_stiffness, angle)) on this
        rank; fibred and isotropic cells of one geometry have their own meshes."""
        fibred = fibre[0] > 0.0
        solver = self._solvers.get((geometry, fibred))
        if solver is None:
            cell = HoneycombCell(*geometry)
            solver = CellSolver(cell, self.resolution, MPI.COMM_SELF, fibres=fibred)
            self._solvers[geometry, fibred] = solver
        extra = dict(fibre_stiffness=fibre[0], fibre_angle=fibre[1]) if fibred else {}
        return _pack(solver.solve(Fg, 1.0, nu, self.pressure, self.strain_averages, **extra))

    def _solve_stretch(self, table: tuple, U: np.ndarray, angle: float | None = None) -> np.ndarray:
        """A table's cell problem at the stretch U: an isotropic table (geometry, nu), or a
        fibred one (geometry, nu, fibre_stiffness) at its angle-lattice node's angle (its 7th
        entry, :data:`director_lattice.ANGLE_STEP` degrees each) or at ``angle``."""
        values = np.array(table[:6], dtype=float) * self.tol
        fibre = (0.0, 0.0)
        if len(table) > 5:
            node = None if len(table) < 7 else table[6] * director_lattice.ANGLE_STEP
            fibre = (values[5], node if angle is None else angle)
        return self._solve_exact(tuple(values[:4]), values[4], U, fibre)

    def homogenize(
        self,
        geometry: np.ndarray,
        E: np.ndarray,
        nu: np.ndarray,
        Fg: np.ndarray,
        weights: sp.spmatrix | None = None,
        fibres: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> NodeTensors:
        """Homogenized tensors at n points from m sample nodes.

        Args:
            geometry: (m, 4) cell parameters (l1, l2, theta in degrees, w) per node.
            E: (n,) wall moduli per point (the E factor is exact: E_hom ~ E, dbar[v] ~ 1/E).
            nu: (m,) Poisson ratios per node.
            Fg: (n, 2, 2) growth tensors per point.
            weights: None: the points are the nodes (n = m, the same arrays on every rank,
                each rank computing a block of them). Else (surrogate only) this rank's own
                points and the nodes' P1 weights there, (n, m): point p gets
                ``sum_k W_pk T(geometry_k, nu_k; Fg_p) E_p``, each node's table asked at the
                point's own Fg.
            fibres: None (isotropic walls), or fibre-reinforced walls: (fibre_stiffness (m,)
                per node, E_f / E >= 0, like nu; fibre_angle (n,) per point, degrees from x1
                in the grown frame, like Fg).
        """
        start = time.perf_counter()
        if fibres is None:
            fibres = (np.zeros(len(nu)), np.zeros(len(Fg)))
        if weights is not None:
            tensors = self._interpolate(geometry, E, nu, Fg, weights, fibres)
        elif self.surrogate is None:
            points = zip(geometry, nu, Fg, zip(*fibres, strict=True), strict=True)
            keys = [self._key(g, v, F, f) for g, v, F, f in points]
            new = sorted(set(keys) - self._results.keys())
            self._results.update(self.scheduler.solve_all(new, _mesh_group, self._solve))
            self.solves_last_call = len(new)
            packed = np.array([self._results[k] for k in keys])
            tensors = self._unpack(packed, E)
        else:
            n, size, rank = len(Fg), self.comm.size, self.comm.rank
            block = slice(n * rank // size, n * (rank + 1) // size)
            mine = sp.identity(n, format="csr")[block]
            own = (fibres[0], fibres[1][block])
            tensors = self._all_blocks(
                self._interpolate(geometry, E[block], nu, Fg[block], mine, own)
            )
        self.seconds_last_call = time.perf_counter() - start
        return tensors

    def _evaluate(
        self, tables: list[tuple], which: np.ndarray, s: np.ndarray, tolerance: np.ndarray
    ) -> surrogate.Answer:
        """Collective: the stretch surrogate's answers (``tables[which[k]]`` at ``s[k]`` to the
        relative ``tolerance[k]``), the
        tables' lattices first loaded from the cache (every rank loads the tables any rank asks
        for) and the newly solved points saved to it."""
        self._load(tables)
        answer = self.surrogate.evaluate(tables, which, s, tolerance)
        self.cache.save(self.surrogate.take_new_points())
        return answer

    def _load(self, tables: list[tuple]) -> None:
        """Collective: the cached lattice values of the tables any rank names, once a run."""
        wanted = set().union(*self.comm.allgather(set(tables)))
        for table in sorted(wanted - self._loaded):
            self.surrogate.add(self.cache.load(table))
            self._loaded.add(table)

    def end_step(self) -> None:
        """A time step ended (the c1 surrogate's blends advance)."""
        if self.surrogate is not None:
            self.surrogate.end_step()

    def state(self) -> dict[str, np.ndarray]:
        """What a resumed run needs to answer as the uninterrupted one (the surrogate's
        refined squares and angle node counts; the same on every rank), {} without one. Empty
        arrays are left out (parallel HDF5 cannot write an empty dataset)."""
        if self.surrogate is None:
            return {}
        state = {"surrogate_squares": self.surrogate.squares(), "angle_levels": self.angles.state()}
        if self.surrogate.smooth is not None:  # c1: the squares' births and the step count
            state["surrogate_births"] = self.surrogate.births()
        return {name: rows for name, rows in state.items() if len(rows)}

    def restore(self, state: dict[str, np.ndarray]) -> None:
        """Collective: rebuild the surrogate of :meth:`state` (its points from the cache or
        solved anew)."""
        if self.surrogate is None or "surrogate_squares" not in state:
            return
        rows = state["surrogate_squares"]
        self._load([tuple(row[1 : 1 + row[0]]) for row in rows.tolist()])
        self.surrogate.restore(rows)
        # c1; without births (a bilinear run's state) the squares are one birth: no blend
        if self.surrogate.smooth is not None and "surrogate_births" in state:
            self.surrogate.restore_births(state["surrogate_births"])
        self.cache.save(self.surrogate.take_new_points())
        self.angles.restore(state.get("angle_levels", np.zeros((0, 7), dtype=np.int64)))

    def _interpolate(
        self, geometry: np.ndarray, E: np.ndarray, nu: np.ndarray, Fg: np.ndarray, weights,
        fibres: tuple[np.ndarray, np.ndarray],
    ) -> NodeTensors:  # fmt: skip
        """The surrogate's answer at this rank's points: for each point and each table its
        nodes weigh (merged: a table met at several nodes is asked once), the stretch
        interpolated (and, for a fibred table, the director's angle turned back by the rotation,
        interpolated over the angle nodes: :mod:`plantgrowth.unitcell.director_lattice`), then
        combined with the weights, scaled by E and rotated exactly."""
        R, s = surrogate.split_growth(Fg)
        turn = np.degrees(np.arctan2(R[:, 1, 0], R[:, 0, 0]))
        b = (fibres[1] - turn) % 180.0  # the director in the stretch's frame, per point
        layout = self._layout(geometry, nu, fibres[0], weights)
        tables, which, point = layout.tables, layout.which, layout.point
        s_q, b_q = s[point], b[point]
        answer = self.angles(tables, which, s_q, b_q)
        self.solves_last_call = answer.solves + self._check(
            lambda k: self._solve_stretch(tables[which[k]], surrogate.stretch(s_q[k]), b_q[k]),
            s_q, answer,
        )  # fmt: skip
        tensors = self._unpack(layout.combine @ answer.values, E)
        T = voigt_rotation(R)  # K_hom, dbar[v] and dbar[w] are symmetric (minor symmetries)
        rotated = {"C": rotate_voigt(R, tensors.C, T)}
        for name in ("K", "dbar_v"):
            if getattr(tensors, name) is not None:
                rotated[name] = rotate_symmetric2(T, getattr(tensors, name))
        if tensors.dbar_w is not None:
            rotated["dbar_w"] = rotate_symmetric4(T, tensors.dbar_w)
        return replace(tensors, **rotated)

    def _layout(
        self, geometry: np.ndarray, nu: np.ndarray, stiffness: np.ndarray, weights
    ) -> QueryLayout:
        """The tables this rank's points ask (for each point, each table its nodes weigh,
        merged: a table met at several nodes is asked once) and the weights that combine the
        answers; found per node (not per weight entry), and kept while the weights and the
        nodes' parameters stay those of the last call (over a run's steps they do)."""
        node = np.column_stack([geometry, nu, stiffness])
        last = self._last_layout
        if last is not None and last.weights is weights and np.array_equal(last.node, node):
            return last
        n = weights.shape[0]
        W = weights.tocoo()
        used, entry_node = np.unique(W.col, return_inverse=True)
        rows = np.round(node[used] / self.tol).astype(np.int64)
        unique, node_table = np.unique(rows, axis=0, return_inverse=True)
        entry_table = node_table.ravel()[entry_node.ravel()]
        # isotropic tables (fibre_stiffness 0) keep the paper's keys
        tables = [tuple(row[:5]) if row[5] == 0 else tuple(row) for row in unique.tolist()]
        pairs = sp.csr_matrix((W.data, (W.row, entry_table.ravel())), shape=(n, len(tables)))
        pairs.sum_duplicates()
        pairs.eliminate_zeros()
        point = np.repeat(np.arange(n), np.diff(pairs.indptr))
        combine = sp.csr_matrix((pairs.data, (point, np.arange(len(point)))), (n, len(point)))
        self._last_layout = QueryLayout(weights, node, tables, pairs.indices, point, combine)
        return self._last_layout

    def _all_blocks(self, mine: NodeTensors) -> NodeTensors:
        """The tensors of all nodes from every rank's block (in rank order)."""
        blocks = self.comm.allgather(mine)
        names = ("C", "phi_w", "K", "dbar_w", "dbar_v", "P2_matrix")
        joined = [[getattr(b, name) for b in blocks] for name in names]
        return NodeTensors(*(None if p[0] is None else np.concatenate(p) for p in joined))

    def _check(
        self, exact: Callable[[int], np.ndarray], s: np.ndarray, answer: surrogate.Answer
    ) -> int:
        """Every CHECK_EVERY-th call: one random interpolated query (over all ranks' queries;
        this rank's k-th at stretch ``s[k]``, its exact values ``exact(k)``, at its own stretch
        and director angle) solved exactly by the rank that holds it, the error logged. Returns
        the number of exact solves made (the same on every rank)."""
        self._calls += 1
        flags = self.comm.allgather(answer.interpolated)
        candidates = np.flatnonzero(np.concatenate(flags))
        if (self._calls - 1) % CHECK_EVERY or not len(candidates):
            return 0
        k = int(candidates[self._rng.integers(len(candidates))])
        owner = int(np.searchsorted(np.cumsum([len(f) for f in flags]), k, side="right"))
        found = None
        if self.comm.rank == owner:
            local = k - sum(len(f) for f in flags[:owner])
            values = exact(local)
            found = (self.surrogate.relative_difference(answer.values[local], values), s[local])
            if self.water:
                both = self._unpack(np.stack([answer.values[local], values]), np.ones(2))
                found += water_errors(both)
        error, where, *water = self.comm.bcast(found, root=owner)
        self.checks += 1
        self.largest_checked_error = max(self.largest_checked_error, error)
        log.info(
            "%s %d: one cell problem solved exactly (cell stretch s = (%.4f, %.4f)) differs by "
            "%.2e (relative) from the interpolated tensors; largest so far %.2e, allowed "
            "accuracy.cell_tolerance = %.1e%s", CHECK_LINE, self.checks, *where, error,
            self.largest_checked_error, self.surrogate.tolerance,
            f"; water: b by {water[0]:.2e}, 1/M by {water[1]:.2e}" if water else "",
        )  # fmt: skip
        return 1

    def _unpack(self, packed: np.ndarray, E: np.ndarray) -> NodeTensors:
        """NodeTensors from packed E = 1 results, scaled to the nodes' E."""
        n = len(packed)
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
