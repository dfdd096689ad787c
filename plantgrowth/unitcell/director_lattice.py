"""The director's angle as a lattice dimension of the surrogate (issue 22, item 3).

A fibred cell problem depends on the director's angle relative to the growth's rotation,
``b = (a - rotation) mod 180`` (periodic: a director is an axis). With feedback the angles are
continuous, so tables keyed by each exact angle would be solved anew for every fine cell and
step. Instead, b is interpolated linearly between the nodes of nested periodic lattices of
spacing ``H0_ANGLE / 2^L``, as the stretch is (:mod:`plantgrowth.unitcell.surrogate`): each node
is a table of the stretch surrogate (its angle an integer index of the finest lattice,
``ANGLE_STEP`` degrees each). A query is answered at the level L at which the interpolants of
levels L and L + 1 differ by at most the tolerance (relative, per homogenized quantity); the
finer one is returned and that difference is its estimate of the angle interpolation's error (on
top of the stretch interpolation's own). Linear weights are non-negative, so E_hom stays SPD.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from mpi4py import MPI

from plantgrowth.unitcell.surrogate import Answer

H0_ANGLE = 15.0
"""Coarsest spacing of the angle lattice (degrees): 12 nodes over 180, where the hexagon's
60-degree symmetry repeats every 4."""
MAX_ANGLE_LEVEL = 10
"""Finest level (spacing 15 / 1024 = 0.0146 degrees); a query not resolved there takes its value."""
ANGLE_STEP = H0_ANGLE / 2**MAX_ANGLE_LEVEL
"""Degrees per integer index of a node's angle."""
PERIOD = round(180.0 / ANGLE_STEP)
"""Node indices per 180 degrees (index PERIOD is index 0)."""


