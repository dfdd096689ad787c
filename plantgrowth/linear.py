"""Direct linear solves with their diagnostics (PETSc LU; MUMPS when distributed).

Every solve reports PETSc's converged reason and the *true* relative residual
``|b - A x| / |b|``, which the time loop checks against its bound.
"""

from __future__ import annotations

from dataclasses import dataclass

from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc


@dataclass(frozen=True)
class SolveReport:
    """PETSc converged reason (> 0: converged) and true relative residual."""

    reason: int
    residual: float


def lu_solver(A: PETSc.Mat, comm: MPI.Comm, prefix: str, serial: str = "mumps") -> PETSc.KSP:
    """PREONLY + LU with its own options prefix; ``serial`` is the factor package on one rank
    (PETSc's own LU is fastest for small unit cells), MUMPS on several."""
    ksp = PETSc.KSP().create(comm)
    ksp.setOptionsPrefix(prefix)
    ksp.setOperators(A)
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType("lu")
    pc.setFactorSolverType(serial if comm.size == 1 else "mumps")
    ksp.setFromOptions()
    return ksp


def relative_residual(A: PETSc.Mat, x: PETSc.Vec, b: PETSc.Vec) -> float:
    """``|b - A x| / |b|`` (``|b - A x|`` when b = 0)."""
    r = b.duplicate()
    A.mult(x, r)
    r.axpy(-1.0, b)
    scale = b.norm()
    value = r.norm() / scale if scale > 0.0 else r.norm()
    r.destroy()
    return value


def assemble_and_solve(
    A: PETSc.Mat, b: PETSc.Vec, a: fem.FormMetaClass, L: fem.FormMetaClass, bcs: list,
    ksp: PETSc.KSP, u: fem.Function,
) -> SolveReport:  # fmt: skip
    """Assemble ``a`` and ``L`` with Dirichlet conditions, factorize, solve into ``u``."""
    A.zeroEntries()
    fem.petsc.assemble_matrix(A, a, bcs=bcs)
    A.assemble()
    with b.localForm() as local:
        local.set(0.0)
    fem.petsc.assemble_vector(b, L)
    fem.petsc.apply_lifting(b, [a], bcs=[bcs])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    fem.petsc.set_bc(b, bcs)
    ksp.solve(b, u.vector)
    u.x.scatter_forward()
    return SolveReport(ksp.getConvergedReason(), relative_residual(A, u.vector, b))
