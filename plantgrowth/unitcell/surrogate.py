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
asks about its own queries (its fine cells, or its block of the coarse nodes); a query's answer
depends only on the lattice and its own point, so serial and parallel runs agree exactly.
Lookups are vectorised: each lattice point has an integer key (table number and finest-lattice
coordinates), found among the sorted keys of the known points by binary search, so a query
costs microseconds and the cells of a fine mesh can each ask their own.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from plantgrowth.base.tensors import det2
from plantgrowth.unitcell.scheduler import CellScheduler

log = logging.getLogger("plantgrowth")

H0 = 0.1
"""Spacing of the coarsest lattice in (s1, s2); |s| = 0.1 is a 10% deviatoric stretch."""
MAX_LEVEL = 12
"""Finest level (spacing H0 / 4096); a query not resolved there takes that level's value."""
STEP = 2**MAX_LEVEL  # finest-lattice integers per coarsest spacing
_OFFSET = 2**20  # finest-lattice integers are keyed in [-OFFSET, OFFSET): |s| < 25


def split_growth(Fg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotations R (n, 2, 2) and stretch coordinates s (n, 2) with
    ``Fg / sqrt(det Fg) = R expm([[s1, s2], [s2, -s1]])``, in closed form: R turns by
    ``atan2(F21 - F12, F11 + F22)``, ``U = R^T F`` (symmetric, det 1), and
    ``U = cosh(r) I + sinh(r)/r S`` gives ``r = arccosh(tr U / 2)``, ``S = (U - cosh(r) I) r /
    sinh(r)``."""
    F = Fg / np.sqrt(det2(Fg))[:, None, None]
    angle = np.arctan2(F[:, 1, 0] - F[:, 0, 1], F[:, 0, 0] + F[:, 1, 1])
    c, s = np.cos(angle), np.sin(angle)
    R = np.stack([np.stack([c, -s], axis=-1), np.stack([s, c], axis=-1)], axis=-2)
    U = np.swapaxes(R, 1, 2) @ F
    r = np.arccosh(np.maximum(0.5 * (U[:, 0, 0] + U[:, 1, 1]), 1.0))
    scale = np.divide(r, np.sinh(r), out=np.ones_like(r), where=r > 0.0)
    s1 = 0.5 * (U[:, 0, 0] - U[:, 1, 1]) * scale
    s2 = 0.5 * (U[:, 0, 1] + U[:, 1, 0]) * scale
    return R, np.column_stack([s1, s2])


def stretch(s: Sequence[float]) -> np.ndarray:
    """``U = expm(S) = cosh(r) I + sinh(r)/r S`` for ``S = [[s1, s2], [s2, -s1]]``, r = |s|."""
    S = np.array([[s[0], s[1]], [s[1], -s[0]]])
    r = float(np.hypot(s[0], s[1]))
    return np.cosh(r) * np.eye(2) + (np.sinh(r) / r if r > 0.0 else 1.0) * S


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


CHUNK = 8192
"""Queries per batched product in :func:`_combine` (and rows per pass of
:meth:`LatticeSurrogate.relative_difference`): a chunk's gathered corner rows (8192 x 4
x m, about 10 MB for the 38 packed values of the strain law) stay in cache; the whole (n, 4, m)
gather of a fine mesh's 500,000 queries took 11 times as long (3.3 s against 0.3 s) and 600 MB."""


def _combine(weights: np.ndarray, rows: np.ndarray, table: np.ndarray) -> np.ndarray:
    """``sum_c weights[n, c] table[rows[n, c], :]`` (n, m): the interpolated values, as
    batched products over chunks of :data:`CHUNK` queries (each row's arithmetic is the same
    whatever the chunk)."""
    out = np.empty((len(weights), table.shape[1]))
    for start in range(0, len(weights), CHUNK):
        part = slice(start, start + CHUNK)
        out[part] = (weights[part, None, :] @ table[rows[part]])[:, 0, :]
    return out


