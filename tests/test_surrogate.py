"""The error-controlled surrogate of the cell problems (plantgrowth/unitcell/surrogate.py, issue 9).

Checks: the polar split is exact; the error estimate bounds the true error on random inputs
of the reduced space; E_hom stays symmetric positive definite; the rotation is applied
exactly; tolerance 0 is the exact path; ranks share the work and agree with one rank.
Cell meshes at resolution 1 (one P2 element across a wall) keep the module at a few seconds:
the surrogate's error is measured against exact solves on the same mesh, so the mesh's own
discretization error does not enter.
"""

from __future__ import annotations

import logging
import re

import numpy as np
import pytest
from mpi4py import MPI

from plantgrowth.base.tensors import (
    det2,
    extreme_eigenvalues_sym3,
    inv2,
    rotate2,
    rotate4,
    rotate_symmetric2,
    rotate_symmetric4,
    rotate_voigt,
    smallest_eigenvalue_sym3,
    tensor_from_voigt,
    voigt_matrix,
    voigt_rotation,
)
from plantgrowth.unitcell import surrogate
from plantgrowth.unitcell.homogenization import Homogenizer

pytestmark = pytest.mark.mpi  # scripts/README.md, "Tests": every test also runs on 2 ranks

ROUND_OFF = 1e-12
GEOMETRY = np.array([[1.5, 1.0, 30.0, 0.1]])  # l1 = 1.5: orthotropic, so rotations show


def random_growth(rng: np.random.Generator, n: int, spread: float = 0.3) -> np.ndarray:
    """Growth tensors g R(angle) expm(S), |s_i| <= spread, any rotation and scale."""
    out = []
    for _ in range(n):
        angle, g = rng.uniform(-np.pi, np.pi), rng.uniform(0.8, 3.0)
        R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        out.append(g * R @ surrogate.stretch(rng.uniform(-spread, spread, 2)))
    return np.array(out)


def homogenizer(tolerance: float, comm=MPI.COMM_SELF, strain: bool = True) -> Homogenizer:
    return Homogenizer(1, 1e-6, True, strain, comm, tolerance)


def test_polar_split_recovers_the_growth_tensor():
    """``Fg / sqrt(det Fg) = R expm(S)`` with R a rotation: round-off."""
    Fg = random_growth(np.random.default_rng(0), 50, spread=1.0)
    R, s = surrogate.split_growth(Fg)
    U = np.array([surrogate.stretch(x) for x in s])
    F = Fg / np.sqrt(np.linalg.det(Fg))[:, None, None]
    np.testing.assert_allclose(R @ U, F, atol=ROUND_OFF)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=ROUND_OFF)
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.tile(np.eye(2), (50, 1, 1)), atol=1e-12)


def test_voigt_round_trip_and_rotations():
    C = np.random.default_rng(1).normal(size=(4, 3, 3))
    C = C + np.swapaxes(C, 1, 2)
    np.testing.assert_array_equal(voigt_matrix(tensor_from_voigt(C)), C)
    R = surrogate.split_growth(random_growth(np.random.default_rng(2), 4))[0]
    T = tensor_from_voigt(C)
    np.testing.assert_allclose(rotate4(np.swapaxes(R, 1, 2), rotate4(R, T)), T, atol=1e-12)
    K = C[:, :2, :2]
    np.testing.assert_allclose(rotate2(np.swapaxes(R, 1, 2), rotate2(R, K)), K, atol=1e-12)
    # the Voigt shortcut is the full 4th-order rotation (round-off of a few products of O(1))
    turned = voigt_matrix(rotate4(R, T))
    np.testing.assert_allclose(rotate_voigt(R, C), turned, rtol=0.0, atol=1e-12)
    # the symmetric forms (K_hom, dbar[v]; dbar[w]: minor symmetries, no major one) are the
    # full rotations, to the same round-off
    turn = voigt_rotation(R)
    np.testing.assert_allclose(rotate_symmetric2(turn, K), rotate2(R, K), rtol=0.0, atol=1e-12)
    D = T + np.random.default_rng(3).normal(size=(4, 2, 2, 1, 1)) * np.eye(2)
    D = 0.5 * (D + np.swapaxes(D, 1, 2))
    assert np.abs(D - np.swapaxes(D, 1, 3)).max() > 0.1  # no major symmetry
    np.testing.assert_allclose(rotate_symmetric4(turn, D), rotate4(R, D), rtol=0.0, atol=1e-12)


