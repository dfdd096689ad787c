"""The surrogate's C1 answers: refinements blended in over steps, and the SPD guard (issue 33,
``accuracy.cell_interpolant = "c1"``, docs/surrogate_c1.md).

Every built square has a *birth*, the step in which it was built. With J_b the C1 interpolant
(:class:`~plantgrowth.unitcell.smooth_lattice.SmoothLattice`) of the squares born up to step b
and c the current step, a query's answer is

    A(s) = J_c(s) + sum_{b in births, c - b < B} (1 - w_b) (J_{<b}(s) - J_b(s)),
    w_b = x^2 (3 - 2 x),   x = (c - b + 1) / (B + 1),

where J_{<b} is the interpolant of the squares born before b: each refinement enters over B
steps (:data:`BLEND_STEPS`) along a smoothstep. Each term is multiplied by a gate g in [0, 1],
decided at the query's current s by the surrogate's bilinear estimate e
(:meth:`LatticeSurrogate._refine`) on the squares born before b: g = 1 for e <= tol, 0 for
e >= :data:`GATE` tol (the query takes J_c), the smoothstep between (a drifting query's gate
closes over steps instead of jumping). A birth's term is taken only at the queries its new
points can change: within 3 spacings of a new point of its level, 5 at level 0 (a point's
kernel reaches 2 h, the finer surpluses it changes 1 h more, a level-0 point's ghosts 2 h_0
more: :data:`REACH`). Everything here is a function of the shared tables (the squares, their
births, the step) and the query: the same on every rank, and a resumed run (births and the
step saved, :meth:`LatticeSurrogate.births`) answers as the straight one.

**SPD guard.** K's negative lobes make J a combination with some negative weights, so E_hom's
positivity is not kept by construction (the bilinear answer is a convex combination). A C1
answer whose Voigt matrix has ``lambda_min / lambda_max`` below half the smallest such ratio over
the exact values at the corners of its deepest built square is replaced by the bilinear answer
(logged).
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np

from plantgrowth.base.errors import RunError
from plantgrowth.unitcell.lattice import (
    LOW,
    OFFSET,
    OFFSETS,
    STEP,
    StopSquares,
    cell,
    find,
    point_key,
    square_corners,
    square_key,
)
from plantgrowth.unitcell.smooth_cells import CellPolynomials
from plantgrowth.unitcell.smooth_lattice import SmoothLattice, point_level

log = logging.getLogger("plantgrowth")

BLEND_STEPS = 8
"""B, steps over which a refinement enters. Measured on gradient_E_strain forced to CG
(docs/surrogate_c1.md): with theta = 0.7, B = 4 left 6 steps from step 16 on above 6 CG
iterations, B = 8 none."""
EARLY = 0.7
"""theta: the c1 path refines where the estimate exceeds theta times the tolerance, so that the
queries starting a refinement are still within the tolerance and blend (measured with B = 8:
theta = 1 let 7 steps jump past 6 iterations, 0.7 none, 0.5 one, at 127 cell solves against
117)."""
GATE = 3.0
"""The blend's gate closes between e = tol and GATE tol (module docstring). Measured on
gradient_E_strain forced to CG, 60 steps (largest CG count from step 16 on): a hard gate at tol
decided at each step 9 (steps 17-20: a drifting query's estimate crossing tol jumps by its
remaining share), smoothstep between 0.7 tol and tol 7, tol and 2 tol 7, tol and 3 tol 6; the
largest exact check 3.5e-5 in each (tolerance 1e-3: J's errors are about a tenth of the
bilinear estimate, docs/surrogate_c1.md)."""
REACH = (5, 3)
"""Spacings of its level around a new point of level 0, and of a finer level, outside which
adding it leaves J unchanged bit for bit: a level-l point's kernel reaches 2 h_l and the finer
surpluses it changes 1 h_l more (3); a level-0 point also changes the ghosts 2 h_0 around it,
whose kernels reach 2 h_0 more (5)."""
SPD_FRACTION = 0.5
"""The SPD guard's bound, a fraction of the corners' smallest lambda_min / lambda_max."""


def smoothstep(x: float | np.ndarray) -> float | np.ndarray:
    """``x^2 (3 - 2 x)`` on [0, 1]: the new interpolant's share."""
    return x * x * (3.0 - 2.0 * x)


def corner_keys(squares: np.ndarray) -> np.ndarray:
    """The point keys (q, 4) of squares' corners (square keys (q,))."""
    ids, level, corner = square_corners(squares)
    points = corner[:, None, :] + OFFSETS[None] * (STEP >> level)[:, None, None]
    return point_key(ids[:, None], points[..., 0], points[..., 1])


