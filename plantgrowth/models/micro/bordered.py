"""The bordered system of the walls and the cells' turgor (docs/model.md, water fluxes), solved
by one sparse factorization:

    [ A    X ] [x]   [g]
    [ Y^T  C ] [p] = [h]

A: the walls' matrix (n_u x n_u, dolfinx's, Dirichlet rows included); X, Y: one sparse column per
cell (supported on that cell's membrane dofs); C: the cells' n x n block (the water network).
The linear step has A = K, X = Y = -B, C = -dt H (symmetric indefinite), a Newton iteration of
the finite step A = J, X = F, Y = D, C = dt H.

The n cell unknowns are owned by the last rank: the global numbering is then u's followed by
P_1 .. P_n, C is set by one rank, and p reaches the others by one broadcast of n numbers (the
factorization, MUMPS, distributes its fronts itself whatever the rows' owners).
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc
from scipy import sparse

from plantgrowth.models.linear import SolveReport, lu_solver, relative_residual


def _cell_rows(comm: MPI.Comm, n: int) -> int:
    """How many of the n cell unknowns this rank owns (all on the last rank)."""
    return n if comm.rank == comm.size - 1 else 0


def _csr_rows(A: PETSc.Mat, X: sparse.csc_matrix, Y: sparse.csc_matrix, C: np.ndarray,
              comm: MPI.Comm) -> sparse.csr_matrix:  # fmt: skip
    """This rank's rows of ``[A X; Y^T C]`` (global column indices; u's global numbers are A's,
    cell c's is ``n_u + c``): A's owned rows with X's, then on the last rank the n cell rows
    (Y's entries gathered from their owners)."""
    n_u = A.getSize()[0]
    start = A.getOwnershipRange()[0]
    indptr, indices, values = A.getValuesCSR()
    shape = (len(indptr) - 1, n_u + len(C))
    X = X.tocoo()
    top = sparse.hstack([  # A's explicit zeros kept: its pattern is the same at every step
        sparse.csr_matrix((values, indices, indptr), (shape[0], n_u)),
        sparse.csr_matrix((X.data, (X.row, X.col)), (shape[0], len(C))),
    ], format="csr")  # fmt: skip
    Y = Y.tocoo()
    gathered = comm.gather((start + Y.row, Y.col, Y.data), root=comm.size - 1)
    if _cell_rows(comm, len(C)) == 0:
        return top
    rows, cols, data = (np.concatenate(parts) for parts in zip(*gathered, strict=True))
    Cc = sparse.coo_matrix(C)
    bottom = sparse.csr_matrix(
        (np.concatenate([data, Cc.data]),
         (np.concatenate([cols, Cc.row]), np.concatenate([rows, n_u + Cc.col]))),
        (len(C), n_u + len(C)),
    )  # fmt: skip
    return sparse.vstack([top, bottom], format="csr")


class BorderedSolve:
    """One factorization of the bordered matrix per :meth:`solve`; the symbolic one is reused
    while the columns' sparsity stays the same (A's is fixed).

    Args:
        A: the walls' matrix (its values are read at each solve).
        n: the number of cells; comm: the mesh's communicator; prefix: the solver's options
            prefix.
    """

    def __init__(self, A: PETSc.Mat, n: int, comm: MPI.Comm, prefix: str) -> None:
        self.A, self.n, self.comm = A, n, comm
        self.n_owned = A.getLocalSize()[0]
        self.n_cells = _cell_rows(comm, n)
        self.M: PETSc.Mat | None = None
        self.pattern: tuple | None = None
        self.ksp: PETSc.KSP | None = None
        self.prefix = prefix

    def _assemble(self, X: sparse.csc_matrix, Y: sparse.csc_matrix, C: np.ndarray) -> None:
        """M = [A X; Y^T C] (its pattern, and so the symbolic factorization, kept while the
        pattern of every rank's rows stays the same)."""
        comm = self.comm
        rows = _csr_rows(self.A, X, Y, C, comm)
        rows.sort_indices()
        indptr = rows.indptr.astype(PETSc.IntType)
        indices = rows.indices.astype(PETSc.IntType)
        same = self.pattern is not None and all(
            np.array_equal(a, b) for a, b in zip((indptr, indices), self.pattern, strict=True)
        )
        if comm.allreduce(same, op=MPI.LAND):
            self.M.zeroEntries()
            self.M.setValuesCSR(indptr, indices, rows.data)
            self.M.assemble()
            return
        if self.M is not None:
            self.M.destroy()
            self.ksp.destroy()
        size = self.A.getSize()[0] + self.n
        local = self.n_owned + self.n_cells
        self.M = PETSc.Mat().createAIJ(
            ((local, size), (local, size)), csr=(indptr, indices, rows.data), comm=comm
        )
        self.ksp = lu_solver(self.M, comm, self.prefix)
        self.pattern = (indptr, indices)

    def solve(
        self, X: sparse.csc_matrix, Y: sparse.csc_matrix, C: np.ndarray, g: PETSc.Vec,
        h: np.ndarray, x: PETSc.Vec,
    ) -> tuple[np.ndarray, SolveReport]:  # fmt: skip
        """Solve ``[A X; Y^T C] [x; p] = [g; h]``: x into ``x`` (owned entries, no ghost
        update), p (n,) returned on every rank, with the true relative residual of the whole
        system. X, Y: this rank's owned rows of the columns; C, h: the same on every rank."""
        self._assemble(X, Y, C)
        rhs, sol = self.M.createVecRight(), self.M.createVecRight()
        rhs.array[: self.n_owned] = g.array
        rhs.array[self.n_owned :] = h[: self.n_cells]
        self.ksp.solve(rhs, sol)
        report = SolveReport(self.ksp.getConvergedReason(), relative_residual(self.M, sol, rhs))
        x.array[:] = sol.array[: self.n_owned]
        p = self.comm.bcast(sol.array[self.n_owned :].copy(), root=self.comm.size - 1)
        rhs.destroy()
        sol.destroy()
        return p, report
