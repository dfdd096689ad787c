"""The director's angle as a dimension of the surrogate (issue 22, item 3; issue 33, item 2).

A fibred cell problem depends on the director's angle relative to the growth's rotation,
``b = (a - rotation) mod 180`` (periodic: a director is an axis). With feedback the angles are
continuous, so tables keyed by each exact angle would be solved anew for every fine cell and
step. Instead, each fibred table (geometry, nu, fibre_stiffness) is interpolated in b by the
trigonometric interpolant of period 180 degrees through N equispaced nodes ``b_j = j 180 / N``,

    I(b) = sum_j l_j(b) f(b_j),   l_j(b) = sin(N d / 2) cos(d / 2) / (N sin(d / 2)),
    d = 2 pi (b - b_j) / 180,

(N even; l_j(b_j) = 1, l_j(b_k) = 0): smooth, periodic by construction (d -> d + 2 pi leaves
l_j unchanged), and for the smooth periodic angle dependence of the cell tensors it converges
spectrally, so it needs far fewer nodes than the piecewise-linear interpolant it replaces
(measured in benchmarks/results/angle_nodes.json). A node is a table of the stretch surrogate
(:mod:`plantgrowth.unitcell.surrogate`), its angle an integer index of ``ANGLE_STEP`` degrees.

A table is a sparse grid in (b, s) (:mod:`plantgrowth.unitcell.angle_surplus`):

    A(b, s) = I_M[S](b, s) + (I_2M - I_M)[P_1 f](b, s) + (I_4M - I_2M)[P_0 f](b, s),

where only the M fine nodes hold stretch tables S refined to the tolerance (each to its
:func:`node_tolerance` by its weight in I_M), and the angle surpluses of the 3M nodes each
doubling adds are taken on the coarse stretch grids of levels 1 and 0 (P_l: bilinear on the
lattice's own points of spacing ``H0 / 2^l``). A is continuous in (b, s) (trigonometric in b,
bilinear or the stretch interpolant in s) and 180-degree periodic. M is one per table,
``6 2^L``. It is chosen in the refine phase of a call, before the answers: the estimate of a
query is the larger of the last surplus term (the angle's: about the error of I_2M, far above
the error of A, which is about I_4M's) and the change the level-1 grid made to the first
surplus term (the stretch's: about three times the error that P_1 leaves there); the table's L
goes up while the largest estimate over its queries (all ranks) exceeds the tolerance, and,
once raised in a call, while it exceeds ``KEEP`` times it (the gap of
:mod:`plantgrowth.unitcell.surrogate`).

Near a fine node b_k (within the second distance of :func:`near_node_zone`) the answer is

    A_k(b, s) = S_k(s) + (I_M - I_k)[P_0 f](b, s),

node k's own table plus the angle interpolant's change on the M nodes' level-0 stretch grid
(I_k: the constant at node k), blended into A with a C1 step in the distance to the node (A
alone beyond the zone, A_k alone within its first distance). A_k is A's first-order term
in b - b_k with the other nodes' tables and the surplus terms, all of weight O(b - b_k), taken
on the coarse grid: a director a hair off a node (a fixed director turned by the growth's
rotation) asks one stretch table instead of M and none of the surplus grids.

The cardinal functions change sign, so E_hom is no longer a non-negative combination of SPD
tensors; it stays SPD because it is within the tolerance (1e-3 relative) of the exact tensors,
whose smallest eigenvalue is about 1e-2 of their norm (the honeycomb's G12 / E1).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np
from mpi4py import MPI

from plantgrowth.unitcell import angle_surplus
from plantgrowth.unitcell.lattice import by_rows
from plantgrowth.unitcell.surrogate import KEEP, Answer, Point

H0_ANGLE = 15.0
"""The angle unit of the node indices (degrees; 12 per 180), unchanged since the cache's
angle-node keys were made with it."""
MAX_ANGLE_LEVEL = 10
"""Finest level of the nodes' index unit (12 288 per 180 degrees, 0.0146 degrees apart)."""
ANGLE_STEP = H0_ANGLE / 2**MAX_ANGLE_LEVEL
"""Degrees per integer index of a node's angle."""
FINE_NODES = 6
"""M at L = 0: 6 nodes 30 degrees apart hold stretch tables refined to the tolerance. The fewest
within the tolerance: with the same surplus grids M = 5 (odd, no Nyquist term) errs by 1.3e-3,
M = 4 by 2.8e-3, M = 3 by 3.2e-3 (scripts/benchmarks/bench_angle_sparse.py; docs/fibres.md)."""
SURPLUS_TERMS = ((2, 1), (4, 0))
"""The surplus terms (I_{kM} - I_{kM/2})[P_l f] as (k, l): the 2M nodes on the level-1
stretch grid, the 4M nodes on the level-0 grid (:mod:`plantgrowth.unitcell.angle_surplus`).
Measured for the reference cell at E_f/E = 5, s in [0, 0.15] x [-0.015, 0.04], b in
[65, 120]: largest error 2.9e-4 with M = 6 (I_6 alone 1.7e-2, I_12 7.7e-4, I_24 1.9e-7;
scripts/benchmarks/bench_angle_sparse.py)."""
LEVEL_CAP = 4
"""Largest L a table is refined to: M = 96 fine nodes (1.9 degrees apart, 384 on the level-0
grid); every query away from a node asks every fine node, so an estimate that does not
converge (a map that is not smooth in the angle) must not take the count on to 12 288."""
NEAR_NODE = (0.05, 0.1)
"""Distances to the nearest fine node (degrees) at a tolerance of 1e-3, between which the
near-node form A_k (module docstring) is blended into A; they scale with the tolerance
(:func:`near_node_zone`). A_k's error is first order in the distance d: 2.0e-3 d (degrees) at
most, 13% of the exact map's own change, on the reference cell at E_f/E = 5 with M = 6
(scripts/benchmarks/bench_near_node.py, benchmarks/results/near_node.json: 1.0e-4 at 0.05
degrees, 2.0e-4 at 0.1). So A_k alone errs by at most a tenth of the tolerance, and in the
blend zone its share (1 - w) of at most 2e-4 keeps that bound. The fibred gradient scene with
a fixed director (fibre_angle 90) turns its directors off node 90 by 0.028 degrees at most
over its 61 steps: A_k answers every query, no surplus grid is asked (docs/fibres.md)."""
NEAR_NODE_WIDEST = 1.0 / 30.0
"""The widest zone's outer distance, in spacings of the fine nodes (1 degree at M = 6, the
zone of a tolerance of 1e-2): A_k is A's first-order term, not an answer across the spacing."""
PERIOD = round(180.0 / ANGLE_STEP)
"""Node indices per 180 degrees (index PERIOD is index 0)."""


