"""The surrogate's answer is one continuous function of the stretch (issue 33, item 1).

The lattice is driven by a smooth analytic map of U (five positive quantities of size 1-3 that
vary by tens of percent over |s| <= 0.3, like E_hom's), so these tests need no cell solve and
take a second. Before issue 33 a query was answered at whichever lattice level its estimate
first met the tolerance, so neighbouring queries could take different levels: the tests of
continuity and of drifting queries fail on that code (measured on 7aa6412: jumps of 0.29 and
0.45 times the tolerance beyond the exact change).
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

from plantgrowth.unitcell import lattice as lattice_walk
from plantgrowth.unitcell import surrogate

TOLERANCE = 1e-3
SEGMENTS = [slice(0, 5)]
TABLE = [(1,)]


def smooth(table: tuple, U: np.ndarray) -> np.ndarray:
    """Five smooth positive quantities of the stretch U (the role of a table's cell solve)."""
    a, b, c = U[0, 0], U[0, 1], U[1, 1]
    return np.array([2 * np.exp(a) + b, np.sin(3 * b) + 1.5, c**3, 1 + a * b, 2 + np.cos(4 * a)])


def exact(s: np.ndarray) -> np.ndarray:
    return np.array([smooth((), surrogate.stretch(x)) for x in s])


def lattice(comm: MPI.Comm = MPI.COMM_SELF) -> surrogate.LatticeSurrogate:
    return surrogate.LatticeSurrogate(smooth, TOLERANCE, SEGMENTS, comm)


def ask(lat: surrogate.LatticeSurrogate, s: np.ndarray) -> surrogate.Answer:
    return lat.evaluate(TABLE, np.zeros(len(s), dtype=np.int64), s)


def test_answers_are_continuous_across_former_level_boundaries():
    """Random queries build the lattice; then 20,001 queries 2.5e-5 apart along a line through
    squares of different depths are answered in one call. Each neighbouring pair's answers
    differ (relative) by at most the exact map's own change plus 0.01 tolerance: a C0
    interpolant's slope differs from f's by about h |f''| (h ~ 0.0125, the finest squares
    here), which over 2.5e-5 is about 1e-3 of the tolerance (measured 8e-4 of it). The per-query
    levels' answers jumped by 0.29 tolerance beyond the exact change along this line."""
    lat = lattice()
    ask(lat, np.random.default_rng(0).uniform(-0.3, 0.3, (200, 2)))
    line = np.column_stack([np.linspace(-0.25, 0.25, 20001), np.full(20001, 0.0371)])
    values, expected = ask(lat, line).values, exact(line)
    jump = lat.relative_difference(values[:-1], values[1:])
    change = lat.relative_difference(expected[:-1], expected[1:])
    excess = (jump - change).max()
    print(f"largest jump beyond the exact change: {excess / TOLERANCE:.3g} tolerance")
    assert excess <= 0.01 * TOLERANCE
    ids = np.zeros(len(line), dtype=np.int64)
    assert len(set(lat._deepest(ids, line)[0].tolist())) >= 2  # squares of different depths


def drift(monkeypatch: pytest.MonkeyPatch, keep: float) -> tuple[float, int, int]:
    """200 queries drifting by (2e-4, 1.3e-4) a call for 100 calls (a growing tissue's cells,
    one call a step) under the keep threshold ``keep``: the largest change of an answer from
    one call to the next beyond the exact change, the calls that refined, the points built."""
    monkeypatch.setattr(surrogate, "KEEP", keep)
    lat = lattice()
    start = np.random.default_rng(1).uniform(-0.1, 0.1, (200, 2))
    previous = None
    excess = 0.0
    refining_calls = 0
    for step in range(100):
        s = start + step * np.array([2e-4, 1.3e-4])
        answer, expected = ask(lat, s), exact(s)
        refining_calls += answer.solves > 0
        if previous is not None:
            jump = lat.relative_difference(previous[0], answer.values)
            change = lat.relative_difference(previous[1], expected)
            excess = max(excess, float((jump - change).max()))
        previous = answer.values, expected
    print(f"KEEP {keep}: {refining_calls} refining calls, {len(lat.values)} points, "
          f"largest jump beyond the exact change {excess / TOLERANCE:.3g} tolerance")  # fmt: skip
    return excess, refining_calls, len(lat.values)


def test_drifting_queries_move_with_the_exact_answer(monkeypatch):
    """Drifting queries (:func:`drift`): from one call to the next every answer changes by at
    most the exact change plus 0.05 tolerance (measured 0.029 with KEEP = 0.7; the jumps left
    are the refinements' surpluses; the per-query levels' were 0.45 tolerance, beyond 0.05 in
    68 of the 99 steps). The gap between the refine and keep thresholds refines in fewer calls
    than none (measured 33 against 44, for 293 points against 275), and halves the jumps
    (without it 0.054 tolerance: a square built where queries already are changes their
    answers by its new corners' surpluses, which the gap makes smaller)."""
    shipped = surrogate.KEEP
    excess, calls, _ = drift(monkeypatch, shipped)
    no_gap_calls = drift(monkeypatch, 1.0)[1]
    assert excess <= 0.05 * TOLERANCE
    assert calls < no_gap_calls


def test_interpolant_is_a_non_negative_combination_of_exact_values():
    """Rebuilt with each point's value a unit vector, the interpolant at a query gives the
    weights of the exact values in its answer: all >= 0 (to -1e-9: a query's place in a square is
    rounded to 9 digits on each level, _cell) and summing to 1, also where built squares meet
    coarser ones and inside a square built in one quadrant only (hanging points, up to several
    levels apart). So an SPD-valued map (E_hom) is interpolated SPD, as by plain bilinear
    weights."""
    lat = lattice()
    queries = np.random.default_rng(2).uniform(-0.3, 0.3, (300, 2))
    ask(lat, queries)
    built = sorted(lat.values)
    unit = surrogate.LatticeSurrogate(smooth, TOLERANCE, [slice(0, len(built))], MPI.COMM_SELF)
    unit.values = dict(zip(built, np.eye(len(built)), strict=True))
    unit._table_ids = dict(lat._table_ids)
    assert unit._build_squares(np.array(sorted(lat._built), dtype=np.int64)) == 0
    probe = np.random.default_rng(3).uniform(-0.3, 0.3, (2000, 2))
    weights, _ = unit.interpolate(TABLE, np.zeros(len(probe), dtype=np.int64), probe)
    print(f"smallest weight {weights.min():.3g}")
    assert weights.min() >= -1e-9
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, rtol=0, atol=1e-14)
    values = lat.interpolate(TABLE, np.zeros(len(probe), dtype=np.int64), probe)[0]
    np.testing.assert_allclose(weights @ np.array([lat.values[p] for p in built]), values,
                               rtol=1e-13)  # fmt: skip


