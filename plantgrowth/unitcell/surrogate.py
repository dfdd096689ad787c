"""Error-controlled surrogate of the homogenized quantities over the growth state (issues 9, 33).

Reduction (exact invariances of the cell problems, docs/model.md section 3): scaling Fg changes
nothing, so only ``F = Fg / sqrt(det Fg)`` matters; and with the polar split ``F = R U`` (R a
rotation, U symmetric positive definite, det U = 1) the problem for F is the problem for U rotated
by R (isotropic walls, rotated periodic solutions are periodic), so E_hom, dbar[w] rotate as
4th-order and K_hom, dbar[v] as 2nd-order tensors. What is left is the stretch
``U = expm(S)``, ``S = [[s1, s2], [s2, -s1]]``: two numbers per cell geometry and nu.

Method (issue 33): one interpolant per table, the sum of hierarchical hat functions over every
lattice point built so far,

    I(s) = sum_p alpha_p phi_p(s),   alpha_p = f(p) - I_<l(p)(p),

where a point p of level l (new on the lattice of spacing ``H0 / 2^l``) carries the bilinear
hat phi_p of that spacing and its *surplus* alpha_p: its exact value less the interpolant of
the coarser levels there (the bilinear interpolant of its parent square's corners). The points
come from *built squares*, a quadtree: a square of level 0 is built with its four corners; a
square of level l >= 1 is built inside its built parent by adding its corners new on level l
(of the parent's five children, the two edge midpoints next to it and the centre). I is one
continuous function of s (a finite sum of continuous hats; C0, piecewise bilinear), equal to
f at every built point, and independent of which query asks: answers no longer jump where a
query's level changes. Where a built square meets a coarser one, the finer hats reach half a
finer square into it; I stays a non-negative combination of exact values there (worked out
for one level of difference, measured in tests/test_surrogate_continuity.py), so E_hom stays
SPD by construction as before.

The error estimate of a query is the relative change e(S) that the new corners of the deepest
built square S (level >= 1) holding it made there (the change the last refinement made; for a
smooth f the error left is about a quarter of it). New points are added only in
:meth:`LatticeSurrogate.refine`, the phase a call runs before it interpolates (so a step's
tensors come from one frozen interpolant): S's child square holding the query is built when
e(S) exceeds the query's tolerance (the refine threshold), and building then goes on while e
exceeds ``KEEP`` times it (the lower keep threshold): the gap keeps queries that drift about a
square whose estimate is near the tolerance from refining it again step after step. Building
a child square rather than all five children of S solves only the points some query's
estimate needs (the other children change I only where no query asked), and a query on a
corner of its level-0 square (every cell of a homogeneous tissue, s = 0) is answered exactly
without children: gradient_E_strain at ``balanced`` solved 101 lattice points with all five
children and KEEP = 0.5, 73 now (the level per query before issue 33: 67), the reference
scene 8 and now 4 (before: 1); benchmarks/results/regression.json.

Lattice points are exact cell solves, shared by every query and time step, solved in rounds
collectively (each rank its cost-balanced share, on COMM_SELF, then one allgather:
:mod:`plantgrowth.unitcell.scheduler`). The squares to refine are the union over the ranks of
each round's requests, so every rank holds the same tables and a query's answer depends only on
them and its own point: serial and parallel runs agree exactly. Lookups are vectorised: points
and squares have integer keys (table number, level, finest-lattice coordinates), found among
the sorted keys by binary search.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from plantgrowth.base.errors import RunError
from plantgrowth.base.tensors import det2
from plantgrowth.unitcell.lattice import (
    CHUNK,
    H0,
    MAX_LEVEL,
    OFFSETS,
    STEP,
    StopSquares,
    cell,
    hats,
    key_integers,
    point_key,
    square_corners,
    square_key,
    touched,
)
from plantgrowth.unitcell.scheduler import CellScheduler
from plantgrowth.unitcell.smooth_answers import EARLY, SmoothAnswers

log = logging.getLogger("plantgrowth")


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
    square: np.ndarray | None = None  # the deepest built square's key per query (refine's)


Point = tuple[tuple, tuple[int, int]]  # (table, finest-lattice integer coordinates)

KEEP = 0.7
"""Keep threshold over refine threshold. A refinement that a query's estimate above its
tolerance started goes on to squares whose estimate is at most 0.7 times the tolerance. One
level divides the surpluses by about 4 (the bilinear interpolant's h^2 convergence), so a
refinement overshoots by a level only where its trigger was rougher than about 2.8 times the
tolerance, and a square just built next to ones near the tolerance is built finer than they
need. Measured on tests/test_surrogate_continuity.py's drifting queries, KEEP 0.5 / 0.7 / 1
(no gap): 28 / 33 / 44 refining calls, 321 / 293 / 275 points, largest jump beyond the exact
change 0.055 / 0.029 / 0.054 tolerance; on gradient_E_strain at ``balanced`` 101 / 73 / 67
lattice points (0.5 overshot a level in most squares: the estimates there sit at 0.5-0.7)."""
QUIET_MARGIN = 1e-6
"""Margin under the threshold where a bound spares an estimate: far above its 1e-16 rounding."""
MAX_GROWTHS = MAX_LEVEL + 1
"""Most passes of one refinement in which a query asks for a square: each time, for the child
of its deepest built square S holding it, so S's level rises from -1 (none) to at most
MAX_LEVEL. A query that asks more often sees a stale level (stop squares a refinement did not
drop, squares that do not nest): it would ask for the same built square forever."""
SQUARE_TABLE = 7
"""Most entries of a table (a fibred table's angle node: geometry, nu, fibre_stiffness, node)."""


class LatticeSurrogate:
    """Hierarchical lattice interpolants of packed homogenized quantities, one per table.

    Args:
        solve: exact packed values at a point, ``solve(table, U)`` (on this rank only).
        tolerance: default refine threshold (relative error estimate), > 0.
        segments: slices of the packed vector measured separately (E_hom, K_hom, ...).
        comm: ranks that share the queries and the lattice solves.
        scheduler: deals the lattice solves to the ranks (default: a new one on ``comm``).
        group: the solver (mesh) a table's points are solved on, ``group(table)`` (default:
            the table less its last entry, nu).
        interpolant: "bilinear" (I, this module) or "c1" (J with refinements blended in and
            started at :data:`~plantgrowth.unitcell.smooth_answers.EARLY` times the tolerance:
            :mod:`plantgrowth.unitcell.smooth_answers`); the estimates are I's either way.
        voigt: the packed slice of E_hom's Voigt matrix, which c1's SPD guard checks (None:
            no guard).
    """

    def __init__(
        self,
        solve: Callable[[tuple, np.ndarray], np.ndarray],
        tolerance: float,
        segments: Sequence[slice],
        comm: MPI.Comm,
        scheduler: CellScheduler | None = None,
        group: Callable[[tuple], Hashable] = lambda table: table[:-1],
        interpolant: str = "bilinear",
        voigt: slice | None = None,
    ) -> None:
        self._solve = solve
        self._group = group
        self.scheduler = scheduler or CellScheduler(comm)
        self.tolerance = tolerance
        self.segments = tuple(segments)
        self.comm = comm
        self.values: dict[Point, np.ndarray] = {}  # exact values (solved or from the cache)
        self.new_points: list[Point] = []  # solved since the last take_new_points()
        self._table_ids: dict[tuple, int] = {}  # table -> its number in the keys
        self._surplus: dict[int, np.ndarray] = {}  # point key -> alpha_p, the interpolant's
        self._built: set[int] = set()  # keys of the built squares
        self._points_index: tuple[np.ndarray, np.ndarray] | None = None
        self._squares_index: np.ndarray | None = None
        self._stops = StopSquares(self.segment_norms)  # I at the corners of the stop squares met
        self.step = 0  # steps ended (:meth:`end_step`): the c1 blend's clock
        self.smooth = None if interpolant == "bilinear" else SmoothAnswers(
            self._lattice_points, self.relative_difference, tolerance, voigt
        )  # fmt: skip

    def add(self, values: dict[Point, np.ndarray]) -> None:
        """Lattice values known from elsewhere (the on-disk cache; the same on every rank):
        solves saved, not points of the interpolant until a refinement asks for them."""
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

    def segment_norms(self, x: np.ndarray) -> np.ndarray:
        """Frobenius norms (..., segments) of the segments of packed values x (..., m)."""
        return np.stack([np.sqrt((x[..., seg] ** 2).sum(axis=-1)) for seg in self.segments], -1)

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

    def _register(self, tables: Sequence[tuple]) -> None:
        """Collective: number the tables any rank names that have no number yet, in sorted
        order, so that a table has one number (and a square one key) on every rank."""
        new = set().union(*self.comm.allgather(set(tables))) - self._table_ids.keys()
        for table in sorted(new):
            self._table_ids[table] = len(self._table_ids)

    def _numbers(self, tables: Sequence[tuple]) -> np.ndarray:
        """The tables' numbers in the keys (KeyError for a table never refined)."""
        return np.array([self._table_ids[t] for t in tables], dtype=np.int64)

    def _points_table(self) -> tuple[np.ndarray, np.ndarray]:
        """Sorted keys of the interpolant's points and their surpluses (rebuilt after a
        refinement)."""
        if self._points_index is None:
            keys = np.array(sorted(self._surplus), dtype=np.int64)
            rows = np.array([self._surplus[k] for k in keys.tolist()]) if len(keys) else None
            self._points_index = keys, np.zeros((0, 0)) if rows is None else rows
        return self._points_index

    def _deepest(self, ids: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per query: the level of the deepest built square S that holds it (-1: its level-0
        square is not built yet) and S's key (:meth:`_walk`)."""
        return self._walk(ids, s)[2:4]

    def refine(
        self, tables: Sequence[tuple], which: np.ndarray, s: np.ndarray,
        tolerance: np.ndarray | None = None,
    ) -> int:  # fmt: skip
        """Collective: build squares until each query k (table ``tables[which[k]]``, stretch
        ``s[k]``) has an estimate within ``tolerance[k]`` (default: the surrogate's own),
        building on past the trigger down to ``KEEP`` times it (module docstring).
        Returns the number of lattice points solved (the same on every rank)."""
        return self._refine(tables, which, s, tolerance).solves

    def _refine(
        self, tables: Sequence[tuple], which: np.ndarray, s: np.ndarray,
        tolerance: np.ndarray | None,
    ) -> Answer:  # fmt: skip
        """:meth:`refine`, returning with the solves the answers of the last round's pass,
        the one that found nothing to refine: the frozen interpolant's values and estimates."""
        n = len(which)
        tol = np.full(n, self.tolerance) if tolerance is None else np.asarray(tolerance)
        self._register(tables)
        ids = self._numbers(tables)[np.asarray(which, dtype=np.int64)]
        s = np.asarray(s, dtype=float).reshape(n, 2)
        fresh = np.zeros(0, dtype=np.int64)  # squares built in this call
        solves = 0
        grown = np.zeros(n, dtype=np.int64)  # passes in which each query asked for a square
        found, squares = None, np.zeros(0, dtype=np.int64)
        while True:
            found = self._pass(ids, s, found, squares, KEEP * tol)
            values, interpolated = found["values"], ~found["on_point"]
            level, key, error = found["level"], found["square"], found["error"]
            going = np.isin(key, fresh) & (error > KEEP * tol)
            grow = (level < 0) | ((level < MAX_LEVEL) & ((error > tol) | going))
            child = level[grow] + 1
            wanted = square_key(ids[grow], child, cell(s[grow], child)[0])
            grown += grow
            stuck = np.flatnonzero(grown > MAX_GROWTHS)[:1]
            every = self.comm.allgather((np.unique(wanted), ids[stuck], s[stuck]))
            self._check_growths(every)
            squares = np.unique(np.concatenate([w for w, _, _ in every]))
            if not len(squares):  # nothing built anywhere: the interpolant is final
                return Answer(values, error, interpolated, solves, key)
            solves += self._build_squares(squares)
            fresh = np.union1d(fresh, squares)

    def _pass(
        self, ids: np.ndarray, s: np.ndarray, last: dict[str, np.ndarray] | None,
        built: np.ndarray, quiet: np.ndarray,
    ) -> dict[str, np.ndarray]:  # fmt: skip
        """One pass of :meth:`_refine`: the frozen interpolant's answers (:meth:`_found`) and
        estimates ``error`` (inf: none yet); a query whose estimate is bounded below ``quiet``
        (KEEP times its tolerance: it grows nothing) has the bound as its estimate
        (:meth:`~plantgrowth.unitcell.lattice.StopSquares.answer`). A query the new hats of the
        squares ``built`` since the ``last`` pass do not reach (:func:`.lattice.touched`) keeps
        its last answer: I, S and S's term are unchanged there (to rounding, 5e-16)."""
        again = np.arange(len(ids))
        if last is not None and last["values"].shape[1]:  # a lattice with points before
            again = np.flatnonzero(touched(built, ids, s))
            if not len(again):
                return last
        found = self._found(ids[again], s[again], quiet=quiet[again] * (1.0 - QUIET_MARGIN))
        level, values = found["level"], found["values"]
        bound, loud, change = found.pop("bound"), found.pop("loud"), found.pop("change")
        error = np.full(len(again), np.inf)
        on_corner = (level == 0) & (cell(s[again], 0)[1] % 1.0 == 0.0).all(axis=1)
        error[on_corner] = 0.0  # level 0 has no estimate (its children are built first)
        inside = level >= 1  # unless the query is a corner: answered exactly
        error[inside] = bound[inside]  # below the threshold, or replaced next
        if len(loud):
            error[loud] = self.relative_difference(values[loud] - change, values[loud])
        found["error"] = error
        if len(again) == len(ids):
            return found
        for name, array in found.items():  # last is this call's own: updated in place
            last[name][again] = array
        return last

    def _check_growths(self, every: list[tuple[np.ndarray, ...]]) -> None:
        """Raise RunError on every rank if a query on any rank (its table numbers and
        stretches, gathered in ``every``) asked for a square in more than :data:`MAX_GROWTHS`
        passes of one refinement."""
        for _, ids, s in every:
            if len(ids):
                names = {v: k for k, v in self._table_ids.items()}
                raise RunError(
                    f"the surrogate's refinement did not end: a query (table {names[ids[0]]}, "
                    f"stretch s = ({s[0, 0]:.6g}, {s[0, 1]:.6g})) asked for a finer square in "
                    f"more than {MAX_GROWTHS} passes, but its deepest square can deepen only "
                    f"{MAX_GROWTHS} times (levels -1 to {MAX_LEVEL}): the lattice lookup does not "
                    "see the squares it builds (a bug, please report it)"
                )

    def _build_squares(self, squares: np.ndarray) -> int:
        """Build the squares (sorted keys, the same on every rank): their corners and those
        corners' surpluses (a level-0 corner's is its value; a corner new on level l >= 1 has
        the bilinear interpolant of the parent square's corners subtracted). Collective."""
        names = {v: k for k, v in self._table_ids.items()}
        ids, level, corner = square_corners(squares)
        step = (STEP >> level)[:, None, None]
        parent_step = (STEP >> np.maximum(level - 1, 0))[:, None, None]
        corners = corner[:, None, :] + OFFSETS[None] * step  # (q, 4, 2)
        parents = (corner[:, None, :] // parent_step + OFFSETS[None]) * parent_step
        every = np.concatenate([corners, parents], axis=1)
        points = [(names[t], (a, b)) for t, row in zip(ids.tolist(), every.tolist(), strict=True)
                  for a, b in row]  # fmt: skip
        solves = self._solve_points(points)
        place = (corners - parents[:, :1, :]) / parent_step  # corners in their parent, [0, 1]
        for q, t in enumerate(ids.tolist()):
            table = names[t]
            f = np.array([self.values[table, tuple(p)] for p in every[q].tolist()])
            keys = point_key(np.int64(t), corners[q, :, 0], corners[q, :, 1]).tolist()
            coarse = hats(place[q]) @ f[4:] if level[q] else np.zeros_like(f[:4])
            new = ((corners[q] // step[q]) % 2).any(axis=-1) | (level[q] == 0)
            for k, value, below, is_new in zip(keys, f[:4], coarse, new, strict=True):
                if is_new:
                    self._surplus.setdefault(k, value - below)
            self._built.add(int(squares[q]))
            if self.smooth is not None:
                self.smooth.births.setdefault(int(squares[q]), self.step)
        self._points_index = self._squares_index = None
        self._stops.drop(squares)
        return solves

    def interpolate(
        self, tables: Sequence[tuple], which: np.ndarray, s: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The frozen interpolant ``I(s) = sum_p alpha_p phi_p(s)`` at this rank's n queries
        (no solve, not collective; :meth:`_found`), and which queries are not on a built point.
        Raises KeyError off the built lattice."""
        n = len(which)
        ids = self._numbers(tables)[np.asarray(which, dtype=np.int64)]
        return self.interpolate_ids(ids, np.asarray(s, dtype=float).reshape(n, 2))

    def interpolate_ids(self, ids: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`interpolate` for queries given by their tables' numbers ids (n,)."""
        return self._walk(ids, s, strict=True)[:2]

    def _walk(
        self, ids: np.ndarray, s: np.ndarray, strict: bool = False
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_found` as a tuple: I(s), which queries are not on a built point, the level
        and key of S and S's term."""
        found = self._found(ids, s, strict)
        return (found["values"], ~found["on_point"], found["level"], found["square"],
                found["change"])  # fmt: skip

    def _found(
        self, ids: np.ndarray, s: np.ndarray, strict: bool = False, quiet: np.ndarray | None = None
    ) -> dict[str, np.ndarray]:
        """The frozen interpolant at n >= 0 queries: I(s) (:meth:`interpolate`; ``strict``: a
        KeyError off the built lattice), whether each is a built point, the level and key of
        the deepest built square S holding it (-1, 0: none), and S's term of I, the change its
        new corners made there, ``sum_c alpha_c phi_c(s)`` (the error estimate is ``|term| /
        |I(s)|`` per segment; for a smooth f the error left is about a third of it); with
        ``quiet``, as :meth:`.StopSquares.answer`. One lookup of each query's stop square, the
        ones not met before found by walks first."""
        if not len(ids):  # a rank without queries (perhaps without stop squares yet)
            empty = np.zeros((0, self._points_table()[1].shape[1]))
            return {"values": empty, "change": empty, "on_point": np.zeros(0, dtype=bool),
                    "level": np.full(0, -1), "square": np.zeros(0, np.int64), "bound":
                    np.zeros(0), "loud": np.zeros(0, dtype=np.int64)}  # fmt: skip
        return self._stops.through(self._lattice_tables, ids, s, strict, quiet)

    def _lattice_tables(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sorted built squares' keys, point keys and surpluses (:meth:`.StopSquares.learn`)."""
        if self._squares_index is None:
            self._squares_index = np.array(sorted(self._built), dtype=np.int64)
        return (self._squares_index, *self._points_table())

    def evaluate(
        self, tables: Sequence[tuple], which: np.ndarray, s: np.ndarray,
        tolerance: np.ndarray | None = None,
    ) -> Answer:  # fmt: skip
        """Collective: :meth:`refine` for this rank's n queries (0 too), then the frozen
        interpolant's answers and their estimates (:meth:`_walk`), taken from refine's last
        pass (it ran on the frozen interpolant: recomputing them gave the same bits). On the
        c1 path the answers are :class:`~plantgrowth.unitcell.smooth_answers.SmoothAnswers`'s
        (refined at EARLY times the tolerance, the estimates still I's)."""
        if self.smooth is None:
            return self._refine(tables, which, s, tolerance)
        n = len(which)
        tol = np.full(n, self.tolerance) if tolerance is None else np.asarray(tolerance)
        answer = self._refine(tables, which, s, EARLY * tol)
        if not n:
            return answer
        ids = self._numbers(tables)[np.asarray(which, dtype=np.int64)]
        s = np.asarray(s, dtype=float).reshape(n, 2)
        values = self.smooth.answer(ids, s, answer.values, answer.square, self.step)
        return Answer(values, answer.estimates, answer.interpolated, answer.solves)

    def end_step(self) -> None:
        """A time step ended: the c1 path's blends advance by one step."""
        self.step += 1

    def births(self) -> np.ndarray:
        """The c1 path's resume state, its squares those of :meth:`squares` in order
        (:meth:`~plantgrowth.unitcell.smooth_answers.SmoothAnswers.birth_rows`)."""
        return self.smooth.birth_rows(sorted(self._built), self.step)

    def restore_births(self, rows: np.ndarray) -> None:
        """Set the squares' births and the step count from :meth:`births`'s rows (after
        :meth:`restore` of the same state's squares)."""
        self.step = self.smooth.restore_births(sorted(self._built), rows)

    def _lattice_points(self, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Exact values and surpluses (P, m) of built lattice points (point keys (P,))."""
        names = {v: k for k, v in self._table_ids.items()}
        keys = np.asarray(keys, dtype=np.int64)
        points = [(names[k >> 42], tuple(ij))
                  for k, ij in zip(keys.tolist(), key_integers(keys).tolist(), strict=True)]
        values = np.array([self.values[p] for p in points])
        return values, np.array([self._surplus[k] for k in keys.tolist()])

    def squares(self) -> np.ndarray:
        """The built squares, what a resumed run needs to rebuild the interpolant: one row a
        square (int64), ``[len(table), table padded with 0 to SQUARE_TABLE entries, level, i,
        j]`` (its lower-left corner in finest integers), sorted."""
        names = {v: k for k, v in self._table_ids.items()}
        keys = np.array(sorted(self._built), dtype=np.int64)
        rows = np.zeros((len(keys), SQUARE_TABLE + 4), dtype=np.int64)
        for r, key in enumerate(keys.tolist()):
            table = names[key >> 46]
            rows[r, 0], rows[r, 1 : 1 + len(table)] = len(table), table
        _, rows[:, -3], rows[:, -2:] = square_corners(keys.reshape(-1))
        return rows

    def restore(self, rows: np.ndarray) -> int:
        """Collective: build the squares of :meth:`squares`'s rows (the same on every rank;
        their points from :attr:`values` or solved). Returns the points solved."""
        if not len(rows):  # the same on every rank
            return 0
        tables = [tuple(row[1 : 1 + row[0]]) for row in rows.tolist()]
        self._register(tables)
        ids = self._numbers(tables)
        keys = square_key(ids, rows[:, -3], rows[:, -2:])
        return self._build_squares(np.unique(keys))

    def take_new_points(self) -> dict[Point, np.ndarray]:
        """The lattice values solved since the last call (for the on-disk cache)."""
        new = {p: self.values[p] for p in self.new_points}
        self.new_points = []
        return new
