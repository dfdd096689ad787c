"""The initial guess from earlier solutions (plantgrowth/models/solution_history.py).

A symmetric positive definite tridiagonal matrix (a 1D Laplacian plus a diagonal that varies
along the vector), distributed over the ranks by PETSc, and solutions made from smooth vectors,
so every test runs alike in serial and under ``mpirun -n 2``. Tolerances: the guess is a
projection computed in double precision from vectors of norm ~1 on a matrix of condition number
~1e3, so it is exact to ~1e-13 where exact; 1e-10 leaves room for the Gram-Schmidt passes.
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.models.solution_history import SolutionHistory

pytestmark = pytest.mark.mpi  # scripts/README.md, "Tests": every test also runs on 2 ranks

N = 400
EXACT = 1e-10


def matrix(shift: float = 0.0) -> PETSc.Mat:
    """``tridiag(-1, 2 + d_i, -1)`` with ``d_i = 0.01 (1 + shift + i / N)``."""
    A = PETSc.Mat().createAIJ([N, N], nnz=3, comm=MPI.COMM_WORLD)
    start, end = A.getOwnershipRange()
    for i in range(start, end):
        A.setValue(i, i, 2.0 + 0.01 * (1.0 + shift + i / N))
        if i > 0:
            A.setValue(i, i - 1, -1.0)
        if i < N - 1:
            A.setValue(i, i + 1, -1.0)
    A.assemble()
    return A


def vector(A: PETSc.Mat, f) -> PETSc.Vec:
    """The vector of ``f(x)`` at ``x = i / N`` (this rank's rows)."""
    v = A.createVecRight()
    start, end = v.getOwnershipRange()
    v.array[:] = f(np.arange(start, end) / N)
    return v


def energy_error(A: PETSc.Mat, x: PETSc.Vec, exact: PETSc.Vec) -> float:
    e = x.copy()
    e.axpy(-1.0, exact)
    Ae = A.createVecLeft()
    A.mult(e, Ae)
    return e.dot(Ae) ** 0.5


def rhs(A: PETSc.Mat, x: PETSc.Vec) -> PETSc.Vec:
    b = A.createVecLeft()
    A.mult(x, b)
    return b


def test_nothing_stored_leaves_the_guess_alone():
    A = matrix()
    x = vector(A, np.sin)
    SolutionHistory(3).guess(A, rhs(A, x), x)
    assert np.array_equal(x.array, np.sin(np.arange(*x.getOwnershipRange()) / N))


def test_a_solution_in_the_span_is_found_exactly():
    """The next solution a combination of the stored ones (a quantity moving along a parabola
    in time): the guess is it, to round-off, whatever the new matrix."""
    A = matrix(shift=0.5)
    history = SolutionHistory(3)
    shapes = [lambda x: np.sin(3 * x), lambda x: x * (1 - x), lambda x: np.cos(x)]
    for shape in shapes:
        history.record(vector(A, shape))
    exact = vector(A, lambda x: 2 * np.sin(3 * x) - 0.5 * x * (1 - x) + 0.1 * np.cos(x))
    guess = A.createVecRight()
    history.guess(A, rhs(A, exact), guess)
    assert energy_error(A, guess, exact) <= EXACT * energy_error(A, 0 * guess, exact)


def test_the_guess_is_never_worse_than_the_last_solution():
    """A slowly drifting sequence (what growth does to u): the projection's energy error is at
    most that of the previous solution (which is in the span), and for a smooth drift several
    orders below it."""
    history = SolutionHistory(5)
    for step in range(8):
        t = 0.1 * step
        A = matrix(shift=t)
        exact = vector(A, lambda x, t=t: np.sin(3 * x + t) * (1 + t * x))
        guess = A.createVecRight()
        history.guess(A, rhs(A, exact), guess)
        if history.solutions:
            last = energy_error(A, history.solutions[-1], exact)
            assert energy_error(A, guess, exact) <= last * (1 + EXACT)
            if len(history.solutions) == 5:
                assert energy_error(A, guess, exact) <= 1e-3 * last
        history.record(exact)


def test_a_repeated_solution_is_dropped_and_the_size_is_kept():
    """A stored solution in the span of the newer ones adds nothing (DROP): the basis is the
    independent ones; beyond ``size`` the oldest are forgotten."""
    A = matrix()
    history = SolutionHistory(3)
    x = vector(A, np.sin)
    for _ in range(4):
        history.record(x)
    assert len(history.solutions) == 3
    assert len(history._a_orthonormal(A)) == 1
    exact = vector(A, lambda s: 3.0 * np.sin(s))
    guess = A.createVecRight()
    history.guess(A, rhs(A, exact), guess)
    assert energy_error(A, guess, exact) <= EXACT * energy_error(A, 0 * guess, exact)
    history.clear()
    assert history.solutions == []