def trigonometric_weights(b: np.ndarray, count: int) -> np.ndarray:
    """The cardinal functions l_j(b) (n, count) of the trigonometric interpolant of period 180
    degrees through ``count`` (even) nodes ``j 180 / count``, at angles b (n,) in degrees
    (module docstring). An angle within 1e-9 node spacings of a node takes that node alone."""
    x = np.asarray(b, dtype=float) / (180.0 / count)
    node = np.round(x)
    hit = np.abs(x - node) <= 1e-9  # a round-off away from a node: that node
    d = np.pi * (x[:, None] - np.arange(count)[None, :]) / count  # d / 2 of the docstring
    safe = np.where(hit[:, None], 1.0, np.sin(d))
    weights = np.sin(count * d) * np.cos(d) / (count * safe)
    weights[hit] = np.arange(count)[None, :] == (node[hit, None] % count)
    return weights


def near_node_zone(tolerance: float, count: int) -> tuple[float, float]:
    """The distances to one of ``count`` fine nodes (degrees) within which the near-node form
    answers alone and beyond which A does: :data:`NEAR_NODE` times ``tolerance / 1e-3`` (A_k's
    error is linear in the distance, so a tenth of any tolerance at the first), scaled down
    to at most :data:`NEAR_NODE_WIDEST` of the spacing."""
    scale = min(tolerance / 1e-3, NEAR_NODE_WIDEST * 180.0 / count / NEAR_NODE[1])
    return NEAR_NODE[0] * scale, NEAR_NODE[1] * scale


