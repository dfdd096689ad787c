"""The C1 interpolant's answers from cached cell polynomials (issue 33, docs/surrogate_c1.md).

On a level-k cell Q of the lattice (side h_k = H0 / 2^k) that no kernel of a finer point
reaches, J (:class:`~plantgrowth.unitcell.smooth_lattice.SmoothLattice`) is one bicubic,

    J(s) = sum_{a,b = 0..3} c_ab t1^a t2^b,   t = s's coordinates in Q, in [0, 1]^2,

since every level j <= k's kernels are cubic in each variable on the level-j cell holding Q.
A query's *stop cell* is the coarsest such cell holding it: its level-k cell for the first k
that is not *reached*, i.e. met by the open support ``|s - p|_inf < 2 h_j`` of any point p
of a level j > k (the cells so met are listed per level when J is built). The 16
coefficients of a stop cell are found once, from J at the 4 x 4 points t in {0, 1/3, 2/3, 1}^2
(the inverse of the tensor-product Vandermonde matrix), and kept while J lives (a refinement
makes a new J and so a new cache). A query then costs one lookup per level down to its stop
cell, one cache lookup and a 16-term product, instead of 16 lookups per level. The answer is
J's to rounding and depends only on the stop cell and J: the same on every rank, and the same
whatever was cached before (exact resume).
"""

from __future__ import annotations

import numpy as np

from plantgrowth.unitcell.lattice import STEP, combine, find, key_integers, place, square_key
from plantgrowth.unitcell.smooth_lattice import SmoothLattice, point_level

SAMPLES = np.array([0.0, 1.0, 2.0, 3.0]) / 3.0
POWERS = np.array([[a, b] for a in range(4) for b in range(4)])  # (16, 2): t1^a t2^b
GRID = np.array([[x, y] for x in SAMPLES for y in SAMPLES])  # (16, 2) sample points
FIT = np.linalg.inv(np.prod(GRID[:, None, :] ** POWERS[None], axis=-1))
"""Coefficients from the 16 samples: ``c = FIT @ J(GRID)`` (condition number about 300)."""


def reached(keys: np.ndarray) -> list[np.ndarray]:
    """Per level k, the sorted keys (:func:`~plantgrowth.unitcell.lattice.square_key`) of the
    level-k cells met by the support of a point (keys (P,)) of a finer level."""
    ids = keys >> 42
    ij = key_integers(keys)
    level = point_level(ij)
    out = []
    for k in range(int(level.max(initial=0))):
        fine = level > k
        side, reach = STEP >> k, 2 * (STEP >> level[fine])[:, None]
        low = (ij[fine] - reach) // side  # the first cell met (open support)
        high = -(-(ij[fine] + reach) // side) - 1  # the last
        found = []
        for dx in range(3):
            for dy in range(3):
                cells = low + np.array([dx, dy])
                ok = (cells <= high).all(axis=1)
                found.append(square_key(ids[fine][ok], k, cells[ok] * side))
        out.append(np.unique(np.concatenate(found)))
    return out


class CellPolynomials:
    """J's answers by stop cells and their cached bicubic coefficients (module docstring)."""

    def __init__(self, lattice: SmoothLattice, keys: np.ndarray) -> None:
        self.lattice = lattice
        self._reached = reached(np.asarray(keys, dtype=np.int64))
        self._keys = np.zeros(0, dtype=np.int64)  # sorted stop cells' keys
        self._coefficients = np.zeros((0, 16, lattice.width))

    def evaluate(self, ids: np.ndarray, s: np.ndarray) -> np.ndarray:
        """J at n queries (tables' numbers ids (n,), stretches s (n, 2)): (n, m)."""
        ids = np.asarray(ids, dtype=np.int64)
        x = place(np.asarray(s, dtype=float).reshape(len(ids), 2))
        level = np.zeros(len(ids), dtype=np.int64)
        alive = np.arange(len(ids))
        for k, cells in enumerate(self._reached):
            key = square_key(ids[alive], k, np.floor(x[alive] * 2.0**k).astype(np.int64)
                             * (STEP >> k))  # fmt: skip
            alive = alive[find(cells, key)[1]]
            level[alive] = k + 1
        scaled = x * 2.0 ** level[:, None]  # exact: a power of 2
        base = np.floor(scaled)
        t = scaled - base
        key = square_key(ids, level, base.astype(np.int64) * (STEP >> level)[:, None])
        rows, there = find(self._keys, key)
        if not there.all():
            self._learn(np.unique(key[~there]))
            rows = find(self._keys, key)[0]
        one = np.ones(len(t))
        p1, p2 = (np.column_stack([one, x, x * x, x * x * x]) for x in (t[:, 0], t[:, 1]))
        weights = (p1[:, :, None] * p2[:, None, :]).reshape(-1, 16)  # t1^a t2^b, POWERS' order
        table = self._coefficients.reshape(-1, self._coefficients.shape[2])
        return combine(weights, rows[:, None] * 16 + np.arange(16)[None], table)

    def inherit(self, older: CellPolynomials, changed: dict[int, np.ndarray]) -> None:
        """Take over the coefficients of ``older`` (a J of a subset of this one's points) on
        the cells that meet none of the ``changed`` cells (per level l, sorted keys of the
        level-l cells where the points added since change J): J is the same there, bit for
        bit (the same terms in the same order; a cell no longer a stop cell is never asked)."""
        keys = older._keys
        ids, level = keys >> 46, (keys >> 42) & 15
        corner = key_integers(keys)
        hit = np.zeros(len(keys), dtype=bool)
        for k, marked in changed.items():
            side = STEP >> k
            finer = level >= k  # the entry's level-k ancestor is marked
            hit[finer] |= find(marked, square_key(ids[finer], k, corner[finer] // side * side))[1]
            coarse = np.flatnonzero(~finer)  # a marked level-k cell lies inside the entry
            if len(coarse):
                m_ids = marked >> 46
                m_corner = key_integers(marked)
                for j in np.unique(level[coarse]).tolist():
                    big = STEP >> j
                    inside = np.unique(square_key(m_ids, j, m_corner // big * big))
                    own = coarse[level[coarse] == j]
                    hit[own] |= find(inside, keys[own])[1]
        self._keys, self._coefficients = keys[~hit], older._coefficients[~hit]

    def _learn(self, cells: np.ndarray) -> None:
        """The coefficients of new stop cells (keys), from J at their 4 x 4 sample points."""
        ids, level = cells >> 46, (cells >> 42) & 15
        corner = key_integers(cells)
        points = corner[:, None, :] / STEP + GRID[None] / 2.0 ** level[:, None, None]
        samples = self.lattice.at(np.repeat(ids, 16), points.reshape(-1, 2))
        coefficients = np.einsum("ij,qjm->qim", FIT, samples.reshape(len(cells), 16, -1))
        keys = np.concatenate([self._keys, cells])
        order = np.argsort(keys)
        self._keys = keys[order]
        self._coefficients = np.concatenate([self._coefficients, coefficients])[order]
