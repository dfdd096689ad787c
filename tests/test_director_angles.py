"""The trigonometric interpolant of the director's angle (issue 33, item 2).

The angle nodes are driven by a smooth analytic map of the node angle (a stand-in for a fibred
cell's tensors: period 180 degrees, E_hom-like values of size 1-3), so no cell is solved here;
tests/test_cell_fibres.py checks the interpolant against CellSolver. Round-off: the weights are
sums of O(1) products of sines of angles up to 6 pi, so 1e-12.
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

from plantgrowth.unitcell import angle_surplus, director_lattice
from plantgrowth.unitcell.surrogate import H0, STEP, Answer

ROUND_OFF = 1e-12
FIBRED = (1, 2, 3, 4, 5, 6)  # a fibred table: more than 5 entries
PLAIN = (1, 2, 3, 4, 5)


def director_map(b: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Three smooth, 180-degree periodic positive quantities of the angle b (degrees) and the
    stretch s (the role of a fibred cell's packed tensors), (n, 3)."""
    theta = np.radians(2.0 * b)
    return np.column_stack([
        2.0 + np.cos(theta) + 0.2 * s[:, 0],
        1.5 + 0.5 * np.sin(theta) * np.cos(theta),
        1.0 / (1.2 + 0.6 * np.cos(theta - 0.3)) + s[:, 1],
    ])  # fmt: skip


def fake_evaluate(tables, which, s, tolerance, f=director_map) -> Answer:
    """The stretch surrogate of a fibred node table (its 7th entry the angle index) or of an
    isotropic table, answering the map f (the director map) exactly."""
    angles = np.array([
        t[6] * director_lattice.ANGLE_STEP if len(t) > 6 else 0.0 for t in tables
    ])[np.asarray(which, dtype=np.int64)]  # fmt: skip
    n = len(angles)
    return Answer(f(angles, np.reshape(s, (n, 2))), np.zeros(n), np.zeros(n, bool), 0)


def difference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.linalg.norm(a - b, axis=-1) / np.linalg.norm(b, axis=-1)


class ExactValues(dict):
    """The stretch surrogate's lattice values of the map f (the director map): a node table's
    value at a lattice point (finest integers), made when first read."""

    def __init__(self, f=director_map) -> None:
        super().__init__()
        self.f = f

    def __missing__(self, key: tuple) -> np.ndarray:
        table, point = key
        s = np.array([point], dtype=float) * (H0 / STEP)
        self[key] = self.f(np.array([table[6] * director_lattice.ANGLE_STEP]), s)[0]
        return self[key]


def interpolant(tolerance: float = 1e-3) -> director_lattice.DirectorInterpolant:
    return director_lattice.DirectorInterpolant(
        fake_evaluate, difference, tolerance, MPI.COMM_SELF, ExactValues()
    )