def near_node_blend(
    b: np.ndarray, count: int, tolerance: float
) -> tuple[np.ndarray, np.ndarray]:
    """Per angle b (n,): the nearest of ``count`` equispaced nodes and the weight of A in the
    blend with the near-node form (module docstring): 0 within the first distance of
    :func:`near_node_zone` of it, 1 beyond the second, the C1 step ``3 t^2 - 2 t^3`` between."""
    spacing = 180.0 / count
    x = np.asarray(b, dtype=float) / spacing
    node = np.round(x)
    low, high = near_node_zone(tolerance, count)
    t = np.clip((np.abs(x - node) * spacing - low) / (high - low), 0.0, 1.0)
    return node.astype(np.int64) % count, t * t * (3.0 - 2.0 * t)


def node_tolerance(tolerance: float, weight: np.ndarray) -> np.ndarray:
    """The relative tolerance a node's stretch interpolation is asked for, given its weight w in
    the angle interpolant: ``tolerance / |w|``, at most 1. A node's stretch error enters the
    answer times w, so each node's term ``|w| e`` is held to the tolerance, as the stretch
    surrogate holds a query's estimate; a node of small weight is not refined for nothing.
    The rule before, ``tolerance / min(1, 2 |w|)``, held the nearest nodes to the tolerance
    itself and the others to half of it: 733 solves on the stress feedback scene against 590,
    with its exact checks at 2.6e-4 and 2.0e-4 (docs/fibres.md)."""
    return np.minimum(tolerance / np.clip(np.abs(weight), 1e-300, 1.0), 1.0)


