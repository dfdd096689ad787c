"""The surrogate's c1 path (``accuracy.cell_interpolant``, docs/surrogate_c1.md): continuous
answers across former level boundaries, exact at built points, the SPD guard, the blend's
resume state, serial = mpirun, and the scene option. The lattice is driven by the smooth
analytic map of tests/test_surrogate_continuity.py (no cell solve): the file takes 4-10 s
(load 1-6 on 2 shared cores).
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI
from test_surrogate_continuity import TOLERANCE, exact, smooth

from plantgrowth.base.errors import SceneError
from plantgrowth.scene.parts import Accuracy
from plantgrowth.unitcell import surrogate
from plantgrowth.unitcell.lattice import H0, LOW, OFFSET, STEP, square_key
from plantgrowth.unitcell.smooth_answers import (
    BLEND_STEPS,
    DECLINE,
    SmoothAnswers,
    corner_keys,
    ratios,
    smoothstep,
)

TABLE = [(1,)]
FIVE, VOIGT = slice(0, 5), slice(0, 9)


def c1(comm: MPI.Comm = MPI.COMM_SELF, solve=smooth, segments=(FIVE,), voigt=None):
    return surrogate.LatticeSurrogate(solve, TOLERANCE, segments, comm, interpolant="c1",
                                      voigt=voigt)  # fmt: skip


def ask(lat: surrogate.LatticeSurrogate, s: np.ndarray) -> np.ndarray:
    return lat.evaluate(TABLE, np.zeros(len(s), dtype=np.int64), s).values


def drift(step: int, n: int = 40) -> np.ndarray:
    """n queries moving on straight lines, step by step (growing cells' stretches)."""
    rng = np.random.default_rng(2)
    start, velocity = rng.uniform(-0.1, 0.1, (n, 2)), rng.uniform(-0.004, 0.004, (n, 2))
    return start + step * velocity


def run(lat: surrogate.LatticeSurrogate, steps: range) -> list[np.ndarray]:
    """The drifting queries' answers at each step (the step ends after each)."""
    out = []
    for step in steps:
        out.append(ask(lat, drift(step)))
        lat.end_step()
    return out


def test_answers_are_continuous_across_former_level_boundaries():
    """Random queries and 10,001 queries 5e-5 apart along a line through squares of different
    depths build the lattice, then B steps pass (no blend left) and the line is asked again.
    Each neighbouring pair's answers differ (relative) by at most the exact map's own change
    plus 0.003 tolerance: J is C1 and the difference of its slope and f's, over 5e-5, amounts
    to about 1e-3 tolerance (measured 1.25e-3; a level chosen per query jumped by 0.29
    tolerance, tests/test_surrogate_continuity.py). The same bound during a blend: the line
    asked at 0.3 times the tolerance refines the lattice along it, and its answers blend the
    refinement in with a gate that the pre-refinement estimates (about 0.3-1 of the old
    tolerance, around the new one) open and close along the line (measured 1.24e-3; a hard
    gate, pass or fail at the tolerance, jumped by 4.3e-3)."""
    lat = c1()
    line = np.column_stack([np.linspace(-0.25, 0.25, 10001), np.full(10001, 0.0371)])
    ask(lat, np.vstack([np.random.default_rng(0).uniform(-0.3, 0.3, (200, 2)), line]))
    for _ in range(BLEND_STEPS):
        lat.end_step()
    values, expected = ask(lat, line), exact(line)
    jump = lat.relative_difference(values[:-1], values[1:])
    change = lat.relative_difference(expected[:-1], expected[1:])
    excess = (jump - change).max()
    print(f"settled: largest jump beyond the exact change {excess / TOLERANCE:.3g} tolerance")
    assert excess <= 0.003 * TOLERANCE
    lat.end_step()
    ids, finer = np.zeros(len(line), dtype=np.int64), np.full(len(line), 0.3 * TOLERANCE)
    values = lat.evaluate(TABLE, ids, line, finer).values  # a refinement, blended in
    assert any(b == lat.step for b in lat.smooth.births.values())
    jump = lat.relative_difference(values[:-1], values[1:])
    excess = (jump - change).max()
    print(f"blending: largest jump beyond the exact change {excess / TOLERANCE:.3g} tolerance")
    assert excess <= 0.003 * TOLERANCE


def test_built_points_are_answered_exactly_once_the_blends_end():
    """At every built point, B steps after the last refinement: J's value, equal to the exact
    value to rounding (1e-12: the cached bicubic is fitted to 16 samples of J; measured 3e-16);
    and the queries that built the lattice are within the tolerance."""
    lat = c1()
    queries = np.random.default_rng(3).uniform(-0.2, 0.2, (150, 2))
    ask(lat, queries)
    for _ in range(BLEND_STEPS):
        lat.end_step()
    keys = np.unique(np.concatenate([list(lat._surplus)]))
    ij = np.column_stack([((keys >> 21) & LOW) - OFFSET, (keys & LOW) - OFFSET])
    values = ask(lat, ij * (H0 / STEP))
    truth = np.array([lat.values[TABLE[0], tuple(p)] for p in ij.tolist()])
    assert lat.relative_difference(values, truth).max() <= 1e-12
    assert lat.relative_difference(ask(lat, queries), exact(queries)).max() <= TOLERANCE


def test_a_point_the_interpolant_missed_enters_at_once_and_a_close_one_along_the_smoothstep():
    """Nine level-0 squares born at step 0 hold a linear map (J reproduces it), then one level-1
    square born at step 1 adds three points: one where the map has a bump of 100 tolerances
    (from 16 tolerances: its exact value at once), one with a bump of 0.8 tolerances (above
    DECLINE, within the tolerance: J_<b plus the smoothstep's share w = smoothstep(1 / (B + 1))
    of the bump) and one of 2 tolerances (over B / 2 steps: w = smoothstep(1 / (B / 2 + 1))).
    At step 1 + B / 2 the 2-tolerance point has its exact value, at step 1 + B every point.
    Values at built points are J's, to the 1e-12 of the cells' fitted bicubics."""
    side = STEP  # the level-0 spacing in finest integers
    bumps = {(side // 2, side // 2): 100.0, (side, side // 2): 0.8, (side // 2, side): 2.0}
    answers, s, ids, truth, base, error = level1_births(bumps)
    miss = error / TOLERANCE  # relative to the bumped values: 90.9, 0.8 and 2.0
    assert miss[0] >= 16.0 and DECLINE < miss[1] <= 1.0
    assert round(BLEND_STEPS / miss[2]) == BLEND_STEPS // 2
    share = smoothstep(np.array([1.0, 1.0 / (BLEND_STEPS + 1), 1.0 / (BLEND_STEPS // 2 + 1)]))
    expected = base + share[:, None] * (truth - base)

    def at(step: int) -> np.ndarray:
        return answers.answer(ids, s, np.zeros((3, 2)), np.zeros(3, dtype=np.int64), step)

    np.testing.assert_allclose(at(1), expected, rtol=1e-12, atol=0.0)
    np.testing.assert_allclose(at(1 + BLEND_STEPS // 2)[2], truth[2], rtol=1e-12, atol=0.0)
    np.testing.assert_allclose(at(1 + BLEND_STEPS), truth, rtol=1e-12, atol=0.0)


def test_a_new_point_the_interpolant_already_meets_is_declined():
    """The nine level-0 squares and the level-1 square of the test above, its three points
    with bumps of 0.3 tolerances (at most DECLINE: declined), 0.8 and 100 (taken). The
    declined point's answer is J_<b's (the level-0 map) at its birth and B steps later, so it
    stays within its 0.3 tolerances of its exact value; the taken ones become exact."""
    side = STEP
    bumps = {(side // 2, side // 2): 0.3, (side, side // 2): 0.8, (side // 2, side): 100.0}
    answers, s, ids, truth, base, error = level1_births(bumps)
    assert error[0] <= DECLINE * TOLERANCE < error[1]
    for step in (1, 1 + BLEND_STEPS):
        values = answers.answer(ids, s, np.zeros((3, 2)), np.zeros(3, dtype=np.int64), step)
        np.testing.assert_allclose(values[0], base[0], rtol=1e-12, atol=0.0)
    np.testing.assert_allclose(values[1:], truth[1:], rtol=1e-12, atol=0.0)


def level1_births(bumps: dict) -> tuple:
    """Nine level-0 squares born at step 0 on a linear map and one level-1 square born at
    step 1 whose three new points (``bumps``: place -> bump in tolerances) carry bumps: the
    answers, the points' places, ids, exact values, J_<b there (the map) and J_<b's misses."""
    side = STEP  # the level-0 spacing in finest integers
    level0 = np.array([[i, j] for i in range(-1, 2) for j in range(-1, 2)]) * side
    new_square = square_key(np.zeros(1, dtype=np.int64), 1, np.array([[side // 2, side // 2]]))
    births = {int(k): 0 for k in square_key(np.zeros(9, dtype=np.int64), 0, level0)}
    births[int(new_square[0])] = 1

    def linear(ij: np.ndarray) -> np.ndarray:
        x = ij / STEP
        return np.column_stack([1.0 + 0.1 * x[:, 0] + 0.2 * x[:, 1], 2.0 - 0.1 * x[:, 1]])

    def exact_values(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ij = np.column_stack([((keys >> 21) & LOW) - OFFSET, (keys & LOW) - OFFSET])
        values = linear(ij)
        for row, p in enumerate(ij.tolist()):
            values[row] *= 1.0 + bumps.get(tuple(p), 0.0) * TOLERANCE
        return values, np.zeros_like(values)

    def difference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.linalg.norm(a - b, axis=1) / np.linalg.norm(b, axis=1)

    answers = SmoothAnswers(exact_values, difference, TOLERANCE, None)
    answers.births = births
    points = np.array(list(bumps), dtype=np.int64)
    s = points * (H0 / STEP)
    ids = np.zeros(len(points), dtype=np.int64)
    keys = np.sort(corner_keys(new_square).ravel())
    ij = np.column_stack([((keys >> 21) & LOW) - OFFSET, (keys & LOW) - OFFSET])
    truth = exact_values(keys)[0][[ij.tolist().index(p) for p in points.tolist()]]
    base = linear(points)  # J_<b there: the level-0 map
    return answers, s, ids, truth, base, difference(base, truth)  # relative to the bumped


def ramp(table: tuple, U: np.ndarray) -> np.ndarray:
    """A Voigt matrix diag(1, 1, g) whose smallest eigenvalue g has a kink: 2e-3 for s1 <= 0.03,
    rising with slope 1 beyond (the C1 interpolant's negative lobes undershoot it)."""
    s1 = np.log(U[0, 0] / U[1, 1]) / 2.0  # U = expm(S), s2 = 0 on this line
    return np.diag([1.0, 1.0, 2e-3 + max(s1 - 0.03, 0.0)]).ravel()


def test_the_spd_guard_replaces_c1_answers_that_lose_positivity():
    """On the ramp's kink, J's undershoot (about h / 16 times the slope, h = 0.1 / 2^l) takes
    the smallest eigenvalue below half the corners' smallest ratio; there the guard answers
    bilinearly (a convex combination: no answer below the corners' smallest ratio). Without the
    guard the same queries have ratios below that bound, so the test sees the guard work."""
    line = np.column_stack([np.linspace(-0.05, 0.2, 2001), np.zeros(2001)])
    answers = {}
    for voigt in (None, slice(0, 9)):
        lat = c1(solve=ramp, segments=(slice(0, 9),), voigt=voigt)
        ask(lat, line)
        for _ in range(BLEND_STEPS):
            lat.end_step()
        answers[voigt is None] = (ask(lat, line), lat)
    unguarded, _ = answers[True]
    guarded, lat = answers[False]
    floor = 2e-3  # the corners' smallest lambda_min / lambda_max
    print(
        f"smallest ratio: unguarded {ratios(unguarded, VOIGT).min():.3g}, guarded "
        f"{ratios(guarded, VOIGT).min():.3g}; guarded answers {lat.smooth.guarded}"
    )
    assert ratios(unguarded, slice(0, 9)).min() < 0.5 * floor
    assert lat.smooth.guarded > 0
    assert ratios(guarded, slice(0, 9)).min() >= 0.5 * floor


def test_the_guard_is_silent_on_smooth_positive_values():
    """The analytic map's E-like Voigt matrices (diagonally dominant, smooth): no answer guarded
    over a whole drifting run."""

    def voigt(table: tuple, U: np.ndarray) -> np.ndarray:
        v = smooth(table, U)
        return np.array([[v[0] + 2, v[3], 0.1], [v[3], v[2] + 2, 0.2], [0.1, 0.2, v[1]]]).ravel()

    lat = c1(solve=voigt, segments=(slice(0, 9),), voigt=slice(0, 9))
    run(lat, range(12))
    assert lat.smooth.guarded == 0


def test_a_resumed_blend_answers_as_the_straight_run():
    """Drifting queries refine the lattice at every step over 11 steps (5 blends running at
    step 6). A surrogate restored at step 6 from squares() and births() (what a run's state
    holds) answers steps 6-10 bit for bit as the straight one; restored without the births
    (each square born at the resume) it does not, so the test sees the births."""
    straight = c1()
    answers = run(straight, range(6))
    squares, births = straight.squares(), straight.births()
    assert any(straight.step - b < BLEND_STEPS for b in straight.smooth.births.values())
    later = run(straight, range(6, 11))
    resumed = c1()
    resumed.restore(squares)
    resumed.restore_births(births)
    for a, b in zip(run(resumed, range(6, 11)), later, strict=True):
        np.testing.assert_array_equal(a, b)
    forgetful = c1()
    forgetful.restore(squares)
    forgetful.step = straight.step - 5
    assert any(not np.array_equal(a, b) for a, b in
               zip(run(forgetful, range(6, 11)), later, strict=True))  # fmt: skip
    assert len(answers) == 6


@pytest.mark.mpi
def test_ranks_answer_as_one_rank_on_the_c1_path():
    """Under mpirun each rank asks its block of the drifting queries; the answers equal one
    rank's (COMM_SELF, every query) bit for bit at every step: the lattice, births and step
    count are the same on every rank, and an answer depends on them and its query only."""
    comm = MPI.COMM_WORLD
    shared, alone = c1(comm), c1()
    n = 20
    block = slice(n * comm.rank // comm.size, n * (comm.rank + 1) // comm.size)
    for step in range(6):  # every step refines (births 0-5): 5 blends run at the last
        s = drift(step, n)
        mine = ask(shared, s[block])
        np.testing.assert_array_equal(mine, ask(alone, s)[block])
        shared.end_step()
        alone.end_step()


def test_the_scene_option_is_validated():
    """accuracy.cell_interpolant: a named error listing the valid values; bilinear by default
    (docs/surrogate_c1.md: c1's answers make a step's cell phase about 1.5x bilinear's)."""
    with pytest.raises(SceneError, match=r"accuracy.cell_interpolant = 'cubic' is invalid.*'c1'"):
        Accuracy(cell_interpolant="cubic")
    with pytest.raises(SceneError, match="accuracy.cell_interpolant: expected a string"):
        Accuracy(cell_interpolant=1)
    assert Accuracy().cell_interpolant == "bilinear"
    assert Accuracy(cell_interpolant="c1").cell_interpolant == "c1"