def test_closed_forms_agree_with_numpy():
    """det2, inv2, smallest_eigenvalue_sym3 and extreme_eigenvalues_sym3 (the per-cell closed
    forms of every step) against numpy's batched LU and eigensolver, on random matrices and on
    nearly singular ones (an eigenvalue 1e-6 of the largest, as a honeycomb's shear modulus is
    1e-2 of its stiffness): agreement to round-off of the entries' size (1e-12)."""
    rng = np.random.default_rng(3)
    A = rng.normal(size=(200, 2, 2))
    np.testing.assert_allclose(det2(A), np.linalg.det(A), rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(inv2(A) @ A, np.tile(np.eye(2), (200, 1, 1)), atol=1e-9)
    B = rng.normal(size=(200, 3, 3))
    B = B + np.swapaxes(B, 1, 2)
    Q = np.linalg.qr(rng.normal(size=(200, 3, 3)))[0]
    small = Q @ (np.array([1e-6, 0.5, 1.0])[None, :, None] * np.swapaxes(Q, 1, 2))
    for M in (B, small):
        expected = np.linalg.eigvalsh(M)
        smallest, largest = extreme_eigenvalues_sym3(M)
        np.testing.assert_array_equal(smallest_eigenvalue_sym3(M), smallest)
        np.testing.assert_allclose(smallest, expected[:, 0], rtol=0.0, atol=1e-12)
        np.testing.assert_allclose(largest, expected[:, -1], rtol=0.0, atol=1e-12)


@pytest.mark.skip_in_parallel
@pytest.mark.parametrize("tolerance", [1e-2, 1e-3])
def test_error_estimate_bounds_the_true_error_on_random_inputs(tolerance):
    """40 random stretches with |s_i| <= 0.3 (a 35% deviatoric stretch): every true error
    (against an exact solve at the same point) is below its estimate and below the tolerance.
    Measured (resolution 1, this test): largest error 0.31 (1e-2) and 0.44 (1e-3) times the
    tolerance with 156 and 326 solves (the per-query levels before issue 33: 0.31 and 0.77 with
    131 and 305 solves; all five children of a refined square and KEEP = 0.5: 0.25 and 0.35
    with 254 and 503). The estimate is the hat-weighted surpluses of the last refinement, exact
    enough for these smooth maps. Lattice points are shared: fewer solves than the queries would
    need each alone (the 4 corners of its level-0 square, 3 more per deeper built square).
    """
    h = homogenizer(tolerance)
    table = h._key(GEOMETRY[0], 0.3, np.eye(2))[:5]
    s = np.random.default_rng(3).uniform(-0.3, 0.3, size=(40, 2))
    answer = h.surrogate.evaluate([table], np.zeros(len(s), dtype=int), s)
    values, estimates, solves = answer.values, answer.estimates, answer.solves
    exact = np.array([h._solve_stretch(table, surrogate.stretch(x)) for x in s])
    errors = h.surrogate.relative_difference(values, exact)
    print(f"tolerance {tolerance:g}: {solves} lattice solves, largest error {errors.max():.2e}")
    assert np.all(errors <= estimates)
    assert errors.max() <= tolerance
    ids = np.zeros(len(s), dtype=np.int64)
    alone = 4 + 3 * h.surrogate._deepest(ids, s)[0]  # a query's own chain of squares
    assert solves < alone.sum()


@pytest.mark.skip_in_parallel
def test_E_hom_stays_symmetric_positive_definite():
    """Large stretches, all rotations: the interpolated Voigt matrix is SPD at every node."""
    h = homogenizer(1e-2, strain=False)
    Fg = random_growth(np.random.default_rng(4), 60, spread=0.7)
    n = len(Fg)
    C = h.homogenize(np.repeat(GEOMETRY, n, 0), np.ones(n), np.full(n, 0.3), Fg).C
    assert np.abs(C - np.swapaxes(C, 1, 2)).max() <= 1e-12 * np.abs(C).max()
    assert np.linalg.eigvalsh(C).min() > 0.0


@pytest.mark.skip_in_parallel
def test_rotation_is_applied_exactly_and_agrees_with_an_exact_solve():
    """Fg = R U: the surrogate's answer is its answer at U rotated by R (round-off), and is
    within the tolerance of an exact cell solve at Fg itself (relative, per quantity)."""
    tolerance = 1e-3
    h, exact = homogenizer(tolerance), homogenizer(0.0)
    Fg = random_growth(np.random.default_rng(5), 6, spread=0.2)
    R, s = surrogate.split_growth(Fg)
    U = np.array([surrogate.stretch(x) for x in s])
    args = (np.repeat(GEOMETRY, 6, 0), np.full(6, 2.0), np.full(6, 0.3))
    rotated, unrotated, reference = (
        h.homogenize(*args, Fg),
        h.homogenize(*args, U),
        exact.homogenize(*args, Fg),
    )
    turned = voigt_matrix(rotate4(R, tensor_from_voigt(unrotated.C)))
    np.testing.assert_allclose(rotated.C, turned, rtol=0, atol=ROUND_OFF * np.abs(turned).max())
    for name in ("C", "K", "dbar_w", "dbar_v"):
        a, b = getattr(rotated, name).reshape(6, -1), getattr(reference, name).reshape(6, -1)
        error = np.linalg.norm(a - b, axis=1) / np.linalg.norm(b, axis=1)
        assert error.max() <= tolerance, (name, error)


def test_tolerance_zero_is_the_exact_solve():
    """cell_tolerance = 0 keeps the exact path: no surrogate, results of the cell solver."""
    h = homogenizer(0.0)
    assert h.surrogate is None
    Fg = np.array([[[1.1, 0.05], [0.0, 0.95]]])
    result = h.homogenize(GEOMETRY, np.ones(1), np.full(1, 0.3), Fg)
    key = h._key(GEOMETRY[0], 0.3, Fg[0])
    np.testing.assert_array_equal(result.C[0], h._results[key][:9].reshape(3, 3))


def test_ranks_share_the_lattice_and_agree_with_one_rank():
    """Under mpirun the lattice solves are split over the ranks (COMM_SELF solves, one
    allgather per round): the answers equal a single rank's to round-off."""
    Fg = random_growth(np.random.default_rng(6), 12, spread=0.15)
    args = (np.repeat(GEOMETRY, 12, 0), np.ones(12), np.full(12, 0.3), Fg)
    shared = homogenizer(1e-3, MPI.COMM_WORLD).homogenize(*args)
    alone = homogenizer(1e-3, MPI.COMM_SELF).homogenize(*args)
    for name in ("C", "K", "dbar_w", "dbar_v"):
        a, b = getattr(shared, name), getattr(alone, name)
        np.testing.assert_allclose(a, b, rtol=0, atol=ROUND_OFF * np.abs(b).max())


def test_each_rank_refines_only_its_block_of_queries(surrogate_lookups):
    """No serial work that grows with the tissue: each rank interpolates its own contiguous
    block of the queries (12 queries: 6 per rank on 2 ranks), and the answer it returns is
    still the whole one."""
    rows = surrogate_lookups
    Fg = random_growth(np.random.default_rng(7), 12, spread=0.15)
    args = (np.repeat(GEOMETRY, 12, 0), np.ones(12), np.full(12, 0.3), Fg)
    result = homogenizer(1e-3, MPI.COMM_WORLD).homogenize(*args)
    comm = MPI.COMM_WORLD
    assert result.C.shape == (12, 3, 3)
    first_round = rows[0]  # the squares of every query of this rank's block
    assert first_round == 12 // comm.size
    assert comm.allreduce(first_round) == 12


def water_coefficients(t) -> tuple[np.ndarray, np.ndarray]:
    """``b = (1 - phi_w) I - K_hom`` (n, 2, 2) and ``1/M = -tr dbar[v]`` (n,) of NodeTensors."""
    b = (1.0 - t.phi_w)[:, None, None] * np.eye(2) - t.K
    return b, -np.trace(t.dbar_v, axis1=1, axis2=2)


def water_bounds(t) -> tuple[np.ndarray, np.ndarray]:
    """The factors that turn the relative error of K_hom and dbar[v] into that of b and 1/M:
    b's error is K_hom's (phi_w depends on the geometry only: interpolated exactly), so
    ``|db| / |b| = (|K_hom| / |b|) |dK| / |K_hom|``; and ``|tr d| <= sqrt(2) |d|`` gives
    ``|d(1/M)| / (1/M) <= (sqrt(2) |dbar[v]| / |tr dbar[v]|) |d dbar[v]| / |dbar[v]|``."""
    b, inv_M = water_coefficients(t)
    norm = np.linalg.norm
    return norm(t.K, axis=(1, 2)) / norm(b, axis=(1, 2)), np.sqrt(2) * norm(
        t.dbar_v, axis=(1, 2)
    ) / np.abs(inv_M)


@pytest.mark.skip_in_parallel
def test_water_coefficients_b_and_storage_agree_with_exact_solves_off_the_lattice(caplog):
    """b and 1/M (docs/model.md, "The unit cell's coefficients") from the surrogate at 12
    random growth tensors (any rotation and scale, |s_i| <= 0.3, off every lattice point) and
    random E, against exact cell solves there: relative error of b within ``|K_hom|/|b|`` times
    the tolerance and of 1/M within ``sqrt(2) |dbar[v]| / |tr dbar[v]|`` times it (the segments'
    errors are within the tolerance: test above; :func:`water_bounds` turns them into b's and
    1/M's). dbar[v] is negative definite here, so the second factor is at most sqrt(2): 1/M is
    no small difference (measured 1.0-1.3, benchmarks/results/surrogate_water.json); |K_hom|/|b|
    is 0.1-0.3, so b is several times more accurate than the tolerance. Measured: b 0.011, 1/M
    0.045 of the tolerance (12 solves at 1e-3, resolution 1). The run's own check (the first
    call checks one random query against an exact solve) logs b's and 1/M's errors there,
    within the same bounds."""
    tolerance = 1e-3
    h = Homogenizer(1, 1e-6, True, True, MPI.COMM_SELF, tolerance, water=True)
    exact = homogenizer(0.0)
    rng = np.random.default_rng(8)
    Fg, n = random_growth(rng, 12, spread=0.3), 12
    args = (np.repeat(GEOMETRY, n, 0), rng.uniform(0.5, 5.0, n), np.full(n, 0.3), Fg)
    with caplog.at_level(logging.INFO, logger="plantgrowth"):
        found = h.homogenize(*args)
    reference = exact.homogenize(*args)
    (b, inv_M), (b_exact, inv_M_exact) = water_coefficients(found), water_coefficients(reference)
    b_factor, storage_factor = water_bounds(reference)
    b_error = np.linalg.norm(b - b_exact, axis=(1, 2)) / np.linalg.norm(b_exact, axis=(1, 2))
    storage_error = np.abs(inv_M - inv_M_exact) / inv_M_exact
    print(f"over the tolerance: b {b_error.max() / tolerance:.3f}, 1/M "
          f"{storage_error.max() / tolerance:.3f}")  # fmt: skip
    assert np.all(b_error <= b_factor * tolerance)
    assert np.all(storage_error <= storage_factor * tolerance)
    assert storage_factor.max() <= np.sqrt(2)
    checked = re.search(r"water: b by (\S+), 1/M by (\S+)$", caplog.text, re.MULTILINE)
    assert float(checked[1]) <= b_factor.max() * tolerance
    assert float(checked[2]) <= storage_factor.max() * tolerance


def rough_storage(table: tuple, U: np.ndarray) -> np.ndarray:
    """A packed cell result (pressure and strain averages) whose only non-constant part is
    dbar[v] = -(0.1 + 0.03 sin(4 U11) cos(4 U12)) I: a storage that varies by 30% over the
    stretches a quarter of a radian apart, while E_hom, K_hom, dbar[w] stay put."""
    C, K = np.diag([1.0, 1.0, 0.5]), -0.07 * np.eye(2)
    dbar_w = np.full(16, 0.01)
    dbar_v = -(0.1 + 0.03 * np.sin(4 * U[0, 0]) * np.cos(4 * U[0, 1])) * np.eye(2)
    return np.concatenate([C.ravel(), [0.1], np.zeros(4), K.ravel(), dbar_w, dbar_v.ravel()])


@pytest.mark.skip_in_parallel
def test_the_indicator_measures_dbar_v_itself(monkeypatch):
    """A scene with water refines on dbar[v] itself: with a cell map whose storage alone varies
    (:func:`rough_storage`, no cell solve), 1/M from the surrogate at 30 random stretches is
    within the tolerance of the map (dbar[v] is isotropic here, so 1/M's relative error is
    dbar[v]'s: :func:`water_bounds`' factor is 1; measured 0.29 of it, as the real cells' 0.25-0.35
    in the test above), while with an indicator without dbar[v] (the mutant) nothing is refined
    past the level-0 squares, whose bilinear interpolant is off by 4.5 tolerances (measured)."""
    monkeypatch.setattr(Homogenizer, "_solve_stretch", lambda _, table, U: rough_storage(table, U))
    tolerance = 1e-3
    s = np.random.default_rng(9).uniform(-0.3, 0.3, size=(30, 2))
    exact = np.array([rough_storage((), surrogate.stretch(x)) for x in s])[:, 34:]
    errors = {}
    for mutant in (False, True):
        h = homogenizer(tolerance)
        if mutant:
            h.surrogate.segments = tuple(g for g in h.surrogate.segments if g != slice(34, 38))
        table = h._key(GEOMETRY[0], 0.3, np.eye(2))[:5]
        values = h.surrogate.evaluate([table], np.zeros(len(s), dtype=int), s).values[:, 34:]
        inv_M, inv_M_exact = -values[:, [0, 3]].sum(1), -exact[:, [0, 3]].sum(1)
        errors[mutant] = (np.abs(inv_M - inv_M_exact) / inv_M_exact).max()
    print(f"1/M error over the tolerance: {errors[False] / tolerance:.3f}, without dbar[v] in "
          f"the indicator {errors[True] / tolerance:.1f}")  # fmt: skip
    assert errors[False] <= tolerance
    assert errors[True] > tolerance