class LatticeSurrogate:
    """Lazily refined lattice tables of packed homogenized quantities.

    Args:
        solve: exact packed values at a point, ``solve(table, U)`` (on this rank only).
        tolerance: largest relative difference accepted between two levels, > 0.
        segments: slices of the packed vector measured separately (E_hom, K_hom, ...).
        comm: ranks that share the queries and the lattice solves.
        scheduler: deals the lattice solves to the ranks (default: a new one on ``comm``).
        group: the solver (mesh) a table's points are solved on, ``group(table)`` (default:
            the table less its last entry, nu).
    """

    def __init__(
        self,
        solve: Callable[[tuple, np.ndarray], np.ndarray],
        tolerance: float,
        segments: Sequence[slice],
        comm: MPI.Comm,
        scheduler: CellScheduler | None = None,
        group: Callable[[tuple], Hashable] = lambda table: table[:-1],
    ) -> None:
        self._solve = solve
        self._group = group
        self.scheduler = scheduler or CellScheduler(comm)
        self.tolerance = tolerance
        self.segments = tuple(segments)
        self.comm = comm
        self.values: dict[Point, np.ndarray] = {}
        self.new_points: list[Point] = []  # solved since the last take_new_points()
        self._table_ids: dict[tuple, int] = {}  # table -> its number in the keys
        self._keys: np.ndarray | None = None  # sorted keys of self.values (:meth:`_index`)
        self._rows = np.zeros((0, 0))

    def add(self, values: dict[Point, np.ndarray]) -> None:
        """Lattice values known from elsewhere (the on-disk cache); the same on every rank."""
        self.values.update(values)

    def relative_difference(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Largest over the segments of ``|a - b| / |b|`` (Frobenius norms), per row of
        (n, m) arrays (or for single vectors), over chunks of :data:`CHUNK` rows."""
        a2, b2 = np.atleast_2d(a), np.atleast_2d(b)
        out = np.zeros(len(b2))
        for start in range(0, len(b2), CHUNK):
            part = slice(start, start + CHUNK)
            out[part] = self._squared_difference(a2[part], b2[part])
        out = np.sqrt(out)
        return out if np.ndim(b) > 1 else float(out[0])

    def _squared_difference(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Largest over the segments of ``|a - b|^2 / |b|^2`` per row."""
        squared, scale2 = (a - b) ** 2, b * b
        out = np.zeros(len(b))
        for seg in self.segments:
            diff, scale = squared[:, seg].sum(axis=1), scale2[:, seg].sum(axis=1)
            ratio = np.divide(diff, scale, out=np.zeros_like(diff), where=scale > 0)
            out = np.maximum(out, ratio)
        return out

    def _solve_points(self, points: list[Point]) -> int:
        """Solve the lattice points missing on any rank (collective: ``points`` are this
        rank's); each point's solver is its table's group (by default the table less nu)."""
        wanted = set().union(*self.comm.allgather(set(points)))
        missing = sorted(wanted - self.values.keys())
        self.values.update(
            self.scheduler.solve_all(
                missing, lambda p: self._group(p[0]),
                lambda p: self._solve(p[0], stretch(np.array(p[1]) * (H0 / STEP))),
            )
        )  # fmt: skip
        self.new_points += missing
        return len(missing)

    def _index(self) -> tuple[np.ndarray, np.ndarray]:
        """Sorted keys of the known lattice points and their values (rebuilt when points were
        added)."""
        if self._keys is None or len(self._keys) != len(self.values):
            points = list(self.values)
            for table, _ in points:
                self._table_ids.setdefault(table, len(self._table_ids))
            ids = np.array([self._table_ids[t] for t, _ in points], dtype=np.int64)
            ij = np.array([p for _, p in points], dtype=np.int64).reshape(-1, 2)
            keys = self._encode(ids, ij[:, 0], ij[:, 1])
            order = np.argsort(keys)
            self._keys = keys[order]
            self._rows = np.array([self.values[points[k]] for k in order])
        return self._keys, self._rows

    def _encode(self, ids: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """One int64 key per lattice point: table number, then the two finest integers."""
        if np.size(i) and max(np.abs(i).max(), np.abs(j).max()) >= _OFFSET:
            raise ValueError(f"a growth stretch |s| >= {_OFFSET * H0 / STEP:g}: off the lattice")
        return (ids << 42) | ((i + _OFFSET) << 21) | (j + _OFFSET)

    def _numbers(self, tables: Sequence[tuple]) -> np.ndarray:
        """The tables' numbers in the keys (new tables get the next ones)."""
        ids = [self._table_ids.setdefault(t, len(self._table_ids)) for t in tables]
        return np.array(ids, dtype=np.int64)

    def _lookup(
        self, ids: np.ndarray, points: np.ndarray, weights: np.ndarray
    ) -> tuple[np.ndarray, list[Point]]:
        """For corners (n, 4, 2) in the tables ``ids`` (n,) with weights (n, 4): their rows
        (n, 4) among the known lattice points (a corner of zero weight, a query on a lattice
        line, may be unknown: its row is any, and it adds 0) and the corners of non-zero weight
        that are not known yet."""
        known, _ = self._index()
        keys = self._encode(ids[:, None], points[..., 0], points[..., 1])
        if not len(known):
            return np.zeros(keys.shape, dtype=np.int64), self._points(keys[weights > 0.0])
        rows = np.minimum(np.searchsorted(known, keys), len(known) - 1)
        return rows, self._points(keys[(known[rows] != keys) & (weights > 0.0)])

    def _points(self, keys: np.ndarray) -> list[Point]:
        """The distinct lattice points of the keys."""
        new = np.unique(keys)
        names = {v: k for k, v in self._table_ids.items()}
        low = (1 << 21) - 1
        i, j = ((new >> 21) & low) - _OFFSET, (new & low) - _OFFSET
        columns = ((new >> 42).tolist(), i.tolist(), j.tolist())
        return [(names[k], (a, b)) for k, a, b in zip(*columns, strict=True)]

    def evaluate(
        self, tables: Sequence[tuple], which: np.ndarray, s: np.ndarray,
        tolerance: np.ndarray | None = None,
    ) -> Answer:  # fmt: skip
        """The surrogate's answer to this rank's n queries (0 too): query k asks table
        ``tables[which[k]]`` at ``s[k]`` (n, 2), to the relative ``tolerance[k]`` (default: the
        surrogate's own). Collective."""
        n = len(which)
        tol = np.full(n, self.tolerance) if tolerance is None else np.asarray(tolerance)
        ids = self._numbers(tables)[np.asarray(which, dtype=np.int64)]
        s = np.asarray(s, dtype=float).reshape(n, 2)
        level = np.zeros(n, dtype=np.int64)
        values: np.ndarray | None = None
        estimates = np.zeros(n)
        interpolated = np.zeros(n, dtype=bool)
        pending = np.arange(n)
        solves = 0
        coarse = None  # the level's interpolant of the pending queries: the last round's fine
        while self.comm.allreduce(len(pending), op=MPI.MAX):
            sub = ids[pending]
            corners = [_corners(s[pending], level[pending] + 1)]  # the fine level, then
            if coarse is None:  # in the first round only, the coarse one
                corners.append(_corners(s[pending], level[pending]))
            found = [self._lookup(sub, points, weights) for points, weights in corners]
            added = self._solve_points([p for _, missing in found for p in missing])
            if added:  # the same count on every rank: the known points changed
                found = [self._lookup(sub, points, weights) for points, weights in corners]
            solves += added
            table = self._index()[1]
            fine_w = corners[0][1]
            fine = _combine(fine_w, found[0][0], table)  # bilinear values
            if coarse is None:
                coarse = _combine(corners[1][1], found[1][0], table)
            if values is None:
                values = np.zeros((n, fine.shape[1]))
            estimates[pending] = self.relative_difference(coarse, fine)
            done = (estimates[pending] <= tol[pending]) | (level[pending] + 1 == MAX_LEVEL)
            values[pending[done]] = fine[done]
            interpolated[pending[done]] = fine_w[done].max(axis=1) < 1.0
            level[pending[~done]] += 1
            pending, coarse = pending[~done], fine[~done]
        return Answer(values, estimates, interpolated, solves)

    def take_new_points(self) -> dict[Point, np.ndarray]:
        """The lattice values solved since the last call (for the on-disk cache)."""
        new = {p: self.values[p] for p in self.new_points}
        self.new_points = []
        return new