def angle_nodes(b: np.ndarray, level: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For angles b (n,) in [0, 180) and levels (n,): the indices of the two nodes of the
    level's interval that holds b (lower, upper; PERIOD wraps to 0) and the upper's weight t."""
    steps = 2 ** (MAX_ANGLE_LEVEL - level)
    x = np.round(b / (H0_ANGLE / 2.0**level), 9)  # round-off of b on a node: that node
    k = np.floor(x)
    t = np.clip(x - k, 0.0, 1.0)
    lower = k.astype(np.int64) * steps
    return lower % PERIOD, (lower + steps) % PERIOD, t


def node_tolerance(tolerance: float, weight: np.ndarray) -> np.ndarray:
    """The relative tolerance a node's stretch interpolation is asked for, given its weight w in
    the angle interpolant: ``tolerance / min(1, 2 w)``, at most 1. A node's error enters the
    answer times w, so the two nodes' errors add up to at most 1.5 tolerance (two halves), and
    a node of small weight (a director near the other node) is not refined for nothing."""
    return np.minimum(tolerance / np.clip(2.0 * weight, 1e-300, 1.0), 1.0)


NEAR = 1.0 / 256.0
"""Largest distance to a node, as a fraction of the coarsest interval (0.06 degrees), at which
a query may be answered without a finer angle level (:func:`interpolate_angles`)."""


def _requests(
    which: np.ndarray, b: np.ndarray, level: np.ndarray, tolerance: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The node requests of m queries (tables ``which``, angles ``b``) at their levels.

    Returns the upper nodes' weights t (m,); per node (lower, upper: (2, m)) the index of its
    request, -1 for a node of zero weight (it adds nothing and is not asked); and per request
    its query, its table and node index as one integer (``table * PERIOD + node``) and its
    tolerance (:func:`node_tolerance`).
    """
    lower, upper, t = angle_nodes(b, level)
    node, weight = np.stack([lower, upper]), np.stack([1.0 - t, t])
    asked = weight > 0.0
    index = np.full(node.shape, -1, dtype=np.int64)
    index[asked] = np.arange(np.count_nonzero(asked))
    query = np.broadcast_to(np.arange(len(b)), node.shape)[asked]
    table_node = which[query] * PERIOD + node[asked]
    return t, index, query, table_node, node_tolerance(tolerance, weight[asked])


def interpolate_angles(
    evaluate: Callable[[list[tuple], np.ndarray, np.ndarray, np.ndarray], Answer],
    difference: Callable[[np.ndarray, np.ndarray], np.ndarray],
    tolerance: float,
    comm: MPI.Comm,
    tables: Sequence[tuple],
    which: np.ndarray,
    s: np.ndarray,
    b: np.ndarray,
) -> Answer:
    """Collective: the answers to this rank's queries, query k asking ``tables[which[k]]`` at
    stretch ``s[k]`` and, for a fibred table (more than 5 entries), angle ``b[k]`` (degrees in
    [0, 180)); an isotropic table is asked once, as it is.

    The first round asks each fibred query's two level-0 nodes. A query within :data:`NEAR`
    of one of them (a fixed director turned by a growth rotation of hundredths of a degree) is
    answered by their linear interpolant if that differs from the near node's value by at
    most the tolerance: the difference is the first-order term of the angle's Taylor
    expansion, which bounds the linear interpolant's second-order error (with the NEAR bound
    that keeps it below the tolerance even if the two nodes happened to agree: h^2 |f''| / 2
    at most about 4 per rad^2 at E_f / E = 5, measured in docs/fibres.md, gives 5e-4). Every
    other query goes on as the lattice does: levels L and L + 1 compared, L + 1 returned.

    Args:
        evaluate: the stretch surrogate, ``evaluate(tables, which, s, tolerance)``
            (collective), a fibred table's node being the table plus its angle index.
        difference: the relative difference per row of two (n, m) value arrays.
    """
    n = len(which)
    which = np.asarray(which, dtype=np.int64).reshape(n)
    fibred = np.array([len(table) > 5 for table in tables], dtype=bool)[which]
    level = np.zeros(n, dtype=np.int64)
    values, estimates = None, np.zeros(n)
    interpolated = np.zeros(n, dtype=bool)
    pending, coarse, solves = np.flatnonzero(fibred), None, 0
    plain = np.flatnonzero(~fibred)
    while True:
        # the first round asks level L = 0, every later one level L + 1 of the pending
        lv = level[pending] + (coarse is not None)
        t, index, query, table_node, tol = _requests(which[pending], b[pending], lv, tolerance)
        names, ask_which = np.unique(table_node, return_inverse=True)
        ask_tables = [tables[k // PERIOD] + (k % PERIOD,) for k in names.tolist()]
        ask_s = s[pending][query]
        if values is None:  # the first round also answers the isotropic queries
            ask_which = np.concatenate([ask_which, len(ask_tables) + which[plain]])
            ask_tables += list(tables)
            ask_s = np.concatenate([ask_s, s[plain]])
            tol = np.concatenate([tol, np.full(len(plain), tolerance)])
        answer = evaluate(ask_tables, ask_which, ask_s.reshape(-1, 2), tol)
        solves += answer.solves
        if answer.values is None:  # no rank has a query
            return Answer(np.zeros((n, 0)), estimates, interpolated, solves)
        asked = len(query)
        if values is None:
            values = np.zeros((n, answer.values.shape[1]))
            values[plain] = answer.values[asked:]
            estimates[plain] = answer.estimates[asked:]
            interpolated[plain] = answer.interpolated[asked:]
        # a zero-weight node (index -1) reads any row and adds 0 times it
        node_values = answer.values[np.maximum(index, 0)]
        fine = (1 - t)[:, None] * node_values[0] + t[:, None] * node_values[1]
        if coarse is None:  # near a level-0 node: the linear interpolant against that node
            nearest = np.where((t <= 0.5)[:, None], node_values[0], node_values[1])
            estimates[pending] = difference(nearest, fine) if len(pending) else np.zeros(0)
            done = (np.minimum(t, 1.0 - t) <= NEAR) & (estimates[pending] <= tolerance)
        else:
            estimates[pending] = difference(coarse, fine) if len(pending) else np.zeros(0)
            done = (estimates[pending] <= tolerance) | (lv == MAX_ANGLE_LEVEL)
            level[pending[~done]] += 1
        values[pending[done]] = fine[done]
        node_interp = (index >= 0) & answer.interpolated[np.maximum(index, 0)]
        between = (t > 0.0) & (t < 1.0)
        interpolated[pending[done]] = (between | node_interp.any(axis=0))[done]
        pending, coarse = pending[~done], fine[~done]
        if not comm.allreduce(len(pending), op=MPI.MAX):
            return Answer(values, estimates, interpolated, solves)
