"""The surrogate's C1 answers: refinements blended in over steps, and the SPD guard (issue 33,
``accuracy.cell_interpolant = "c1"``, docs/surrogate_c1.md).

Every built square has a *birth*, the step in which it was built, and every lattice point the
earliest birth of the squares it is a corner of. The answer is one C1 interpolant J
(:class:`~plantgrowth.unitcell.smooth_lattice.SmoothLattice`) of every point built so far,
each point with a *blended value*: at step c, a point p born at step b with c - b < B
(:data:`BLEND_STEPS`) takes

    f~(p) = J_<b(p) + w_p (f(p) - J_<b(p)),
    w_p = x^2 (3 - 2 x),   x = min(1, (c - b + 1) / (L_p + 1)),   L_p = round(B / max(1, m_p)),

where f(p) is its exact value, J_<b the interpolant of the points born before b (with their
own blended values, births taken in order) and m_p = |f(p) - J_<b(p)| / tol the miss in
tolerances (relative, the surrogate's segments); older points take f. Since J's kernels are
cardinal, a point whose value is J_<b(p) has a zero surplus and changes nothing: each
refinement enters along a smoothstep, and J is C1 in s at every step (one interpolant, linear
in the values). A point J_<b met within the tolerance enters over B steps; one it missed by m
tolerances over B / m (its value moves by about a tolerance per step) and from 16 tolerances
at once (L_p = 0). A new point that the interpolant of the taken points born before it, with
their exact values, already meets to :data:`DECLINE` times the tolerance is *declined*: not
taken into J at all (the bilinear lattice keeps it for its estimates). Refinement is decided by
the bilinear estimate, which J beats by far, so most refinements would otherwise move J by a
few hundredths of the tolerance, each move costing the macro CG iterations (its initial guess
cannot predict it). The verdict is fixed at the point's birth. J is rebuilt when a
square is born or a blend moves (a few hundred points: milliseconds), and its cells' bicubic
coefficients (:class:`~plantgrowth.unitcell.smooth_cells.CellPolynomials`) are carried over
outside :data:`REACH` of the points whose values changed, so a step costs one evaluation of J
at the queries. Everything here is a function of the shared tables (the squares, their births,
the step): the same on every rank, and a resumed run (births and the step saved,
:meth:`LatticeSurrogate.births`) answers as the straight one.

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
from plantgrowth.base.tensors import extreme_eigenvalues_sym3
from plantgrowth.unitcell.lattice import (
    OFFSETS,
    STEP,
    key_integers,
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
REACH = (6, 3)
"""Spacings of its level around a point of level 0, and of a finer level, outside which adding
it or changing its value leaves J unchanged bit for bit: a level-l point's kernel reaches 2 h_l
and the finer surpluses it changes 1 h_l more (3); a level-0 point also changes the ghosts
3 h_0 around it (quadratic extrapolation from three points in a row), whose kernels reach 2 h_0
more (6)."""
DECLINE = 0.5
"""A new point is declined (module docstring) where the taken points' interpolant misses its
exact value by at most DECLINE times the tolerance: J stays within that of it. On the organ
scene the new points' misses fell in two groups, 0.03-0.48 and from 0.96 tolerances (every
threshold between gives the same run): with the declines and the blend lengths B / m, 3 steps
from step 16 on above 6 CG iterations (at most 8), 322 in all, against 6 steps and 343 (with
the quadratic ghosts too: none, 280); on gradient_E_strain forced to CG none above 6, 289
against 310 (docs/surrogate_c1.md)."""
SPD_FRACTION = 0.5
"""The SPD guard's bound, a fraction of the corners' smallest lambda_min / lambda_max."""


def smoothstep(x: float | np.ndarray) -> float | np.ndarray:
    """``x^2 (3 - 2 x)`` on [0, 1]: the new interpolant's share."""
    return x * x * (3.0 - 2.0 * x)


def blend_share(miss: np.ndarray, age: int) -> np.ndarray:
    """w_p (P,) of new points ``age`` steps after their birth (0 at it) whose interpolant
    before them missed their values by ``miss`` tolerances (module docstring)."""
    length = np.round(BLEND_STEPS / np.maximum(miss, 1.0))
    return smoothstep(np.minimum((age + 1) / (length + 1), 1.0))


def corner_keys(squares: np.ndarray) -> np.ndarray:
    """The point keys (q, 4) of squares' corners (square keys (q,))."""
    ids, level, corner = square_corners(squares)
    points = corner[:, None, :] + OFFSETS[None] * (STEP >> level)[:, None, None]
    return point_key(ids[:, None], points[..., 0], points[..., 1])


def places(keys: np.ndarray) -> np.ndarray:
    """The places (P, 2) of lattice points (point keys (P,)) in level-0 spacings, as
    :meth:`~plantgrowth.unitcell.smooth_lattice.SmoothLattice.at` takes them (exact)."""
    return key_integers(keys) / STEP


def marks(new: np.ndarray) -> dict[int, np.ndarray]:
    """Per level k, the sorted keys of the level-k cells within :data:`REACH` of a new point
    of level k (point keys ``new``): where J changes when they are added."""
    ij = key_integers(new)
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
    smallest, largest = extreme_eigenvalues_sym3(0.5 * (C + np.swapaxes(C, 1, 2)))
    return smallest / np.maximum(largest, 1e-300)


