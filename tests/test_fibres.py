"""The fibre director (plantgrowth/models/fibres.py): the cue of a tensor against numpy's
eigen-solver, the exact one-step feedback update (consequence 5 of docs/model.md's fibre
section: a constant anisotropic cue is followed along the closed form, an isotropic one leaves
the director alone), and the summary statistics, serial = mpirun."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

from plantgrowth.models import fibres

EPS = np.finfo(float).eps
ROUND_OFF = 1e-10
"""Degrees: the closed form's round-off after up to 200 steps (each step's tan/atan costs a few
ulp of 90 degrees, ~1e-14; measured 2.9e-12 after 200 steps of dt = 0.01)."""


def _apart(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a - b| between two axes (degrees), modulo 180."""
    return np.abs(fibres.reduce_angle(np.asarray(a) - np.asarray(b)))


def _closed_form(a0, a_Q, kA, t):
    """tan(a(t) - a_Q) = tan(a0 - a_Q) exp(-k A t), written out independently (radians)."""
    d0 = np.radians(fibres.reduce_angle(a0 - a_Q))
    return a_Q + np.degrees(np.arctan(np.tan(d0) * np.exp(-kA * t)))


# --- the cue --------------------------------------------------------------------------------------


def test_cue_matches_numpy_eigh_on_random_tensors():
    rng = np.random.default_rng(22)
    A = rng.normal(size=(500, 2, 2)) * 10.0 ** rng.uniform(-3, 3, size=(500, 1, 1))
    Q = 0.5 * (A + A.transpose(0, 2, 1))
    values, vectors = np.linalg.eigh(Q)  # ascending
    q1, q2, v1 = values[:, 1], values[:, 0], vectors[:, :, 1]
    c = fibres.cue(Q)
    scale = np.abs(values).max(axis=1)
    # eigenvalues: backward stable, error a few eps |Q|
    assert np.all(np.abs(c.q1 - q1) <= 8 * EPS * scale)
    assert np.all(np.abs(c.q2 - q2) <= 8 * EPS * scale)
    # A's error: that of q1 - q2 over |q1| + |q2| >= |Q|
    assert np.allclose(c.anisotropy, (q1 - q2) / (np.abs(q1) + np.abs(q2)), rtol=0, atol=32 * EPS)
    # eigenvector: error ~ eps |Q| / (q1 - q2) radians (Davis-Kahan), with a factor 100 of slack
    expected = np.degrees(np.arctan2(v1[:, 1], v1[:, 0]))
    bound = np.degrees(100 * EPS * scale / (q1 - q2))
    assert np.all(_apart(c.angle, expected) <= bound)
    assert np.all((c.angle > -90.0) & (c.angle <= 90.0))


def test_cue_of_known_tensors():
    Q = np.array([
        [[2.0, 0.0], [0.0, 1.0]],    # along x1, A = 1/3
        [[1.0, 0.0], [0.0, 2.0]],    # along x2: 90, never -90
        [[0.0, 1.0], [1.0, 0.0]],    # q = +-1 along 45 degrees, A = 1
        [[3.0, 0.0], [0.0, 3.0]],    # isotropic: A = 0
        [[0.0, 0.0], [0.0, 0.0]],    # zero: A = 0
        [[-1.0, 0.0], [0.0, -3.0]],  # compression: q1 = -1 along x1, A = 1/2
    ])  # fmt: skip
    c = fibres.cue(Q)
    assert c.angle.tolist() == [0.0, 90.0, 45.0, 0.0, 0.0, 0.0]
    assert np.allclose(c.anisotropy, [1 / 3, 1 / 3, 1.0, 0.0, 0.0, 0.5], rtol=0, atol=4 * EPS)
    assert c.q1.tolist() == [2.0, 2.0, 1.0, 3.0, 0.0, -1.0]


# --- the one-step update (consequence 5) ----------------------------------------------------------