@pytest.mark.parametrize("count", [12, 24, 96])
def test_weights_are_periodic_interpolating_and_exact_for_trigonometric_polynomials(count):
    """Cardinal functions: the same at b, b + 180 and b - 360 (round-off); l_j(b_k) = delta_jk;
    they sum to 1; and they reproduce cos(k theta), sin(k theta) for k < N / 2 (theta = 2 pi b /
    180) to round-off, which a piecewise-linear interpolant does not."""
    b = np.random.default_rng(0).uniform(0.0, 180.0, 50)
    w = director_lattice.trigonometric_weights(b, count)
    for shifted in (b + 180.0, b - 360.0):
        w2 = director_lattice.trigonometric_weights(shifted, count)
        np.testing.assert_allclose(w2, w, rtol=0, atol=ROUND_OFF)
    nodes = np.arange(count) * 180.0 / count
    np.testing.assert_allclose(
        director_lattice.trigonometric_weights(nodes, count), np.eye(count), atol=ROUND_OFF
    )
    np.testing.assert_allclose(w.sum(axis=1), 1.0, rtol=0, atol=ROUND_OFF)
    theta, theta_nodes = np.radians(2.0 * b), np.radians(2.0 * nodes)
    for k in range(1, count // 2):
        for f in (np.cos, np.sin):
            np.testing.assert_allclose(w @ f(k * theta_nodes), f(k * theta), atol=1e-11)


def test_answers_at_angle_and_angle_plus_180_are_the_same():
    """A director is an axis: queries at b, b + 180 and b - 180 get the same answers (to
    round-off), whatever the node count the table reached, and an isotropic query among them
    is answered as it is."""
    rng = np.random.default_rng(1)
    b = rng.uniform(0.0, 180.0, 40)
    s = rng.uniform(-0.2, 0.2, (40, 2))
    angles = interpolant()
    tables = [FIBRED, PLAIN]
    which = np.r_[np.zeros(120, dtype=np.int64), 1]
    answer = angles(tables, which, np.vstack([s, s, s, [[0.1, 0.0]]]),
                    np.r_[b, b + 180.0, b - 180.0, 33.0])  # fmt: skip
    values = answer.values
    np.testing.assert_allclose(values[40:80], values[:40], rtol=0, atol=ROUND_OFF)
    np.testing.assert_allclose(values[80:120], values[:40], rtol=0, atol=ROUND_OFF)
    np.testing.assert_array_equal(values[120], director_map(np.zeros(1), np.array([[0.1, 0.0]]))[0])


@pytest.mark.parametrize("tolerance", [1e-3, 1e-6])
def test_node_count_is_refined_to_the_tolerance_and_is_one_per_table(tolerance):
    """The table's node count doubles until the estimate (against every other node) is within
    the tolerance for every query; the true error is then below it by far (spectral
    convergence: measured 1.3e-7 with 24 nodes at 1e-3, 3e-14 with 48 at 1e-6). One count
    serves all of the table's queries, so the answer is one smooth function of the angle."""
    b = np.linspace(0.0, 180.0, 721)[:-1]
    s = np.zeros((len(b), 2))
    angles = interpolant(tolerance)
    answer = angles([FIBRED], np.zeros(len(b), dtype=np.int64), s, b)
    error = difference(answer.values, director_map(b, s)).max()
    count = angles.count(FIBRED)
    print(f"tolerance {tolerance:g}: {count} nodes, largest error {error:.2g}")
    assert error <= tolerance
    assert answer.estimates.max() <= tolerance
    assert count <= (24 if tolerance > 1e-4 else 48)


def test_a_director_on_a_node_asks_that_node_alone():
    """The other nodes' cardinal functions are 0 at a node (and the surplus terms' weights), so
    a query whose director is on the node 90 (or 270, the same axis) asks that node's table
    alone, at its stretch, and is answered by it exactly; a query off the node, in the same
    call, still asks all M. Before, every query asked every fine node (those of weight 0 at
    tolerance 1): 24 solves on a fibred reference scene (rotation-free growth) instead of 4."""
    asked: dict[tuple, set] = {}  # stretch -> the tables asked there

    def recording(tables, which, s_asked, tolerance) -> Answer:
        which = np.asarray(which, dtype=np.int64)
        for t, point in zip(which.tolist(), np.reshape(s_asked, (-1, 2)).tolist(), strict=True):
            asked.setdefault(tuple(point), set()).add(tables[t])
        return fake_evaluate(tables, which, s_asked, tolerance)

    angles = director_lattice.DirectorInterpolant(
        recording, difference, 1e-3, MPI.COMM_SELF, ExactValues()
    )
    s = np.array([[0.05, 0.01], [-0.02, 0.03], [0.01, -0.04]])
    b = np.array([90.0, 270.0, 100.0])
    answer = angles([FIBRED], np.zeros(3, dtype=np.int64), s, b)
    count = angles.count(FIBRED)
    node = FIBRED + (director_lattice.PERIOD // 2,)  # 90 degrees
    fine = {FIBRED + (j * director_lattice.PERIOD // count,) for j in range(count)}
    assert asked[tuple(s[0])] == asked[tuple(s[1])] == {node}
    assert asked[tuple(s[2])] == fine
    np.testing.assert_array_equal(answer.values[:2], director_map(np.full(2, 90.0), s[:2]))


def curved_map(b: np.ndarray, s: np.ndarray) -> np.ndarray:
    """The director map with an angle dependence that varies with the stretch (exp(3 s1)):
    the angle surpluses are then not linear in s, so the coarse grids' bilinear interpolants
    of them have an error (the stretch surrogate's role)."""
    theta = np.radians(2.0 * b)
    values = director_map(b, s)
    values[:, 0] += np.exp(3.0 * s[:, 0]) / (1.6 + 0.6 * np.cos(theta + 4.0 * s[:, 1]))
    return values


def test_new_angle_nodes_are_asked_on_the_coarse_stretch_grids_only():
    """The sparse grid (director_lattice.SURPLUS_TERMS): only the M fine nodes are asked at
    the queries' own stretches; the nodes the surplus terms add (3M of 4M) are asked only at
    the builders of the stretch grids' squares (one per square: here 6 level-1 and 4 level-0
    squares), whatever the number of queries. The answer is within the tolerance 1e-3 of the
    map (measured 2e-4, M = 6), which I_M alone misses by far (measured 1.9e-2: the surplus
    terms carry the angle dependence past the M nodes). The old interpolant asked all 24
    nodes at every query's stretch, and fails the count of asked stretches."""
    rng = np.random.default_rng(2)
    b = rng.uniform(60.0, 120.0, 300)
    s = np.column_stack([rng.uniform(0.0, 0.15, 300), rng.uniform(-0.015, 0.04, 300)])
    asked: dict[tuple, set] = {}

    def recording(tables, which, s_asked, tolerance) -> Answer:
        which = np.asarray(which, dtype=np.int64)
        for t, point in zip(which.tolist(), np.reshape(s_asked, (-1, 2)).tolist(), strict=True):
            asked.setdefault(tables[t], set()).add(tuple(point))
        return fake_evaluate(tables, which, s_asked, tolerance, curved_map)

    angles = director_lattice.DirectorInterpolant(
        recording, difference, 1e-3, MPI.COMM_SELF, ExactValues(curved_map)
    )
    answer = angles([FIBRED], np.zeros(len(b), dtype=np.int64), s, b)
    exact = curved_map(b, s)
    error = difference(answer.values, exact).max()
    count = angles.count(FIBRED)
    fine_only = np.einsum(
        "qj,jqm->qm", director_lattice.trigonometric_weights(b, count),
        np.array([curved_map(np.full(len(b), a), s) for a in np.arange(count) * 180.0 / count]),
    )  # fmt: skip
    coarse_error = difference(fine_only, exact).max()
    print(f"M {count}: error {error:.2g}, I_M alone {coarse_error:.2g}")
    assert error <= 1e-3 < coarse_error
    fine = {FIBRED + (j * director_lattice.PERIOD // count,) for j in range(count)}
    assert len(asked) == 4 * count and fine <= asked.keys()
    level1, level0 = (len(np.unique(np.floor(s / h), axis=0)) for h in (H0 / 2, H0))
    for node, points in asked.items():
        on_level1 = node[6] % (director_lattice.PERIOD // (2 * count)) == 0  # a node of 2M
        grids = level0 + level1 * on_level1
        assert len(points) == grids + len(b) * (node in fine)


@pytest.mark.parametrize("level", [0, 1, 3])
def test_grid_squares_are_the_sorted_distinct_squares_whose_hats_rebuild_each_stretch(level):
    """angle_surplus.grid_squares on stretches of both signs, some on grid lines: its squares
    are numpy's row-wise unique of the queries' squares (distinct, sorted, the same inverse;
    the builders are asked in that order), and each query's four hats over its square's
    corners rebuild its stretch (the bilinear hats reproduce linear functions): to half a unit
    of the 9th decimal of a grid step, to which the hats' coordinates are rounded as the
    stretch lattice rounds (so that a query on a grid line takes one square), plus round-off;
    a wrong square or hat misses by a grid step."""
    rng = np.random.default_rng(7)
    h = H0 / 2.0**level
    s = np.vstack([
        np.column_stack([rng.uniform(-0.05, 0.15, 500), rng.uniform(-0.03, 0.04, 500)]),
        h * rng.integers(-3, 4, size=(20, 2)),  # on grid lines: one square, a hat of 1
        np.zeros((1, 2)),
    ])  # fmt: skip
    squares, square, hats = angle_surplus.grid_squares(s, level)
    expected, inverse = np.unique(np.floor(np.round(s / h, 9)).astype(np.int64), axis=0,
                                  return_inverse=True)  # fmt: skip
    assert np.array_equal(squares, expected) and np.array_equal(square, inverse.reshape(-1))
    corners = squares[square][:, None, :] + np.array([[0, 0], [1, 0], [0, 1], [1, 1]])[None]
    rebuilt = h * np.einsum("qc,qcd->qd", hats, corners)
    assert np.abs(rebuilt - s).max() <= h * (0.5e-9 + ROUND_OFF)
    assert np.allclose(hats.sum(axis=1), 1.0, rtol=0.0, atol=ROUND_OFF) and hats.min() >= 0.0
    empty = angle_surplus.grid_squares(np.zeros((0, 2)), level)
    assert empty[0].shape == (0, 2) and len(empty[1]) == 0 and empty[2].shape == (0, 4)


def degree_four_map(b: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(n, 2) values whose angle dependence has degree 4 in theta = 2 pi b / 180 (12 nodes
    reproduce it, 6 do not) with amplitudes not bilinear in s."""
    theta = np.radians(2.0 * b)
    return np.column_stack([
        2.0 + np.exp(3.0 * s[:, 0]) * np.cos(4.0 * theta + 5.0 * s[:, 1]),
        1.5 + 0.3 * np.exp(2.0 * s[:, 1]) * np.sin(4.0 * theta),
    ])  # fmt: skip


def test_the_2M_nodes_surplus_is_exact_on_the_level1_grid():
    """A(b, s) = I_M f + (I_2M - I_M)[P_1 f] + (I_4M - I_2M)[P_0 f]: for a map of degree 4 in the
    angle (I_12 and I_24 reproduce it exactly, so the last surplus is 0) and at points of the
    level-1 stretch grid (where P_1 is exact) that are not level-0 points, A is I_12 f = f to
    round-off (1e-12, the module's: the stretch tables are exact here), although I_6 alone
    misses by far (measured 1.2) and P_0 would not be exact there. With the surpluses on
    each other's grids (the larger one on level 0) the answer misses by P_0's error."""
    rng = np.random.default_rng(3)
    points = np.array([[0.05, 0.0], [0.0, 0.05], [0.05, 0.05], [0.15, -0.05]])
    # angles 1.5 degrees or more from the fine nodes: A, not the near-node form, answers there
    b = rng.uniform(1.5, 28.5, 10 * len(points)) + 30.0 * rng.integers(0, 6, 10 * len(points))
    s = np.repeat(points, 10, axis=0)

    def evaluate(tables, which, s_asked, tolerance) -> Answer:
        return fake_evaluate(tables, which, s_asked, tolerance, degree_four_map)

    # tolerance 0.5: the node count stays at M = 6 (12 would make I_M itself exact)
    angles = director_lattice.DirectorInterpolant(
        evaluate, difference, 0.5, MPI.COMM_SELF, ExactValues(degree_four_map)
    )
    answer = angles([FIBRED], np.zeros(len(b), dtype=np.int64), s, b)
    assert angles.count(FIBRED) == 6
    exact = degree_four_map(b, s)
    fine = np.arange(6) * 30.0
    only_fine = np.einsum(
        "qj,jqm->qm", director_lattice.trigonometric_weights(b, 6),
        np.array([degree_four_map(np.full(len(b), a), s) for a in fine]),
    )  # fmt: skip
    print(f"A: {difference(answer.values, exact).max():.2g}, I_6 alone: "
          f"{difference(only_fine, exact).max():.2g}")  # fmt: skip
    assert difference(answer.values, exact).max() <= ROUND_OFF
    assert difference(only_fine, exact).max() > 0.1


@pytest.mark.parametrize("tolerance", [1e-2, 1e-3, 1e-4])
def test_the_near_node_blend_is_a_c1_step_in_the_distance_to_the_nearest_node(tolerance):
    """0 within the zone's first distance of a node (on either side, and across 0 = 180), 1
    beyond its second, increasing in between with zero slope at both ends (C1); the zone is
    proportional to the tolerance (A_k's error is linear in the distance)."""
    count = 6
    low, high = director_lattice.near_node_zone(tolerance, count)
    tenth = director_lattice.near_node_zone(0.1 * tolerance, count)
    assert np.allclose(tenth, [0.1 * low, 0.1 * high], rtol=ROUND_OFF)
    assert high <= 30.0 * director_lattice.NEAR_NODE_WIDEST  # at most that much of the spacing
    widest = director_lattice.near_node_zone(10.0 * tolerance, 2 * count)
    assert widest[1] <= 15.0 * director_lattice.NEAR_NODE_WIDEST * (1.0 + ROUND_OFF)
    b = np.array([90.0, 90.0 - 0.9 * low, 0.5 * low, 180.0 - 0.5 * low, 90.0 + 1.1 * high, 105.0])
    nearest, blend = director_lattice.near_node_blend(b, count, tolerance)
    assert nearest.tolist() == [3, 3, 0, 0, 3, 4]  # 105 is a midpoint: either; round-half-even
    assert blend.tolist() == [0.0, 0.0, 0.0, 0.0, 1.0, 1.0]
    inside = 90.0 + np.linspace(low, high, 201)
    step = director_lattice.near_node_blend(inside, count, tolerance)[1]
    assert step[0] < ROUND_OFF and step[-1] > 1.0 - ROUND_OFF and np.all(np.diff(step) > 0.0)
    slope = np.diff(step) / np.diff(inside)
    assert slope[0] < 0.02 * slope.max() and slope[-1] < 0.02 * slope.max()


def test_a_director_near_a_node_asks_that_node_and_the_level0_grid_and_is_continuous():
    """Within the near-node zone's first distance of node 90 a query asks node 90's table at
    its own stretch, the other nodes only at the level-0 grid's builders, and none of the
    surplus grids' new nodes; its
    answer is A_k = S_k + (I_M - I_k)[P_0 f], which for a map linear in s (P_0 exact) is I_M f
    itself (round-off). Across the blend zone, for a map whose angle dependence varies with s
    (P_0 not exact, so A_k and A differ), the answer changes from sample to sample by no more
    than the exact map does plus 1e-3 of the tolerance (1e-6 relative): no jump where A_k gives
    way to A (a step at mid-zone in place of the C1 blend fails this: checked)."""
    low, high = director_lattice.near_node_zone(1e-3, 6)
    asked: dict[tuple, set] = {}

    def recording(f):
        def evaluate(tables, which, s_asked, tolerance) -> Answer:
            which = np.asarray(which, dtype=np.int64)
            for t, point in zip(which.tolist(), np.reshape(s_asked, (-1, 2)).tolist(),
                                strict=True):  # fmt: skip
                asked.setdefault(tuple(point), set()).add(tables[t])
            return fake_evaluate(tables, which, s_asked, tolerance, f)

        return evaluate

    s = np.array([[0.034, 0.012], [-0.021, 0.047]])
    b = np.array([90.0 + 0.5 * low, 90.0 - 0.8 * low])
    angles = director_lattice.DirectorInterpolant(
        recording(director_map), difference, 1e-3, MPI.COMM_SELF, ExactValues()
    )
    answer = angles([FIBRED], np.zeros(2, dtype=np.int64), s, b)
    count = angles.count(FIBRED)
    node = FIBRED + (director_lattice.PERIOD // 2,)
    assert asked[tuple(s[0])] == asked[tuple(s[1])] == {node}
    builders = {(0.0, 0.0), (-0.1, 0.0)}  # the level-0 squares' lower-left corners
    assert asked.keys() == {tuple(s[0]), tuple(s[1])} | builders
    nodes = {FIBRED + (j * director_lattice.PERIOD // count,) for j in range(count)}
    assert all(asked[p] == nodes for p in builders)
    fine = np.array([director_map(np.full(2, a), s) for a in np.arange(count) * 180.0 / count])
    I_M = np.einsum("qj,jqm->qm", director_lattice.trigonometric_weights(b, count), fine)
    np.testing.assert_allclose(answer.values, I_M, rtol=ROUND_OFF)

    b = 90.0 + np.linspace(0.5 * low, 1.5 * high, 401)
    s = np.tile([[0.034, 0.012]], (len(b), 1))
    angles = director_lattice.DirectorInterpolant(
        recording(curved_map), difference, 1e-3, MPI.COMM_SELF, ExactValues(curved_map)
    )
    values = angles([FIBRED], np.zeros(len(b), dtype=np.int64), s, b).values
    exact = curved_map(b, s)
    scale = np.linalg.norm(exact, axis=1)[:-1]
    moved = np.linalg.norm(np.diff(values, axis=0), axis=1) / scale
    exact_moved = np.linalg.norm(np.diff(exact, axis=0), axis=1) / scale
    assert np.all(moved <= exact_moved + 1e-6)
    print(f"largest change {moved.max():.2g}, the exact map's {exact_moved.max():.2g}")
    assert difference(values, exact).max() <= 1e-3
