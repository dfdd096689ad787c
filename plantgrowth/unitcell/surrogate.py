"""Error-controlled surrogate of the homogenized quantities over the growth state (issue 9).

Reduction (exact invariances of the cell problems, docs/model.md section 3): scaling Fg changes
nothing, so only ``F = Fg / sqrt(det Fg)`` matters; and with the polar split ``F = R U`` (R a
rotation, U symmetric positive definite, det U = 1) the problem for F is the problem for U rotated
by R (isotropic walls, rotated periodic solutions are periodic), so E_hom, dbar[w] rotate as
4th-order and K_hom, dbar[v] as 2nd-order tensors. What is left is the stretch
``U = expm(S)``, ``S = [[s1, s2], [s2, -s1]]``: two numbers per cell geometry and nu.

Method: bilinear interpolation on nested square lattices in (s1, s2), spacing ``H0 / 2^L``,
built lazily where the run's queries fall. A query is answered by the lattice level L at
which the interpolants of levels L and L + 1 differ by at most the tolerance (relative, in
the norm of each homogenized quantity); the finer interpolant is returned and that
difference is its error estimate (for a smooth function the error of level L + 1 is about a
third of it: the estimate is conservative). Bilinear weights in a lattice square are
non-negative, so the interpolant of symmetric positive definite tensors is one: E_hom stays
SPD by construction. Lattice points are exact cell solves, shared by every query and time
step, solved in rounds collectively (each rank its cost-balanced share, on COMM_SELF, then one
allgather: :mod:`plantgrowth.unitcell.scheduler`), so every rank holds the same tables. Each rank
asks about its own queries (its block of the coarse nodes); a query's answer depends only on the
lattice and its own point, so serial and parallel runs agree exactly.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from plantgrowth.unitcell.scheduler import CellScheduler

log = logging.getLogger("plantgrowth")

H0 = 0.1
"""Spacing of the coarsest lattice in (s1, s2); |s| = 0.1 is a 10% deviatoric stretch."""
MAX_LEVEL = 12
"""Finest level (spacing H0 / 4096); a query not resolved there takes that level's value."""
STEP = 2**MAX_LEVEL  # finest-lattice integers per coarsest spacing


