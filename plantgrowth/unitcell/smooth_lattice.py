"""A C1 interpolant over the surrogate's lattice points (issue 33, prototype: docs/surrogate_c1.md).

The same built points as :class:`~plantgrowth.unitcell.surrogate.LatticeSurrogate`'s bilinear
interpolant, no other cell solve; each level's bilinear hat replaced by the tensor-product Keys
(Catmull-Rom) cubic of that level's spacing h_l = H0 / 2^l,

    J(s) = sum_l sum_p beta_p K((s1 - p1) / h_l) K((s2 - p2) / h_l),
    K(x) = 3/2 |x|^3 - 5/2 |x|^2 + 1 (|x| <= 1),  -1/2 |x|^3 + 5/2 |x|^2 - 4 |x| + 2 (1 < |x| < 2),

K is C1, cardinal (K(0) = 1, K(k) = 0 at the other integers) and reproduces quadratics on a
full grid. The coefficients are hierarchical surpluses against the C1 interpolant of the coarser
levels, ``beta_p = f(p) - J_<l(p)`` for a point new on level l >= 1 (zero where no point is
built); on level 0, ``beta_p = f(p)`` at the built points and, at the unbuilt level-0 nodes next
to them (Chebyshev distance 1: every node the stencil of a query in a built square needs),
a *ghost*: the mean over the eight directions d with p + d, p + 2d and p + 3d built of the
quadratic extrapolation ``3 f(p + d) - 3 f(p + 2d) + f(p + 3d)``, or where no direction has
three, over those with p + d and p + 2d of the linear ``2 f(p + d) - f(p + 2d)``. J reproduces
linear functions on the built level-0 squares, and quadratics where every ghost a square's
stencil reaches is quadratic (as the Keys kernel does on a full grid). With linear ghosts
alone, J at the lattice's frontier was only as good as a linear fit: on the organ scene two
frontier points of step 51 were missed by 5.4 tolerances, and the macro CG needed 8
iterations there against at most 6 with quadratic ghosts (docs/surrogate_c1.md). Finer
kernels vanish at every coarser and same-level point, so J equals f at every built point; J
is a fixed finite sum of C1 functions, so it is C1 in s (piecewise bicubic on the finest built
lattice). It depends only on the shared points and values (serial = mpirun) and is evaluated
per query by 16 key lookups per level.
"""

from __future__ import annotations

import numpy as np

from plantgrowth.unitcell.lattice import (
    MAX_LEVEL,
    STEP,
    combine,
    find,
    key_integers,
    place,
    point_key,
)

