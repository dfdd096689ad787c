"""Cost-balanced dealing of cell problems (plantgrowth.unitcell.scheduler): the schedule and the
results.

The schedule is checked on a stand-in communicator of a chosen size (``assign`` only reads
``comm.size``); ``solve_all`` runs on the real COMM_WORLD (serial, and under mpirun -n 2).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from mpi4py import MPI

from plantgrowth.unitcell.scheduler import SETUP_SOLVES, CellScheduler

pytestmark = pytest.mark.mpi  # scripts/README.md, "Tests": every test also runs on 2 ranks


def scheduler(size: int) -> CellScheduler:
    return CellScheduler(SimpleNamespace(size=size, rank=0))


def test_a_built_geometry_stays_on_its_rank_while_a_second_setup_costs_more():
    s = scheduler(2)
    s.built.add((1, "g"))
    # 10 solves cost less than one set-up (SETUP_SOLVES = 30 solves): all on rank 1
    assert s.assign(["g"] * 10) == [1] * 10


def test_many_solves_of_one_geometry_are_shared():
    s = scheduler(2)
    s.built.add((0, "g"))
    owner = s.assign(["g"] * 200)
    # rank 1 pays one set-up (30 solves) and takes its share: (200 - 30) / 2 = 85 of them
    assert (owner.count(0), owner.count(1)) == (115, 85)


def test_distinct_geometries_are_spread_without_duplicate_setups():
    s = scheduler(2)
    owner = s.assign([f"g{i % 4}" for i in range(40)])  # four geometries, ten solves each
    by_geometry = {f"g{i % 4}": set() for i in range(4)}
    for i, r in enumerate(owner):
        by_geometry[f"g{i % 4}"].add(r)
    assert all(len(ranks) == 1 for ranks in by_geometry.values())  # one set-up per geometry
    assert owner.count(0) == owner.count(1) == 20


def test_round_robin_would_have_set_up_every_geometry_twice():
    """The case the cost model exists for: groups of two solves per geometry. Round-robin
    gives each geometry to both ranks (2 set-ups); the schedule to one."""
    keys = [f"g{i // 2}" for i in range(20)]
    owner = scheduler(2).assign(keys)
    setups = len({(r, k) for r, k in zip(owner, keys, strict=True)})
    round_robin = len({(i % 2, k) for i, k in enumerate(keys)})
    assert (setups, round_robin) == (10, 20)


def test_the_prior_is_used_until_costs_are_measured():
    s = scheduler(2)
    assert s.costs == (SETUP_SOLVES * 1.0, 1.0)
    s._sums[:] = [0.5, 2, 0.02, 4]  # two first solves of 0.25 s, four of 5 ms
    setup, solve = s.costs
    assert np.isclose(solve, 0.005) and np.isclose(setup, 0.245)


def test_solve_all_returns_every_result_on_every_rank():
    comm = MPI.COMM_WORLD
    s = CellScheduler(comm)
    items = list(range(25))
    solved_here = []

    def solve(item: int) -> np.ndarray:
        solved_here.append(item)
        return np.array([item**2.0])

    results = s.solve_all(items, lambda i: i % 3, solve)
    assert sorted(results) == items and all(results[i][0] == i**2 for i in items)
    counts = comm.allgather(len(solved_here))
    assert sum(counts) == len(items)  # each item solved once, somewhere
    assert s.built == set().union(*comm.allgather({(comm.rank, i % 3) for i in solved_here}))
