"""Linear solves with their diagnostics: direct (PETSc LU; MUMPS when distributed) or
conjugate gradients with smoothed-aggregation multigrid (GAMG) for large elasticity systems.

Every solve reports PETSc's converged reason, the iterations and the *true* relative residual
``|b - A x| / |b|``, which the time loop checks against its bound.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from dolfinx import fem, la
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.models.diagnostics import RESIDUAL_BOUND


@dataclass(frozen=True)
class SolveReport:
    """PETSc converged reason (> 0: converged), true relative residual, Krylov iterations (0
    for a direct solve), the largest true relative residual the solve may leave."""

    reason: int
    residual: float
    iterations: int = 0
    bound: float = RESIDUAL_BOUND


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


def rigid_body_modes(A: PETSc.Mat, V: fem.FunctionSpace) -> PETSc.NullSpace:
    """The near-nullspace of 2D elasticity (matrix ``A`` on a blocked vector space ``V``): the
    two translations and the in-plane rotation, orthonormalized (dolfinx v0.5.2's elasticity
    demo, in 2D)."""
    owned = V.dofmap.index_map.size_local
    x = V.tabulate_dof_coordinates()[:owned]  # one row per owned node
    modes = [A.createVecRight() for _ in range(3)]
    for k, mode in enumerate(modes):
        values = mode.array.reshape(-1, V.dofmap.index_map_bs)
        values[:] = 0.0
        if k < 2:
            values[:, k] = 1.0
        else:
            values[:, 0], values[:, 1] = -x[:, 1], x[:, 0]
    la.orthonormalize(modes)
    return PETSc.NullSpace().create(vectors=modes)


GAMG_OPTIONS = {
    "pc_gamg_reuse_interpolation": True,
    "mg_levels_ksp_type": "chebyshev",  # the smoother of dolfinx's elasticity demo
    "mg_levels_pc_type": "jacobi",
}
"""PETSc options of :func:`gamg_solver` (under its prefix)."""
SPD_OPTIONS = {"mg_levels_esteig_ksp_type": "cg"}  # the smoothed operator is SPD
"""Added for a symmetric positive definite matrix (CG); GMRES keeps PETSc's GMRES estimate."""


def _krylov(
    A: PETSc.Mat, comm: MPI.Comm, prefix: str, rtol: float, max_it: int, spd: bool, warm: bool
) -> PETSc.KSP:
    """CG (``spd``) or right-preconditioned GMRES on ``A``, tested on the unpreconditioned
    residual relative to ``|b|``; ``warm``: from the vector it is given."""
    ksp = PETSc.KSP().create(comm)
    ksp.setOptionsPrefix(prefix)
    ksp.setOperators(A)
    if spd:
        ksp.setType("cg")
    else:
        # PETSc's restart 30: 90-111 iterations a solve on gradient_E_strain with finite
        # kinematics, against 88-100 with restart 100 at 3.3x the memory. Right
        # preconditioning: GMRES then minimizes the unpreconditioned residual it is tested on.
        ksp.setType("gmres")
        ksp.setPCSide(PETSc.PC.Side.RIGHT)
    ksp.setNormType(PETSc.KSP.NormType.UNPRECONDITIONED)
    ksp.setTolerances(rtol=rtol, atol=0.0, max_it=max_it)
    ksp.setInitialGuessNonzero(warm)
    return ksp


def _set_options(ksp: PETSc.KSP, prefix: str, options: dict) -> None:
    petsc_options = PETSc.Options()
    for key, value in options.items():
        petsc_options[prefix + key] = value
    ksp.setFromOptions()


def gamg_solver(
    A: PETSc.Mat, V: fem.FunctionSpace, prefix: str, rtol: float, max_it: int = 500,
    spd: bool = True, warm: bool = False, options: dict | None = None,
) -> PETSc.KSP:  # fmt: skip
    """A Krylov solver preconditioned by GAMG with the rigid-body near-nullspace, for an
    elasticity matrix ``A`` on ``V``, with its own options prefix: CG for a symmetric positive
    definite ``A`` (``spd``, linear elasticity), else right-preconditioned GMRES (a finite-
    kinematics Jacobian: follower loads make it non-symmetric, compression indefinite).

    The residual test is on the unpreconditioned residual relative to ``|b|``, i.e. on the
    quantity the true-residual check measures; ``warm``: the solve starts from the vector it is
    given (the previous solution), and PETSc's default test still scales by ``|b|``, not by the
    initial residual (KSPConvergedDefaultSetUIRNorm is not set). The multigrid hierarchy's
    interpolation is built at the first solve and reused when ``A`` is re-assembled with the
    same pattern (only the Galerkin coarse operators and smoothers are recomputed).
    ``options``: PETSc options added to (or replacing) GAMG_OPTIONS and SPD_OPTIONS.
    """
    A.setNearNullSpace(rigid_body_modes(A, V))
    ksp = _krylov(A, V.mesh.comm, prefix, rtol, max_it, spd, warm)
    ksp.getPC().setType("gamg")
    _set_options(ksp, prefix, GAMG_OPTIONS | (SPD_OPTIONS if spd else {}) | (options or {}))
    return ksp