def marks(new: np.ndarray) -> dict[int, np.ndarray]:
    """Per level k, the sorted keys of the level-k cells within :data:`REACH` of a new point
    of level k (point keys ``new``): where J changes when they are added."""
    ij = np.column_stack([((new >> 21) & LOW) - OFFSET, (new & LOW) - OFFSET])
    level = point_level(ij)
    out = {}
    for k in np.unique(level).tolist():
        span = np.arange(-REACH[k > 0], REACH[k > 0])
        around = np.array([[a, b] for a in span for b in span])
        own = level == k
        cells = (ij[own] // (STEP >> k))[:, None, :] + around[None]
        out[k] = np.unique(square_key((new[own] >> 42)[:, None], k, cells * (STEP >> k)))
    return out


def ratios(values: np.ndarray, voigt: slice) -> np.ndarray:
    """``lambda_min / lambda_max`` of the Voigt matrices in ``values[:, voigt]`` (n,)."""
    C = values[:, voigt].reshape(-1, 3, 3)
    eig = np.linalg.eigvalsh(0.5 * (C + np.swapaxes(C, 1, 2)))
    return eig[:, 0] / np.maximum(eig[:, -1], 1e-300)


class SmoothAnswers:
    """The C1 path's answers over a surrogate's squares (module docstring).

    Args:
        points: ``points(keys)`` the exact values (P, m) and bilinear surpluses (P, m) of
            lattice points (point keys (P,)).
        difference: the surrogate's relative difference per row (its segments).
        voigt: the slice of the packed values holding E_hom's Voigt matrix (None: no guard).
    """

    def __init__(
        self, points: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
        difference: Callable[[np.ndarray, np.ndarray], np.ndarray], voigt: slice | None,
    ) -> None:  # fmt: skip
        self._points = points
        self._difference = difference
        self.voigt = voigt
        self.births: dict[int, int] = {}  # square key -> its step
        self.guarded = 0  # answers the SPD guard replaced so far
        self._cache: dict[int, tuple[int, CellPolynomials | None]] = {}

    def birth_rows(self, keys: list[int], step: int) -> np.ndarray:
        """The resume state: per square of ``keys`` (sorted) its birth step, then one row
        holding the step count ``step`` ((q + 1, 1) int64)."""
        return np.array([*(self.births[k] for k in keys), step], dtype=np.int64).reshape(-1, 1)

    def restore_births(self, keys: list[int], rows: np.ndarray) -> int:
        """Set the births of the squares ``keys`` from :meth:`birth_rows`'s rows; returns the
        step count."""
        births = np.asarray(rows, dtype=np.int64).reshape(-1)
        if len(births) != len(keys) + 1:
            raise RunError("the saved surrogate state does not match its squares")
        self.births = dict(zip(keys, births[:-1].tolist(), strict=True))
        return int(births[-1])

    def _squares(self, last: int, first: int | None = None) -> np.ndarray:
        """Sorted keys of the squares born in [first, last] (first None: any before)."""
        low = -np.inf if first is None else first
        keys = [k for k, b in self.births.items() if low <= b <= last]
        return np.array(sorted(keys), dtype=np.int64)

    def interpolant(self, last: int) -> CellPolynomials | None:
        """J of the squares born up to step ``last`` (None: none)."""
        return self._lattice(last)[1]

    def _lattice(self, last: int) -> tuple:
        """The squares born up to step ``last``: their count, J (None: none), sorted keys of the
        squares and of their points, the points' bilinear surpluses, the new points' marks of
        :meth:`_near` (filled there) and the bilinear interpolant's stop squares (:meth:`_gate`);
        kept while no square is born up to ``last``."""
        last = max((b for b in self.births.values() if b <= last), default=-1)
        count = sum(b <= last for b in self.births.values())
        kept = self._cache.get(last)
        if kept is None or kept[0] != count:
            squares = self._squares(last)
            keys = np.unique(corner_keys(squares))
            smooth, surplus = None, np.zeros((0, 0))
            if len(keys):
                values, surplus = self._points(keys)
                smooth = CellPolynomials(SmoothLattice(keys, values), keys)
                earlier = [b for b in self._cache if b < last]
                older = kept or (self._cache[max(earlier)] if earlier else None)
                if older is not None and older[1] is not None:  # its points are a subset
                    smooth.inherit(older[1], marks(np.setdiff1d(keys, older[3])))
            self._cache[last] = kept = (count, smooth, squares, keys, surplus, {}, StopSquares())
        return kept

    def answer(
        self, ids: np.ndarray, s: np.ndarray, tol: np.ndarray, bilinear: np.ndarray,
        square: np.ndarray, step: int,
    ) -> np.ndarray:  # fmt: skip
        """The answers (n, m) at step ``step`` to queries (table numbers ids, stretches s,
        tolerances tol) whose bilinear answers and deepest built squares' keys are given."""
        values = self.interpolant(step).evaluate(ids, s)
        born = sorted(set(self.births.values()))
        active = [b for b in born if step - b < BLEND_STEPS]
        pairs = zip(born[:-1], born[1:], strict=True)  # each birth and the one before it
        needed = set(active) | {born[-1]} | {a for a, b in pairs if b in active}
        self._cache = {b: v for b, v in self._cache.items() if b in needed}
        terms = []  # per blending birth: it, the birth before it, its queries and gates
        for b in active:
            earlier = [a for a in born if a < b]
            if not earlier:
                continue  # the first squares: nothing to blend from
            near = np.flatnonzero(self._near(ids, s, b, earlier[-1]))
            if len(near):
                gate = self._gate(ids[near], s[near], tol[near], earlier[-1])
                terms.append((b, earlier[-1], near[gate > 0.0], gate[gate > 0.0]))
        if not terms:
            return self._guard(values, bilinear, square)
        wanted: dict[int, list[np.ndarray]] = {}  # each J needed, at the queries needing it
        for b, before, near, _ in terms:
            wanted.setdefault(before, []).append(near)
            wanted.setdefault(b, []).append(near)
        at = {}
        for cut, nears in wanted.items():
            where = np.unique(np.concatenate(nears))
            at[cut] = where, (values[where] if cut == born[-1]
                              else self.interpolant(cut).evaluate(ids[where], s[where]))
        for b, before, near, gate in terms:
            weight = smoothstep((step - b + 1) / (BLEND_STEPS + 1))
            old, new = (j[np.searchsorted(where, near)] for where, j in (at[before], at[b]))
            values[near] += ((1.0 - weight) * gate)[:, None] * (old - new)
        return self._guard(values, bilinear, square)

    def _near(self, ids: np.ndarray, s: np.ndarray, birth: int, before: int) -> np.ndarray:
        """Which queries lie within :data:`REACH` spacings of a point new at step ``birth``."""
        kept = self._lattice(birth)[5]
        if not kept:
            kept.update(marks(np.setdiff1d(self._lattice(birth)[3], self._lattice(before)[3])))
        near = np.zeros(len(ids), dtype=bool)
        for k, marked in kept.items():
            near |= find(marked, square_key(ids, k, cell(s, k)[0]))[1]
        return near

    def _gate(self, ids: np.ndarray, s: np.ndarray, tol: np.ndarray, before: int) -> np.ndarray:
        """The gate g (n,) of a birth's blend (module docstring) from the bilinear estimate e
        of the lattice of the squares born up to step ``before``, from its stop squares (the walk's
        to rounding, :mod:`~plantgrowth.unitcell.lattice`)."""
        _, _, squares, keys, surplus, _, stops = self._lattice(before)
        if not len(squares):
            return np.zeros(len(ids))
        found = stops.through(lambda: (squares, keys, surplus), ids, s)
        values, change, level = found["values"], found["change"], found["level"]
        error = np.full(len(ids), np.inf)
        error[(level == 0) & (cell(s, 0)[1] % 1.0 == 0.0).all(axis=1)] = 0.0
        inside = level >= 1
        if inside.any():
            part = values[inside]
            error[inside] = self._difference(part - change[inside], part)
        return smoothstep(np.clip((GATE * tol - error) / ((GATE - 1.0) * tol), 0.0, 1.0))

    def _guard(self, values: np.ndarray, bilinear: np.ndarray, square: np.ndarray) -> np.ndarray:
        """The SPD guard (module docstring): the bilinear answer where the C1 one fails it."""
        if self.voigt is None or not len(values):
            return values
        squares, index = np.unique(square, return_inverse=True)
        corners = corner_keys(squares)
        exact = self._points(corners.ravel())[0]
        bound = SPD_FRACTION * ratios(exact, self.voigt).reshape(-1, 4).min(axis=1)
        bad = ratios(values, self.voigt) < bound[index.ravel()]
        if bad.any():
            self.guarded += int(bad.sum())
            log.info("c1 surrogate: %d answers failed the SPD guard, bilinear answers taken "
                     "(%d so far)", int(bad.sum()), self.guarded)  # fmt: skip
            values[bad] = bilinear[bad]
        return values