DIRECTIONS = np.array([[1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [1, -1], [-1, 1], [-1, -1]])
STENCIL = np.array([[a, b] for a in range(-1, 3) for b in range(-1, 3)])  # (16, 2)


def keys_kernel(x: np.ndarray) -> np.ndarray:
    """The Keys cubic convolution kernel (a = -1/2, module docstring): C1, cardinal."""
    r = np.abs(x)
    inner = (1.5 * r - 2.5) * r * r + 1.0
    outer = ((-0.5 * r + 2.5) * r - 4.0) * r + 2.0
    return np.where(r <= 1.0, inner, np.where(r < 2.0, outer, 0.0))


def point_level(ij: np.ndarray) -> np.ndarray:
    """The level on which each lattice point (finest integers, (P, 2)) is new."""
    level = np.full(len(ij), MAX_LEVEL)
    for k in range(MAX_LEVEL, -1, -1):
        level[~(ij % (STEP >> k)).any(axis=1)] = k
    return level


class SmoothLattice:
    """The C1 interpolant J of the points ``keys`` (point keys of
    :func:`~plantgrowth.unitcell.lattice.point_key`, (P,)) with exact values (P, m)."""

    def __init__(self, keys: np.ndarray, values: np.ndarray) -> None:
        keys = np.asarray(keys, dtype=np.int64)
        values = np.asarray(values, dtype=float)
        ids = keys >> 42
        ij = key_integers(keys)
        level = point_level(ij)
        self.width = values.shape[1]  # m, the packed values' length
        self.levels: list[tuple[np.ndarray, np.ndarray]] = []  # per level: sorted keys, beta
        for k in range(int(level.max()) + 1 if len(keys) else 0):
            own = level == k
            if k == 0:
                table = self._with_ghosts(ids[own], ij[own], values[own])
            else:
                below = self.at(ids[own], ij[own] / STEP)  # exact places
                table = (keys[own], values[own] - below)
            order = np.argsort(table[0])
            self.levels.append((table[0][order], table[1][order]))

    @staticmethod
    def _with_ghosts(
        ids: np.ndarray, ij: np.ndarray, values: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Level 0's keys and coefficients: the built points' values and the ghosts (module
        docstring) of the unbuilt nodes next to them."""
        nodes = ij // STEP
        keys = point_key(ids, ij[:, 0], ij[:, 1])
        order = np.argsort(keys)
        known = keys[order]
        ring = (nodes[:, None, :] + DIRECTIONS[None]).reshape(-1, 2)
        ring_ids = np.repeat(ids, len(DIRECTIONS))
        ring_keys = point_key(ring_ids, ring[:, 0] * STEP, ring[:, 1] * STEP)
        ring_keys, pick = np.unique(ring_keys, return_index=True)
        missing = ~find(known, ring_keys)[1]
        g_ids, g = ring_ids[pick][missing], ring[pick][missing]
        values = values[order]
        total = np.zeros((2, len(g), values.shape[1]))  # quadratic, linear extrapolations
        count = np.zeros((2, len(g)))
        for d in DIRECTIONS:
            rows, there = zip(*(find(known, point_key(g_ids, (g[:, 0] + k * d[0]) * STEP,
                                                      (g[:, 1] + k * d[1]) * STEP))
                                for k in (1, 2, 3)), strict=True)  # fmt: skip
            v = [values[r] for r in rows]
            quad = there[0] & there[1] & there[2]
            line = there[0] & there[1] & ~there[2]
            total[0][quad] += (3.0 * v[0] - 3.0 * v[1] + v[2])[quad]
            total[1][line] += (2.0 * v[0] - v[1])[line]
            count[0] += quad
            count[1] += line
        if np.any(count.sum(axis=0) == 0):
            raise ValueError("a level-0 ghost node without two built points in a row")
        quadratic = count[0] > 0
        ghost = np.where(quadratic[:, None], total[0] / np.maximum(count[0], 1)[:, None],
                         total[1] / np.maximum(count[1], 1)[:, None])  # fmt: skip
        ghost_keys = point_key(g_ids, g[:, 0] * STEP, g[:, 1] * STEP)
        return (np.concatenate([known, ghost_keys]),
                np.vstack([values, ghost]))  # fmt: skip

    def evaluate(self, ids: np.ndarray, s: np.ndarray) -> np.ndarray:
        """J at n queries (tables' numbers ids (n,), stretches s (n, 2)): (n, m), by the walk
        over every level (:meth:`at`; the reference for :class:`CellPolynomials`)."""
        ids = np.asarray(ids, dtype=np.int64)
        return self.at(ids, place(np.asarray(s, dtype=float).reshape(len(ids), 2)))

    def at(self, ids: np.ndarray, x: np.ndarray) -> np.ndarray:
        """J at queries given by their places x (n, 2), s / H0 (:func:`lattice.place`)."""
        out = np.zeros((len(ids), self.width))
        for k, (keys, beta) in enumerate(self.levels):
            if not len(keys):
                continue
            y = x * 2.0**k  # exact: a power of 2
            base = np.floor(y)
            t = y - base
            nodes = base.astype(np.int64)[:, None, :] + STENCIL[None]  # (n, 16, 2)
            wanted = point_key(ids[:, None], nodes[..., 0] * (STEP >> k),
                               nodes[..., 1] * (STEP >> k))  # fmt: skip
            rows, there = find(keys, wanted)
            weights = keys_kernel(t[:, None, 0] - STENCIL[None, :, 0]) * keys_kernel(
                t[:, None, 1] - STENCIL[None, :, 1]
            )
            out += combine(np.where(there, weights, 0.0), rows, beta)
        return out