def split_growth(Fg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotations R (n, 2, 2) and stretch coordinates s (n, 2) with
    ``Fg / sqrt(det Fg) = R expm([[s1, s2], [s2, -s1]])``."""
    F = Fg / np.sqrt(np.linalg.det(Fg))[:, None, None]
    w, V = np.linalg.eigh(np.einsum("nki,nkj->nij", F, F))  # F^T F = U^2
    U_inv = np.einsum("nik,nk,njk->nij", V, 1.0 / np.sqrt(w), V)
    S = np.einsum("nik,nk,njk->nij", V, 0.5 * np.log(w), V)  # log U
    return F @ U_inv, np.column_stack([0.5 * (S[:, 0, 0] - S[:, 1, 1]), S[:, 0, 1]])


def stretch(s: Sequence[float]) -> np.ndarray:
    """``U = expm(S) = cosh(r) I + sinh(r)/r S`` for ``S = [[s1, s2], [s2, -s1]]``, r = |s|."""
    S = np.array([[s[0], s[1]], [s[1], -s[0]]])
    r = float(np.hypot(s[0], s[1]))
    return np.cosh(r) * np.eye(2) + (np.sinh(r) / r if r > 0.0 else 1.0) * S


@dataclass(frozen=True)
class Query:
    """One coarse node's question: which table (cell geometry and nu) and where in it."""

    table: tuple
    s: np.ndarray  # (2,)


@dataclass(frozen=True)
class Answer:
    """Values (n, m) for n queries, their error estimates (n,), which were interpolated (the
    others sit on a lattice point: exact), and how many lattice points were solved for them."""

    values: np.ndarray
    estimates: np.ndarray
    interpolated: np.ndarray
    solves: int


Point = tuple[tuple, tuple[int, int]]  # (table, finest-lattice integer coordinates)


def _corners(s: np.ndarray, level: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each query (s: (n, 2), level: (n,)): the four lattice points (finest integers,
    (n, 4, 2)) of the square of its level that holds it, and their bilinear weights (n, 4)."""
    h = (H0 / 2.0**level)[:, None]
    step = (STEP // 2**level)[:, None]
    x = s / h
    base = np.floor(np.round(x, 9))  # round-off of Fg (x = 1e-17, or 0.9999999999) is on the
    t = np.clip(np.round(x - base, 9), 0.0, 1.0)  # lattice line: one exact point, no neighbours
    corner = base.astype(np.int64) * step
    offsets = np.array([[0, 0], [1, 0], [0, 1], [1, 1]])
    points = corner[:, None, :] + offsets[None, :, :] * step[:, None, :]
    tx, ty = t[:, 0:1], t[:, 1:2]
    weights = np.hstack([(1 - tx) * (1 - ty), tx * (1 - ty), (1 - tx) * ty, tx * ty])
    return points, weights


class LatticeSurrogate:
    """Lazily refined lattice tables of packed homogenized quantities.

    Args:
        solve: exact packed values at a point, ``solve(table, U)`` (on this rank only).
        tolerance: largest relative difference accepted between two levels, > 0.
        segments: slices of the packed vector measured separately (E_hom, K_hom, ...).
        comm: ranks that share the queries and the lattice solves.
        scheduler: deals the lattice solves to the ranks (default: a new one on ``comm``).
    """

    def __init__(
        self,
        solve: Callable[[tuple, np.ndarray], np.ndarray],
        tolerance: float,
        segments: Sequence[slice],
        comm: MPI.Comm,
        scheduler: CellScheduler | None = None,
    ) -> None:
        self._solve = solve
        self.scheduler = scheduler or CellScheduler(comm)
        self.tolerance = tolerance
        self.segments = tuple(segments)
        self.comm = comm
        self.values: dict[Point, np.ndarray] = {}
        self.new_points: list[Point] = []  # solved since the last take_new_points()

    def add(self, values: dict[Point, np.ndarray]) -> None:
        """Lattice values known from elsewhere (the on-disk cache); the same on every rank."""
        self.values.update(values)

    def relative_difference(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Largest over the segments of ``|a - b| / |b|`` (Frobenius norms), per row of
        (n, m) arrays (or for single vectors)."""
        a2, b2 = np.atleast_2d(a), np.atleast_2d(b)
        out = np.zeros(len(b2))
        for seg in self.segments:
            scale = np.linalg.norm(b2[:, seg], axis=1)
            diff = np.linalg.norm(a2[:, seg] - b2[:, seg], axis=1)
            out = np.maximum(out, np.divide(diff, scale, out=np.zeros_like(diff), where=scale > 0))
        return out if np.ndim(b) > 1 else float(out[0])

    def _solve_points(self, points: list[Point]) -> int:
        """Solve the lattice points missing on any rank (collective: ``points`` are this
        rank's); each point's solver is its table's geometry (the table less nu)."""
        wanted = set().union(*self.comm.allgather(set(points)))
        missing = sorted(wanted - self.values.keys())
        self.values.update(
            self.scheduler.solve_all(
                missing, lambda p: p[0][:-1],
                lambda p: self._solve(p[0], stretch(np.array(p[1]) * (H0 / STEP))),
            )
        )  # fmt: skip
        self.new_points += missing
        return len(missing)

    def _interpolate(
        self, tables: list[tuple], points: np.ndarray, weights: np.ndarray
    ) -> np.ndarray:
        """Bilinear values (n, m) from the corner points (n, 4, 2) and weights (n, 4)."""
        zero = np.zeros(len(next(iter(self.values.values()))))
        if not len(tables):
            return np.zeros((0, len(zero)))
        corner_values = np.array(
            [
                [  # a corner of zero weight (a query on a lattice line) is never needed
                    self.values[(table, (int(i), int(j)))] if w > 0.0 else zero
                    for (i, j), w in zip(corners, ws, strict=True)
                ]
                for table, corners, ws in zip(tables, points, weights, strict=True)
            ]
        )
        return np.einsum("nc,ncm->nm", weights, corner_values)

    def evaluate(self, queries: Sequence[Query]) -> Answer:
        """The surrogate's answer to this rank's queries (any number, 0 too). Collective."""
        n = len(queries)
        s = np.array([q.s for q in queries]).reshape(n, 2)
        tables = [q.table for q in queries]
        level = np.zeros(n, dtype=np.int64)
        values: np.ndarray | None = None
        estimates = np.zeros(n)
        interpolated = np.zeros(n, dtype=bool)
        pending = np.arange(n)
        solves = 0
        while self.comm.allreduce(len(pending), op=MPI.MAX):
            sub = [tables[k] for k in pending]
            coarse_pts, coarse_w = _corners(s[pending], level[pending])
            fine_pts, fine_w = _corners(s[pending], level[pending] + 1)
            needed = {
                (table, (int(i), int(j)))
                for pts, w in ((coarse_pts, coarse_w), (fine_pts, fine_w))
                for table, corners, weights in zip(sub, pts, w, strict=True)
                for (i, j), weight in zip(corners, weights, strict=True)
                if weight > 0.0
            }
            solves += self._solve_points(list(needed))
            coarse = self._interpolate(sub, coarse_pts, coarse_w)
            fine = self._interpolate(sub, fine_pts, fine_w)
            if values is None:
                values = np.zeros((n, fine.shape[1]))
            estimates[pending] = self.relative_difference(coarse, fine)
            done = (estimates[pending] <= self.tolerance) | (level[pending] + 1 == MAX_LEVEL)
            values[pending[done]] = fine[done]
            interpolated[pending[done]] = fine_w[done].max(axis=1) < 1.0
            level[pending[~done]] += 1
            pending = pending[~done]
        return Answer(values, estimates, interpolated, solves)

    def take_new_points(self) -> dict[Point, np.ndarray]:
        """The lattice values solved since the last call (for the on-disk cache)."""
        new = {p: self.values[p] for p in self.new_points}
        self.new_points = []
        return new