class SmoothAnswers:
    """The C1 path's answers over a surrogate's squares (module docstring).

    Args:
        points: ``points(keys)`` the exact values (P, m) and bilinear surpluses (P, m) of
            lattice points (point keys (P,)).
        difference: the surrogate's relative difference per row (its segments).
        tolerance: the surrogate's tolerance, the unit of the new points' misses.
        voigt: the slice of the packed values holding E_hom's Voigt matrix (None: no guard).
    """

    def __init__(
        self, points: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
        difference: Callable[[np.ndarray, np.ndarray], np.ndarray], tolerance: float,
        voigt: slice | None,
    ) -> None:  # fmt: skip
        self._points = points
        self._difference = difference
        self.tolerance = tolerance
        self.voigt = voigt
        self.births: dict[int, int] = {}  # square key -> its step
        self.guarded = 0  # answers the SPD guard replaced so far
        self._kept: tuple | None = None  # (births' count and blend ages, keys, values, J)
        self._taken: dict[int, bool] = {}  # point key -> taken into J (False: declined)

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
        self._kept = None  # J of other births
        self._taken = {}  # the verdicts are recomputed from the births, in order
        return int(births[-1])

    def answer(
        self, ids: np.ndarray, s: np.ndarray, bilinear: np.ndarray, square: np.ndarray,
        step: int,
    ) -> np.ndarray:  # fmt: skip
        """The answers (n, m) at step ``step`` to queries (table numbers ids, stretches s)
        whose bilinear answers and deepest built squares' keys are given."""
        smooth = self.interpolant(step)
        if smooth is None:  # no point built: the bilinear answers (a query builds its square)
            return bilinear
        return self._guard(smooth.evaluate(ids, s), bilinear, square)

    def interpolant(self, step: int) -> CellPolynomials | None:
        """J of every point built up to step ``step`` with its blended value (module
        docstring; None: no point); kept while neither the squares nor the blend change, and
        its cells' coefficients carried over outside the reach of the points whose values
        changed."""
        births = {k: b for k, b in self.births.items() if b <= step}
        if not births:
            return None
        blending = tuple(sorted({b for b in births.values() if step - b < BLEND_STEPS}))
        state = (len(births), tuple((b, step - b) for b in blending))
        if self._kept is not None and self._kept[0] == state:
            return self._kept[3]
        squares = np.array(sorted(births), dtype=np.int64)
        corners = corner_keys(squares)  # (q, 4)
        born = np.repeat(np.array([births[k] for k in squares.tolist()]), 4)
        keys, inverse = np.unique(corners.ravel(), return_inverse=True)
        point_birth = np.full(len(keys), np.iinfo(np.int64).max)
        np.minimum.at(point_birth, inverse, born)
        exact = self._points(keys)[0]
        taken = self._verdicts(keys, point_birth, exact)
        keys, point_birth, values = keys[taken], point_birth[taken], exact[taken]
        for b in blending:  # in birth order: each blends in against the ones before it
            new, before = point_birth == b, point_birth < b
            if not before.any():
                continue  # the first points: nothing to blend from
            old = SmoothLattice(keys[before], values[before])
            previous = old.at(keys[new] >> 42, places(keys[new]))
            share = blend_share(self._difference(previous, values[new]) / self.tolerance, step - b)
            values[new] = previous + share[:, None] * (values[new] - previous)
        smooth = CellPolynomials(SmoothLattice(keys, values), keys)
        if self._kept is not None:
            _, old_keys, old_values, older = self._kept
            common, here, there = np.intersect1d(keys, old_keys, return_indices=True)
            same = (values[here] == old_values[there]).all(axis=1)
            changed = np.setdiff1d(keys, common[same])
            if len(changed) < len(keys):  # J is the same bits away from the changed points
                smooth.inherit(older, marks(changed))
        self._kept = (state, keys, values, smooth)
        return smooth

    def _verdicts(
        self, keys: np.ndarray, point_birth: np.ndarray, exact: np.ndarray
    ) -> np.ndarray:
        """(P,) whether each point (keys, births, exact values) is taken into J
        (:data:`DECLINE`), decided birth by birth in order for the points not decided yet."""
        undecided = np.array([k not in self._taken for k in keys.tolist()], dtype=bool)
        if undecided.any():
            for b in np.unique(point_birth[undecided]).tolist():
                new = undecided & (point_birth == b)
                taken = np.array([self._taken.get(k, False) for k in keys.tolist()], dtype=bool)
                before = taken & (point_birth < b)
                verdict = np.ones(int(new.sum()), dtype=bool)
                if before.any():
                    old = SmoothLattice(keys[before], exact[before])
                    miss = self._difference(old.at(keys[new] >> 42, places(keys[new])), exact[new])
                    verdict = miss > DECLINE * self.tolerance
                self._taken.update(zip(keys[new].tolist(), verdict.tolist(), strict=True))
        return np.array([self._taken[k] for k in keys.tolist()], dtype=bool)

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