def walked(lat: surrogate.LatticeSurrogate, s: np.ndarray) -> dict[str, np.ndarray]:
    """The walk down every level at the queries s themselves (no stop squares)."""
    keys, surplus = lat._points_table()
    squares = np.array(sorted(lat._built), dtype=np.int64)
    ids = np.zeros(len(s), dtype=np.int64)
    return lattice_walk.walk(squares, keys, surplus, ids, s, s[:, None, :])


def test_stop_squares_answer_as_the_walk_and_forget_what_a_refinement_changes():
    """A step's answers come from the stop squares' corners (one lookup); they are the walk's
    answers: values to 1e-9 relative (the walk rounds a query's place in each level's square to
    9 digits, lattice.cell, so its answer is quantised at 1e-9 of a square's side; the corners'
    bilinear combination is not: measured 1e-10 here), estimates' terms likewise, and the
    deepest built squares and on-point flags identical. Then queries elsewhere refine the
    lattice: the first queries' answers follow the new interpolant (the table's entries were
    dropped), again the walk's."""
    lat = lattice()
    rng = np.random.default_rng(5)
    first = np.vstack([rng.uniform(-0.3, 0.3, (300, 2)), [[0.0, 0.0], [0.1, -0.2]]])
    ask(lat, first)
    for refined in (False, True):
        if refined:  # queries next to the first refine the squares they share
            count = len(lat._built)
            ask(lat, rng.uniform(-0.02, 0.02, (50, 2)) + first[:50])
            assert len(lat._built) > count
        ids = np.zeros(len(first), dtype=np.int64)
        values, interpolated, level, square, change = lat._walk(ids, first)
        walk = walked(lat, first)
        scale = np.abs(walk["values"][:, 0]).max(axis=1)
        assert (np.abs(values - walk["values"][:, 0]).max(axis=1) <= 1e-9 * scale).all()
        assert (np.abs(change - walk["change"][:, 0]).max(axis=1) <= 1e-9 * scale).all()
        np.testing.assert_array_equal(level, walk["level"])
        np.testing.assert_array_equal(square, walk["square"])
        np.testing.assert_array_equal(interpolated, ~walk["on_point"][:, 0])
        assert not interpolated[-2:].any()


