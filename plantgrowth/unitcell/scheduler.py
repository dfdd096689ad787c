"""Cost-balanced sharing of distinct cell problems among the ranks (issue 10, item 2).

A cell problem's cost is one solve, plus the set-up of its geometry's solver (mesh, basis
integrals: about 30 solves at resolution 2) on a rank that has not built that solver yet.
Problems are dealt by geometry group, largest first, each group to the rank that would finish
it earliest (list scheduling with set-up costs); a large group is then split where the idle
time of another rank pays for a second set-up. Round-robin, which this replaces, set up every
geometry on every rank. The two costs are
measured while the run goes (means over all ranks, exchanged with the results), so every rank
computes the same schedule; results do not depend on the schedule (each problem is solved on
``COMM_SELF`` by the same code), only the time does.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Hashable, Sequence

import numpy as np
from mpi4py import MPI

SETUP_SOLVES = 30.0
"""Prior set-up cost in solves, before any is measured: CellSolver construction over its first
solve for the reference cell, 0.074 s / 0.0024 s at resolution 2 and 0.15 s / 0.0096 s at 3
(this machine, warm JIT cache)."""


class CellScheduler:
    """Deals items (each with the key of the solver it needs) to the ranks of ``comm``."""

    def __init__(self, comm: MPI.Comm) -> None:
        self.comm = comm
        self.built: set[tuple[int, Hashable]] = set()  # (rank, solver key) pairs, all ranks'
        self._sums = np.zeros(4)  # first-solve seconds, first solves, other seconds, others

    @property
    def costs(self) -> tuple[float, float]:
        """Estimated (set-up, solve) seconds: measured means, or the prior ratio."""
        first, n_first, other, n_other = self._sums
        solve = other / n_other if n_other else (first / n_first if n_first else 1.0)
        solve = max(solve, 1e-9)  # a clock too coarse for the solve
        setup = max(first / n_first - solve, 0.0) if n_first and n_other else SETUP_SOLVES * solve
        return setup, solve

    def assign(self, keys: Sequence[Hashable]) -> list[int]:
        """The rank of each item, given its solver key (the same answer on every rank).

        Whole geometry groups first, largest first, each to the rank that finishes it
        earliest; then, while it shortens the longest rank's time, part of a group moves from
        the longest to the shortest rank (which pays the set-up if it has not built it)."""
        setup, solve = self.costs
        groups: dict[Hashable, list[int]] = {}
        for i, k in enumerate(keys):
            groups.setdefault(k, []).append(i)
        load = np.zeros(self.comm.size)
        share: dict[Hashable, dict[int, int]] = {}  # key -> {rank: items}

        def setup_on(rank: int, k: Hashable) -> float:
            return 0.0 if (rank, k) in self.built or rank in share.get(k, {}) else setup

        for k, items in sorted(groups.items(), key=lambda kv: -len(kv[1])):
            finish = [load[r] + len(items) * solve + setup_on(r, k) for r in range(len(load))]
            rank = int(np.argmin(finish))  # ties: the lowest rank
            load[rank], share[k] = finish[rank], {rank: len(items)}
        for _ in range(4 * len(load) * len(groups)):  # each move shortens the longest rank
            a, b = int(np.argmax(load)), int(np.argmin(load))
            moves = [
                (min(n[a], int((load[a] - load[b] - setup_on(b, k)) // (2 * solve))), k)
                for k, n in share.items()
                if a in n
            ]
            m, k = max(moves, key=lambda mk: mk[0])
            if m < 1:
                break
            load[b] += setup_on(b, k) + m * solve
            load[a] -= m * solve
            share[k][a] -= m
            share[k][b] = share[k].get(b, 0) + m
        owner = [0] * len(keys)
        for k, items in groups.items():
            ranks = [r for r in sorted(share[k]) for _ in range(share[k][r])]
            for i, r in zip(items, ranks, strict=True):
                owner[i] = r
        return owner

    def solve_all(
        self, items: Sequence[Hashable], key: Callable[[Hashable], Hashable],
        solve: Callable[[Hashable], np.ndarray],
    ) -> dict[Hashable, np.ndarray]:  # fmt: skip
        """``{item: solve(item)}`` for all items, each solved on its assigned rank, the results
        exchanged with one allgather. Collective; ``items`` the same on every rank."""
        keys = [key(item) for item in items]
        owner = self.assign(keys)
        rank = self.comm.rank
        mine: dict[Hashable, np.ndarray] = {}
        sums = np.zeros(4)
        for item, k, r in zip(items, keys, owner, strict=True):
            if r != rank:
                continue
            first = (rank, k) not in self.built
            start = time.perf_counter()
            mine[item] = solve(item)
            sums[2 * (not first)] += time.perf_counter() - start
            sums[2 * (not first) + 1] += 1
            self.built.add((rank, k))
        results: dict[Hashable, np.ndarray] = {}
        for part, part_sums in self.comm.allgather((mine, sums)):
            results.update(part)
            self._sums += part_sums
        self.built.update(zip(owner, keys, strict=True))
        return results