class DirectorInterpolant:
    """The angle interpolants of the fibred tables, their node counts kept across calls.

    Args:
        evaluate: the stretch surrogate, ``evaluate(tables, which, s, tolerance)``
            (collective), a fibred table's node being the table plus its angle index.
        difference: the relative difference per row of two (n, m) value arrays.
        tolerance: the surrogate's relative tolerance.
        comm: the ranks that share the tables.
        values: the stretch surrogate's exact lattice values, ``values[node table, point]``
            (read for the grids' corners, which ``evaluate`` has built).
    """

    def __init__(
        self,
        evaluate: Callable[[list[tuple], np.ndarray, np.ndarray, np.ndarray], Answer],
        difference: Callable[[np.ndarray, np.ndarray], np.ndarray],
        tolerance: float,
        comm: MPI.Comm,
        values: Mapping[Point, np.ndarray],
    ) -> None:
        self._evaluate = evaluate
        self._values = values
        self._difference = difference
        self.tolerance = tolerance
        self.comm = comm
        self.levels: dict[tuple, int] = {}  # fibred table -> L (M = 6 2^L fine nodes)

    def state(self) -> np.ndarray:
        """The tables' levels as int64 rows ``[table..., L]`` (a resumed run's :meth:`restore`)."""
        rows = [(*table, level) for table, level in sorted(self.levels.items())]
        return np.array(rows, dtype=np.int64).reshape(len(rows), 7)  # 6 table entries, L

    def restore(self, rows: np.ndarray) -> None:
        """The levels of :meth:`state`'s rows."""
        self.levels = {tuple(row[:-1]): row[-1] for row in rows.tolist()}

    def count(self, table: tuple) -> int:
        """The table's fine node count M."""
        return FINE_NODES * 2 ** self.levels.get(table, 0)

    def __call__(
        self, tables: Sequence[tuple], which: np.ndarray, s: np.ndarray, b: np.ndarray
    ) -> Answer:
        """Collective: the answers to this rank's queries, query k asking ``tables[which[k]]``
        at stretch ``s[k]`` and, for a fibred table (more than 5 entries), angle ``b[k]``
        (degrees); an isotropic table is asked once, as it is. The fibred tables' node counts
        are refined first (module docstring); the answers come from the last round's nodes."""
        n = len(which)
        which = np.asarray(which, dtype=np.int64).reshape(n)
        s, b = np.asarray(s, dtype=float).reshape(n, 2), np.asarray(b, dtype=float).reshape(n)
        fibred_table = np.array([len(table) > 5 for table in tables], dtype=bool)
        plain = np.flatnonzero(~fibred_table[which])
        groups = {tables[t]: np.flatnonzero(which == t) for t in np.flatnonzero(fibred_table)}
        groups = {table: queries for table, queries in groups.items() if len(queries)}
        every = sorted(set().union(*self.comm.allgather(set(groups))))
        raised: set[tuple] = set()
        solves = 0
        while True:
            answer, layout = self._ask(tables, which, s, b, groups, plain)
            solves += answer.solves
            values, estimates, interpolated = self._combine(answer, layout, b, plain, n)
            local = np.array([estimates[groups[t]].max() if t in groups else 0.0 for t in every])
            largest = np.max(self.comm.allgather(local), axis=0)
            grow = [
                table for table, e in zip(every, largest.tolist(), strict=True)
                if self.levels.get(table, 0) < LEVEL_CAP
                and (e > self.tolerance or (table in raised and e > KEEP * self.tolerance))
            ]  # fmt: skip
            if not grow:
                return Answer(values, estimates, interpolated, solves)
            for table in grow:
                self.levels[table] = self.levels.get(table, 0) + 1
                raised.add(table)

    def _ask(
        self, tables: Sequence[tuple], which: np.ndarray, s: np.ndarray, b: np.ndarray,
        groups: dict[tuple, np.ndarray], plain: np.ndarray,
    ) -> tuple[Answer, list[tuple]]:  # fmt: skip
        """One collective evaluation of the fibred tables' M nodes at their queries' stretches
        (each to its :func:`node_tolerance`; a node whose weight at a query is 0 is not asked
        there), of the grid squares' builders of every node of the surplus terms
        (:data:`SURPLUS_TERMS`) and of the isotropic queries. Returns the answer and, per
        fibred table, its queries (q,), their weights (q, M), their rows in the answer (q, M)
        and the surplus terms' grids."""
        ask_tables: list[tuple] = []
        ask_which, ask_s, tol, layout = [], [], [], []

        def ask_grid(nodes: list[tuple], stretches: np.ndarray, level: int) -> tuple:
            """Ask every node at the builders of the level-``level`` grid squares holding the
            stretches (their corners are what is wanted: tolerance 1); returns the squares,
            each stretch's square and its hats (:func:`angle_surplus.grid_squares`)."""
            squares, square, hats = angle_surplus.grid_squares(stretches, level)
            build = angle_surplus.builders(squares, level)
            ask_which.append(np.repeat(len(ask_tables) + np.arange(len(nodes)), len(build)))
            ask_tables.extend(nodes)
            ask_s.append(np.tile(build, (len(nodes), 1)))
            tol.append(np.ones(len(nodes) * len(build)))
            return squares, square, hats

        factors = [factor for factor, _ in SURPLUS_TERMS]
        for table, queries in groups.items():
            count = self.count(table)
            fine = [table + (j * PERIOD // count,) for j in range(count)]
            cardinal = {  # each interpolant's cardinal functions at the queries, once
                k: trigonometric_weights(b[queries], k * count) for k in (1, *factors)
            }
            weights = cardinal[1]
            nearest, blend = near_node_blend(b[queries], count, self.tolerance)
            own = np.arange(count)[None, :] == nearest[:, None]
            # asked: the nodes of nonzero weight, only the nearest one where A is not blended
            # in; a node not asked has as its row any of the table's (times 0, or unused)
            used = (weights != 0.0) & ((blend > 0.0)[:, None] | own)
            query, node = np.nonzero(used)
            offset = sum(len(w) for w in ask_which)  # the rows asked before these
            ask_which.append(len(ask_tables) + node)
            ask_tables.extend(fine)
            ask_s.append(s[queries[query]])
            tol.append(node_tolerance(self.tolerance, weights[used]))
            rows = np.full(weights.shape, offset)
            rows[used] = offset + np.arange(len(query))
            grids = []
            surpluses = [
                angle_surplus.surplus_weights(cardinal[factor], cardinal[factor // 2])
                for factor in factors
            ]  # all zero at a fine node's angle: no grid asked for it (exactly, the terms are 0)
            need = by_rows(np.logical_or, np.hstack(surpluses) != 0.0) & (blend > 0.0)
            for (factor, level), surplus in zip(SURPLUS_TERMS, surpluses, strict=True):
                nodes = [table + (j * PERIOD // (factor * count),) for j in range(factor * count)]
                squares, square, hats = ask_grid(nodes, s[queries[need]], level)
                grids.append((nodes, squares, level, square, hats, surplus[need]))
            far = (blend < 1.0) & by_rows(np.logical_or, (weights != 0.0) & ~own)
            near = None  # the near-node form's grid: the M nodes' level-0 squares
            if far.any():
                near = (far, fine, *ask_grid(fine, s[queries[far]], 0), (weights - own)[far])
            layout.append((queries, weights, rows, need, grids, nearest, blend, near))
        ask_which.append(len(ask_tables) + which[plain])
        ask_tables.extend(tables)
        ask_s.append(s[plain])
        tol.append(np.full(len(plain), self.tolerance))
        answer = self._evaluate(
            ask_tables, np.concatenate(ask_which), np.concatenate(ask_s), np.concatenate(tol)
        )
        return answer, layout

    def _combine(
        self, answer: Answer, layout: list[tuple], b: np.ndarray, plain: np.ndarray, n: int,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
        """The queries' values (the fibred ones A(b, s) of the module docstring), their
        estimates (the larger of the last surplus term, the angle's, and the change the
        level-1 grid made to the first, the stretch's: :mod:`plantgrowth.unitcell.angle_surplus`)
        and which were interpolated."""
        values = np.zeros((n, answer.values.shape[1]))
        estimates = np.zeros(n)
        interpolated = np.zeros(n, dtype=bool)
        start = len(answer.values) - len(plain)
        values[plain] = answer.values[start:]
        estimates[plain] = answer.estimates[start:]
        interpolated[plain] = answer.interpolated[start:]
        for queries, weights, rows, need, grids, nearest, blend, near in layout:
            with_a = blend > 0.0  # where A is blended in (elsewhere A_k alone, estimate 0)
            value = np.zeros((len(queries), answer.values.shape[1]))
            value[with_a] = np.einsum("qj,qjm->qm", weights[with_a], answer.values[rows[with_a]])
            terms = [np.zeros_like(value) for _ in grids]
            coarse = np.zeros_like(value)
            if need.any():
                for term, (nodes, squares, level, square, hats, surplus) in zip(
                    terms, grids, strict=True
                ):
                    term[need] = angle_surplus.grid_term(
                        nodes, squares, level, square, hats, surplus, self._values
                    )
                (first, *_, surplus), (_, squares, level, square, hats, _) = grids
                coarse[need] = angle_surplus.grid_term(
                    first, squares, level, square, hats, surplus, self._values
                )  # the first surplus term on the last term's (coarser) grid
            full = value + sum(terms)
            # near a node the angle's terms are O(distance to it): no estimate asks for more M
            blended = full[with_a]
            estimates[queries[with_a]] = np.maximum(
                self._difference(blended - terms[-1][with_a], blended),
                self._difference(blended - terms[0][with_a] + coarse[with_a], blended),
            )
            values[queries] = self._blend(full, answer.values, rows, nearest, blend, near)
            used = weights != 0.0
            interpolated[queries] = (
                (used.sum(axis=1) > 1)
                | by_rows(np.logical_or, used & answer.interpolated[rows])
                | need
            )
        return values, estimates, interpolated

    def _blend(
        self, full: np.ndarray, answers: np.ndarray, rows: np.ndarray, nearest: np.ndarray,
        blend: np.ndarray, near: tuple | None,
    ) -> np.ndarray:  # fmt: skip
        """A (``full``) blended with the near-node form A_k = S_k + (I_M - I_k)[P_0 f] by the
        weights ``blend`` (module docstring): A where the weight is 1, A_k where it is 0."""
        if (blend == 1.0).all():
            return full
        own = answers[rows[np.arange(len(rows)), nearest]]  # S_k (a copy)
        if near is not None:
            far, nodes, squares, square, hats, change = near
            own[far] += angle_surplus.grid_term(
                nodes, squares, 0, square, hats, change, self._values
            )
        w = blend[:, None]
        return np.where(w == 1.0, full, np.where(w == 0.0, own, w * full + (1.0 - w) * own))