BOOMERAMG_OPTIONS = {"pc_hypre_type": "boomeramg"}
"""hypre BoomerAMG with PETSc's defaults (Falgout coarsening, strength threshold 0.25, one
symmetric-SOR/Jacobi sweep down and up): the fastest of the settings measured on the organ
scene's system (docs/large_tissues.md, "Macro solve sized by accuracy")."""


def boomeramg_cg_solver(
    A: PETSc.Mat, comm: MPI.Comm, prefix: str, rtol: float, max_it: int, warm: bool,
    spare: int = 0,
) -> PETSc.KSP:  # fmt: skip
    """CG preconditioned by hypre BoomerAMG (:data:`BOOMERAMG_OPTIONS`) for a symmetric
    positive definite ``A``, tested as :func:`gamg_solver`'s, or with ``spare`` > 0 by
    :class:`SpareAccuracy`; the hierarchy is rebuilt at a solve unless the preconditioner is
    marked for reuse (``PCSetReusePreconditioner``)."""
    ksp = _krylov(A, comm, prefix, rtol, max_it, spd=True, warm=warm)
    ksp.getPC().setType("hypre")
    _set_options(ksp, prefix, BOOMERAMG_OPTIONS)
    if spare:
        ksp.setConvergenceTest(SpareAccuracy(spare))
    return ksp


SPARE_FACTOR = 4.0
"""How much tighter than its tolerance :class:`SpareAccuracy` takes CG while it has iterations
to spare: a factor 4 is about 2 iterations (CG from the projected guess gains about a decade in 3
on the organ scene). On the organ scene with 6 to spare (2 ranks, 60 steps) it kept every step
from 16 on at 6 iterations or fewer, 306 in all against 280, and its 1- and 2-rank summaries
within 5.8e-7 (elastic_strain_max) against 1.8e-6 (benchmarks/results/organ_60_stop50b.json,
docs/large_tissues.md)."""


class SpareAccuracy:
    """A CG stopping test that spends spare iterations on accuracy: while a solve has taken
    fewer than ``spare`` iterations it stops at ``|r| <= rtol / SPARE_FACTOR |b|``, from then
    on at ``|r| <= rtol |b|`` (the KSP's rtol and iteration limit; r the residual its norm type
    gives, the true one here). So a solve is never less accurate than ``rtol`` asks, and takes
    no more iterations than the plain test unless it could stop before ``spare``: CG's iterates
    do not depend on the test. Diverged on a NaN or infinite residual, at the KSP's iteration
    limit, or beyond its dtol times the first residual."""

    def __init__(self, spare: int) -> None:
        self.spare = spare
        self._scale = self._first = 0.0

    def __call__(self, ksp: PETSc.KSP, its: int, rnorm: float) -> int:
        reason = PETSc.KSP.ConvergedReason
        rtol, _, dtol, max_it = ksp.getTolerances()
        if its == 0:
            self._scale, self._first = ksp.getRhs().norm(), rnorm
        if not np.isfinite(rnorm):
            return reason.DIVERGED_NANORINF
        goal = rtol / SPARE_FACTOR if its < self.spare else rtol
        if rnorm <= goal * self._scale:
            return reason.CONVERGED_RTOL
        if its >= max_it:
            return reason.DIVERGED_ITS
        if rnorm > dtol * self._first:
            return reason.DIVERGED_DTOL
        return reason.ITERATING


SADDLE_POINT_OPTIONS = {
    "pc_fieldsplit_type": "schur",
    "pc_fieldsplit_schur_fact_type": "diag",
    "fieldsplit_u_ksp_type": "preonly",
    "fieldsplit_u_pc_type": "lu",
    "fieldsplit_u_pc_factor_mat_solver_type": "mumps",
    "fieldsplit_p_ksp_type": "preonly",
    "fieldsplit_p_pc_type": "hypre",
    "fieldsplit_p_pc_hypre_type": "boomeramg",
}
"""PETSc options of :func:`saddle_point_solver` (under its prefix)."""