def test_lattice_points_are_answered_exactly_and_refining_is_a_phase_of_its_own():
    """A query on a built point gets its exact value to the bit; ``interpolate`` (the frozen
    interpolant a solve uses) solves nothing and refuses a query off the built lattice."""
    lat = lattice()
    points = np.array([[0.0, 0.0], [0.1, -0.2]])
    answer = ask(lat, points)
    np.testing.assert_array_equal(answer.values, exact(points))
    assert not answer.interpolated.any()
    count = len(lat.values)
    lat.interpolate(TABLE, np.zeros(1, dtype=np.int64), np.array([[0.03, 0.01]]))
    assert len(lat.values) == count
    with pytest.raises(KeyError):
        lat.interpolate(TABLE, np.zeros(1, dtype=np.int64), np.array([[2.03, 0.01]]))


@pytest.mark.mpi
def test_a_query_builds_only_its_own_chain_of_squares():
    """Refining solves only the points a query's estimate needs: a query builds its level-0
    square's 4 corners and the 3 new corners of each deeper square on its chain (before, all
    five children of each refined square: 9 + 5 per level, 101 lattice points on
    gradient_E_strain at balanced where these need 73), and a query on a lattice point (every
    cell of a homogeneous tissue at s = 0) only the 4 corners, its estimate 0."""
    lat = lattice()
    s = np.array([[0.0123, -0.0456]])
    ask(lat, s)
    depth = lat._deepest(np.zeros(1, dtype=np.int64), s)[0][0]
    assert depth >= 2
    assert len(lat.values) == 4 + 3 * depth
    lat = lattice()
    answer = ask(lat, np.zeros((3, 2)))
    assert answer.solves == len(lat.values) == 4
    np.testing.assert_array_equal(answer.estimates, 0.0)


@pytest.mark.mpi
def test_ranks_build_the_same_tables():
    """Under mpirun each rank asks its own half of the queries, of two tables named in an order
    of its own (a rank numbers the tables it meets; the squares' keys must not depend on that):
    every rank ends with the one-rank lattice's refined squares and gives its answers bit for
    bit."""
    comm = MPI.COMM_WORLD
    rng = np.random.default_rng(4)
    queries, which = rng.uniform(-0.3, 0.3, (60, 2)), rng.integers(0, 2, 60)
    tables = [(1,), (2,)]

    def scaled(table: tuple, U: np.ndarray) -> np.ndarray:
        return table[0] * smooth(table, U)

    mine = slice(len(queries) * comm.rank // comm.size, len(queries) * (comm.rank + 1) // comm.size)
    shared = surrogate.LatticeSurrogate(scaled, TOLERANCE, SEGMENTS, comm)
    alone = surrogate.LatticeSurrogate(scaled, TOLERANCE, SEGMENTS, MPI.COMM_SELF)
    order = tables if comm.rank % 2 == 0 else tables[::-1]
    asked = [order.index(tables[k]) for k in which[mine]]
    values = shared.evaluate(order, np.array(asked, dtype=np.int64), queries[mine]).values
    expected = alone.evaluate(tables, which, queries).values[mine]
    assert shared.squares().tolist() == alone.squares().tolist()
    np.testing.assert_array_equal(values, expected)