@pytest.mark.parametrize("dt", [0.01, 0.3, 1.0, 7.0])
def test_constant_cue_follows_the_closed_form_at_every_step(dt):
    rng = np.random.default_rng(5)
    a0, a_Q = rng.uniform(-90, 90, 200), rng.uniform(-90, 90, 200)
    A, k = rng.uniform(0.05, 1.0, 200), 0.7
    a = a0.copy()
    for step in range(1, 201):
        a = fibres.turn_director(a, a_Q, A, k, dt)
        assert np.all(_apart(a, _closed_form(a0, a_Q, k * A, step * dt)) <= ROUND_OFF), step
        assert np.all((a > -90.0) & (a <= 90.0))


def test_the_director_turns_monotonically_and_never_overshoots():
    rng = np.random.default_rng(7)
    a_Q = rng.uniform(-90, 90, 1000)
    a = a_Q + rng.uniform(-89.9, 89.9, 1000)
    gap = fibres.reduce_angle(a - a_Q)
    for kAdt in [1e-3, 0.5, 3.0, 40.0, 1e3]:  # up to exp(-1000) = 0: lands on a_Q, not beyond
        a = fibres.turn_director(a, a_Q, 1.0, kAdt, 1.0)
        new = fibres.reduce_angle(a - a_Q)
        # |gap| shrinks and keeps its sign, to the round-off of a - a_Q (a few ulp of 90 deg)
        assert np.all(np.abs(new) <= np.abs(gap) + 1e-12)
        assert np.all(new * np.sign(gap) >= -1e-12)
        gap = new
    assert np.all(np.abs(gap) <= 1e-12)


def test_an_isotropic_cue_or_no_rate_leaves_the_director_unchanged():
    a = np.array([-89.5, -30.0, 0.0, 12.345, 90.0, 135.0])  # 135 -> -45 (reduced)
    same = fibres.reduce_angle(a)
    assert fibres.turn_director(a, 17.0, 0.0, 5.0, 1.0).tolist() == same.tolist()
    assert fibres.turn_director(a, 17.0, 0.8, 0.0, 1.0).tolist() == same.tolist()
    assert fibres.turn_director(a, 17.0, 0.8, 5.0, 0.0).tolist() == same.tolist()


def test_the_director_is_an_axis():
    rng = np.random.default_rng(9)
    a, a_Q, A = rng.uniform(-90, 90, 300), rng.uniform(-90, 90, 300), rng.uniform(0, 1, 300)
    turned = fibres.turn_director(a, a_Q, A, 0.8, 1.3)
    for shift_a, shift_Q in [(180, 0), (-180, 0), (0, 180), (360, -540)]:
        again = fibres.turn_director(a + shift_a, a_Q + shift_Q, A, 0.8, 1.3)
        assert np.all(_apart(again, turned) <= ROUND_OFF)
    assert fibres.reduce_angle(np.array([-90.0, 90.0, 270.0, -270.0, 180.0])).tolist() == [
        90.0, 90.0, 90.0, 90.0, 0.0,
    ]  # fmt: skip


def test_across_the_cue_the_director_stays_and_near_it_turns():
    """d = 90 is the unstable equilibrium: the exact solution stays there; 1e-9 degrees off,
    the director turns toward a_Q (to 45 degrees off when tan(d) exp(-k A dt) = 1)."""
    assert fibres.turn_director(np.array([90.0, -60.0]), np.array([0.0, 30.0]), 1.0, 50.0, 1.0
                                ).tolist() == [90.0, -60.0]  # fmt: skip
    d = 90.0 - 1e-9
    kAdt = np.log(np.tan(np.radians(d)))  # tan(d) exp(-kA dt) = 1: d_new = 45
    turned = fibres.turn_director(np.array([d]), 0.0, 1.0, kAdt, 1.0)
    assert abs(turned[0] - 45.0) <= 1e-6  # tan's conditioning at d: ~eps tan(d) ~ 1e-5 relative


def _rk4(a0: float, a_Q: float, kA: float, t: float, n: int) -> float:
    """da/dt = -(k A / 2) sin(2 (a - a_Q)) by n classical RK4 steps (radians inside)."""
    a, q, h = np.radians(a0), np.radians(a_Q), t / n

    def f(x: float) -> float:
        return -0.5 * kA * np.sin(2.0 * (x - q))

    for _ in range(n):
        k1 = f(a)
        k2 = f(a + 0.5 * h * k1)
        k3 = f(a + 0.5 * h * k2)
        k4 = f(a + h * k3)
        a += h * (k1 + 2 * k2 + 2 * k3 + k4) / 6
    return float(np.degrees(a))


