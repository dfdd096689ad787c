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


def interpolate_angles(
    evaluate: Callable[[list[tuple], np.ndarray, np.ndarray], Answer],
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

    Args:
        evaluate: the stretch surrogate, ``evaluate(tables, which, s, tolerance)``
            (collective), a fibred table's node being the table plus its angle index.
        difference: the relative difference per row of two (n, m) value arrays.
    """
    n = len(which)
    fibred = np.array([len(tables[w]) > 5 for w in which], dtype=bool).reshape(n)
    level = np.zeros(n, dtype=np.int64)
    values, estimates = None, np.zeros(n)
    interpolated = np.zeros(n, dtype=bool)
    pending, coarse, solves = np.flatnonzero(fibred), None, 0
    plain = np.flatnonzero(~fibred)
    while True:
        # level L's nodes, then L + 1's (of which the first round also needs L's)
        ask_tables, ask_which, ask_s, ask_tol, parts = [], [], [], [], []
        levels = (
            (level[pending] + 1,) if coarse is not None else (level[pending], level[pending] + 1)
        )
        for lv in levels:
            lower, upper, t = angle_nodes(b[pending], lv)
            parts.append(t)
            for node, weight in ((lower, 1.0 - t), (upper, t)):
                ask_which.append(np.arange(len(ask_tables), len(ask_tables) + len(pending)))
                ask_tables += [
                    tables[w] + (int(i),) for w, i in zip(which[pending], node, strict=True)
                ]
                ask_s.append(s[pending])
                ask_tol.append(node_tolerance(tolerance, weight))
        if values is None:  # the first round also answers the isotropic queries
            ask_which.append(np.arange(len(ask_tables), len(ask_tables) + len(plain)))
            ask_tables += [tables[w] for w in which[plain]]
            ask_s.append(s[plain])
            ask_tol.append(np.full(len(plain), tolerance))
        ask = (np.concatenate(ask_which), np.concatenate(ask_s).reshape(-1, 2))
        answer = evaluate(ask_tables, *ask, np.concatenate(ask_tol))
        solves += answer.solves
        if answer.values is None:  # no rank has a query
            return Answer(np.zeros((n, 0)), estimates, interpolated, solves)
        m = len(pending)
        width = answer.values.shape[1]
        node_values = answer.values[: len(levels) * 2 * m].reshape(len(levels), 2, m, width)
        node_interp = answer.interpolated[: len(levels) * 2 * m].reshape(len(levels), 2, m)
        if values is None:
            values = np.zeros((n, width))
            values[plain] = answer.values[len(levels) * 2 * m :]
            estimates[plain] = answer.estimates[len(levels) * 2 * m :]
            interpolated[plain] = answer.interpolated[len(levels) * 2 * m :]
        mix = [
            (1 - t)[:, None] * v[0] + t[:, None] * v[1]
            for t, v in zip(parts, node_values, strict=True)
        ]
        fine = mix[-1]
        if coarse is None:
            coarse = mix[0]
        estimates[pending] = difference(coarse, fine) if m else np.zeros(0)
        done = (estimates[pending] <= tolerance) | (level[pending] + 1 == MAX_ANGLE_LEVEL)
        values[pending[done]] = fine[done]
        between = (parts[-1] > 0.0) & (parts[-1] < 1.0)
        interpolated[pending[done]] = (between | node_interp[-1].any(axis=0))[done]
        level[pending[~done]] += 1
        pending, coarse = pending[~done], fine[~done]
        if not comm.allreduce(len(pending), op=MPI.MAX):
            return Answer(values, estimates, interpolated, solves)
