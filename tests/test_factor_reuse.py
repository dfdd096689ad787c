"""The macro LU factors kept across steps (plantgrowth/models/factor_reuse.py): refinement with
them reaches a fresh solve's residual, a matrix that moved too far is factorized again, and a
resumed run factorizes the straight run's matrix and repeats it exactly."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from dolfinx import fem, mesh
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.cli import main
from plantgrowth.models.factor_reuse import REFINE_RTOL, FactorReuse
from plantgrowth.models.linear import lu_solver, relative_residual
from plantgrowth.runner.output import StateFile


def laplacian(scale: np.ndarray, n: int = 40) -> PETSc.Mat:
    """A tridiagonal SPD matrix of this rank's rows (diagonal 2 scale_i + 1e-3, -1 off it)."""
    A = PETSc.Mat().createAIJ([(None, n), (None, n)], nnz=(3, 2), comm=MPI.COMM_WORLD)
    start, end = A.getOwnershipRange()
    for i in range(start, end):
        A.setValue(i, i, 2.0 * scale[i] + 1e-3)
        for j in (i - 1, i + 1):
            if 0 <= j < A.getSize()[0]:
                A.setValue(i, j, -1.0)
    A.assemble()
    return A


def refill(A: PETSc.Mat, scale: np.ndarray) -> None:
    """A's values in place (as a step's re-assembly: same pattern)."""
    fresh = laplacian(scale, A.getSize()[0])
    A.zeroEntries()
    A.axpy(1.0, fresh, PETSc.Mat.Structure.SAME_NONZERO_PATTERN)
    fresh.destroy()


def kept_factors(A: PETSc.Mat, prefix: str) -> tuple[FactorReuse, PETSc.Vec, PETSc.Vec]:
    """A FactorReuse over A's LU solver (one placeholder coefficient), b = 1 and x."""
    ksp = lu_solver(A, MPI.COMM_WORLD, prefix, serial="petsc")
    coefficient = fem.Function(
        fem.FunctionSpace(mesh.create_unit_interval(MPI.COMM_WORLD, 2), ("DG", 0))
    )
    b, x = A.createVecLeft(), A.createVecRight()
    b.set(1.0)
    return FactorReuse(ksp, (coefficient,)), b, x


def test_kept_factors_refine_to_a_fresh_solve_and_refactor_when_the_matrix_moved():
    """Serial: under mpirun every solve factorizes (FactorReuse.solve; the next test)."""
    n = 40
    scale = np.ones(n)
    A = laplacian(scale, n)
    factors, b, x = kept_factors(A, "test_factor_reuse_")
    factors.solve(A, b, x)
    assert factors.factorizations == 1 and factors.floor < 1e-13
    # a change of 1e-6: the kept factors contract the error by about 1e-6 a correction
    refill(A, scale * (1.0 + 1e-6 * np.linspace(0.0, 1.0, n)))
    factors.solve(A, b, x)
    assert factors.factorizations == 1
    assert relative_residual(A, x, b) <= REFINE_RTOL * factors.floor
    # a change by half: refinement contracts too little; A is factorized, x is A's solution
    refill(A, scale * (1.0 + 0.5 * np.linspace(0.0, 1.0, n)))
    factors.solve(A, b, x)
    assert factors.factorizations == 2
    assert relative_residual(A, x, b) < 1e-13  # a fresh LU solve's round-off (~1e-16 here)


SCENE = """\
[tissue]
h = 0.5
H = 2.0
[material]
E = {from = 0.5, to = 2.0}
[growth]
law = "stress"
[time]
t_max = 6
dt = 1
[accuracy]
cell_resolution = 1
"""


def summary(outdir):
    with open(outdir / "summary.csv", newline="") as f:
        return [
            {k: v for k, v in row.items() if not k.startswith("seconds") and k != "n_cell_solves"}
            for row in csv.DictReader(f)
        ]


def test_a_resumed_run_factorizes_the_straight_runs_matrix_and_repeats_it(tmp_path):
    """The state of steps 5 and 6 holds the coefficients of one earlier step's matrix (the kept
    factors'); resumed after step 5 (step 6's file and row removed), the run ends on exactly the
    straight run's row (the cell solves aside: the surrogate restarts empty). Without the saved
    coefficients it would factorize step 6's matrix, and its row differs in the last digits.
    Serial only: a distributed run does not repeat itself bit for bit (MUMPS), kept factors or
    not (5e-13 in u1_max); test_interruptions resumes 2-rank runs, to 1e-10."""
    scene = tmp_path / "reuse.toml"
    scene.write_text(SCENE)
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    assert main(["-q", "run", str(scene), "-o", str(whole)]) == 0
    assert main(["-q", "run", str(scene), "-o", str(cut)]) == 0
    state = StateFile(cut, MPI.COMM_SELF)
    kept = [state.read(s)["lu_Fg"] for s in (5, 6)]
    assert np.array_equal(*kept)  # the factors of an earlier step, kept
    (cut / "fields" / "step_000006.h5").unlink()
    lines = (cut / "summary.csv").read_text().splitlines(keepends=True)
    (cut / "summary.csv").write_text("".join(lines[:-1]))
    assert main(["-q", "run", str(scene), "--resume", str(cut)]) == 0
    rows, expected = summary(cut), summary(whole)
    assert len(rows) == len(expected) == 7
    assert rows[-1] == expected[-1]  # as written: every digit


@pytest.mark.mpi
@pytest.mark.skipif(MPI.COMM_WORLD.size == 1, reason="the distributed LU only")
def test_under_mpirun_every_solve_factorizes():
    """Two 2-rank runs' LU round-off differs (their floors by about 1 %), so kept factors would
    make them refactorize at different steps: under mpirun each solve factorizes afresh."""
    n = 40
    A = laplacian(np.ones(n), n)
    factors, b, x = kept_factors(A, "test_factor_reuse_mpi_")
    factors.solve(A, b, x)
    factors.solve(A, b, x)  # the same matrix: kept factors would serve it serially
    assert factors.factorizations == 2