def saddle_point_solver(
    A: PETSc.Mat, fields: tuple[PETSc.IS, PETSc.IS], schur: PETSc.Mat, comm: MPI.Comm,
    prefix: str, rtol: float, max_it: int,
) -> PETSc.KSP:  # fmt: skip
    """MINRES for a symmetric saddle point ``[K  -B; -B^T  -C]`` (K and C positive definite;
    ``fields``: the index sets of u and P), preconditioned by the block diagonal
    ``diag(LU(K), AMG(schur))``: PETSc's Schur field split with the diagonal factorization,
    which negates the Schur block so that the preconditioner is positive definite; ``schur``
    approximates the Schur complement ``-(C + B^T K^-1 B)`` (the caller assembles it before each
    solve). K is factorized (MUMPS): one BoomerAMG cycle on the homogenized honeycomb's K
    (nearly incompressible) took MINRES from 18 to 189 iterations on the apex scene (1,728
    dofs), over 1,600 at 25,620 (docs/large_tissues.md, "Water fluxes"). MINRES tests the
    preconditioned residual: callers check the true one."""
    ksp = PETSc.KSP().create(comm)
    ksp.setOptionsPrefix(prefix)
    ksp.setOperators(A)
    ksp.setType("minres")
    ksp.setTolerances(rtol=rtol, atol=0.0, max_it=max_it)
    pc = ksp.getPC()
    pc.setType("fieldsplit")
    pc.setFieldSplitIS(("u", fields[0]), ("p", fields[1]))
    _set_options(ksp, prefix, SADDLE_POINT_OPTIONS)
    pc.setFieldSplitSchurPreType(PETSc.PC.SchurPreType.USER, schur)
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


def assemble_matrix(A: PETSc.Mat, a: fem.FormMetaClass, bcs: list) -> PETSc.Mat:
    """Assemble ``a`` into A with Dirichlet conditions (their rows and columns zero, 1 on the
    diagonal); returns A."""
    A.zeroEntries()
    fem.petsc.assemble_matrix(A, a, bcs=bcs)
    A.assemble()
    return A


def assemble_system(
    A: PETSc.Mat, b: PETSc.Vec, a: fem.FormMetaClass, L: fem.FormMetaClass, bcs: list
) -> None:
    """Assemble ``a`` into A and ``L`` into b with homogeneous Dirichlet conditions (b's owned
    entries summed over the ranks, zero on the conditions' dofs; ghosts not updated). Every
    condition of the models holds u = 0, whose lifting ``b -= A u_D`` subtracts zero: it is
    not assembled (on the 1e5-dof tissue it took 6 ms of a step's 40 ms of assembly, one
    rank); a nonzero condition is refused."""
    if any(np.any(bc.value.value != 0.0) for bc in bcs):
        raise ValueError("assemble_system takes homogeneous Dirichlet conditions (u = 0) only")
    assemble_matrix(A, a, bcs)
    with b.localForm() as local:
        local.set(0.0)
    fem.petsc.assemble_vector(b, L)
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    fem.petsc.set_bc(b, bcs)


def assemble_and_solve(
    A: PETSc.Mat, b: PETSc.Vec, a: fem.FormMetaClass, L: fem.FormMetaClass, bcs: list,
    ksp: PETSc.KSP, u: fem.Function, bound: float = RESIDUAL_BOUND,
    guess: Callable[[PETSc.Mat, PETSc.Vec, PETSc.Vec], None] | None = None,
    solve: Callable[[PETSc.Mat, PETSc.Vec, PETSc.Vec], object] | None = None,
) -> SolveReport:  # fmt: skip
    """Assemble ``a`` and ``L`` with Dirichlet conditions, solve into ``u`` with ``ksp`` (from
    ``u`` if its initial guess is nonzero, after ``guess(A, b, u.vector)`` has set it), or with
    ``solve(A, b, u.vector)`` if given (:class:`~plantgrowth.models.factor_reuse.FactorReuse`);
    ``bound``: the report's residual bound."""
    assemble_system(A, b, a, L, bcs)
    if guess is not None:
        guess(A, b, u.vector)
    if solve is None:
        ksp.solve(b, u.vector)
    else:
        solve(A, b, u.vector)
    u.x.scatter_forward()
    residual = relative_residual(A, u.vector, b)
    iterations = 0 if ksp.getType() == "preonly" else ksp.getIterationNumber()
    return SolveReport(ksp.getConvergedReason(), residual, iterations, bound)