@pytest.mark.parametrize("a0, a_Q, kA", [(80.0, 0.0, 1.0), (-70.0, 35.0, 0.4), (10.0, -5.0, 2.0)])
def test_rk4_agrees_with_the_one_step_solution(a0, a_Q, kA):
    """RK4 converges at fourth order to the exact step: its error falls ~16-fold when h halves,
    and with 2000 steps over t = 4 (kA h <= 4e-3) it is below 1e-9 degrees (the error constant
    ~ t (kA h)^4 / 5! ~ 1e-11 radians)."""
    t = 4.0
    exact = float(fibres.turn_director(np.array([a0]), a_Q, kA, 1.0, t)[0])
    coarse, fine = (_apart(_rk4(a0, a_Q, kA, t, n), exact) for n in (20, 40))
    assert 12.0 < coarse / fine < 20.0
    assert _apart(_rk4(a0, a_Q, kA, t, 2000), exact) < 1e-9


# --- the director field and its statistics --------------------------------------------------------


def test_director_is_the_unit_vector_of_the_angle():
    m = fibres.director(np.array([0.0, 90.0, -45.0, 30.0]))
    assert np.allclose(m, [[1, 0], [0, 1], [np.sqrt(0.5), -np.sqrt(0.5)],
                           [np.sqrt(3) / 2, 0.5]], rtol=0, atol=4 * EPS)  # fmt: skip
    assert np.allclose(np.linalg.norm(m, axis=1), 1.0, rtol=0, atol=2 * EPS)


def test_all_parallel_fibres_have_order_one():
    rng = np.random.default_rng(3)
    areas = rng.uniform(0.1, 1.0, 50)
    for a in (0.0, 37.5, 90.0, -60.0):
        # 180 apart is the same axis: order 1
        angles = np.where(rng.random(50) < 0.5, a, a + 180.0)
        order, mean = fibres.fibre_statistics(angles, areas, MPI.COMM_SELF)
        assert abs(order - 1.0) <= 8 * EPS  # round-off of a sum of 50 terms, relative
        assert _apart(mean, a) <= 1e-12


def test_two_perpendicular_families_of_equal_area_have_order_zero():
    angles = np.array([20.0, 20.0, 110.0, 110.0, 110.0])
    areas = np.array([0.75, 0.75, 0.5, 0.5, 0.5])
    order, mean = fibres.fibre_statistics(angles, areas, MPI.COMM_SELF)
    assert order <= 1e-15 and mean == 0.0  # no mean direction: reported as 0
    # unequal areas: the larger family's direction, order = the area imbalance
    order, mean = fibres.fibre_statistics(
        angles, np.array([1.0, 1.0, 0.5, 0.5, 0.5]), MPI.COMM_SELF
    )
    assert abs(order - 0.5 / 3.5) <= 1e-15 and abs(mean - 20.0) <= 1e-12


@pytest.mark.mpi
def test_statistics_serial_equals_mpirun():
    """Each rank holds an interleaved share of one global field; the collective statistics
    equal those of the whole field on one rank (to the round-off of a reordered sum)."""
    comm = MPI.COMM_WORLD
    rng = np.random.default_rng(11)
    angles, areas = rng.normal(25.0, 20.0, 1001), rng.uniform(0.5, 1.5, 1001)
    whole = fibres.fibre_statistics(angles, areas, MPI.COMM_SELF)
    share = slice(comm.rank, None, comm.size)
    shared = fibres.fibre_statistics(angles[share], areas[share], comm)
    assert 0.5 < whole[0] < 1.0
    assert abs(shared[0] - whole[0]) <= 1e-14 and abs(shared[1] - whole[1]) <= 1e-12
    assert comm.allgather(shared) == [shared] * comm.size  # the same on every rank
