"""The integrals every unit-cell problem is a weighted sum of (docs/model.md section 3).

With Fg constant over the cell, the bilinear form of [UC_weak]/[UCw_weak] is a weighted sum of
the products ``int d_q phi d_p z`` and its right-hand sides and averages are weighted sums of the
moments ``int d_c phi_j`` (the weights: :mod:`plantgrowth.unitcell.solver`); a
:class:`GradientBasis` assembles them once per geometry, per wall part.
"""

from __future__ import annotations

import itertools

import dolfinx_mpc
import numpy as np
import ufl
from dolfinx import fem
from petsc4py import PETSc

from plantgrowth.forms import cell_problems


def _csr_pointer(rows: np.ndarray, n: int) -> np.ndarray:
    """Row pointer of a CSR matrix on n rows whose entries have these row indices."""
    return np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=n))]).astype(PETSc.IntType)


def _selector(p: int) -> np.ndarray:
    """``e_i (x) e_a`` for the flat gradient index p = 2 i + a."""
    return np.eye(4)[p].reshape(2, 2)


class GradientBasis:
    """The integrals every cell problem is a weighted sum of, assembled once per geometry.

    One set per wall part (the whole walls, or the three segment families of fibred walls, whose
    tensors differ): ``products[f]``: for p <= q the MPC-reduced ``B_pq + B_qp``,
    ``B_pq = int d_q phi d_p z``, zero on Dirichlet and slave rows (dolfinx_mpc with diagval 0);
    ``diagonal``: dolfinx_mpc's unit diagonal on those rows, added once. ``reduced[f]``/``full[f]``:
    (owned dofs, 4) moments ``int d_c phi_j``, MPC-reduced with the Dirichlet rows zeroed
    (right-hand sides) and unconstrained (the averages).

    Matrices are stored as ``M[order][:, order]``, all with one pattern, so that a weighted sum
    is a sum of value arrays (AXPY). On one rank ``order`` is PETSc's nested dissection of the
    2x2 node blocks and the storage symmetric (SBAIJ, upper triangle, dolfinx_mpc assembles
    into it through a permuted local-to-global map): Cholesky in that order has the fill of
    nested-dissection LU and took 1.5 ms of CPU against 3.4 ms (BAIJ LU) and 4.2 ms (AIJ LU,
    before) at resolution 2 (loaded machine). On several ranks ``order`` is the identity and
    the storage dolfinx_mpc's AIJ, for MUMPS' LU (PETSc 3.18's MPISBAIJ AXPY with the same
    pattern adds wrongly).

    Args:
        V: the displacement space.
        mpc: the finalized periodic constraint.
        bcs: the Dirichlet conditions (their rows and columns are zero in every product).
        dxs: the measures of the wall parts.
    """

    PAIRS = tuple(itertools.combinations_with_replacement(range(4), 2))

    def __init__(
        self,
        V: fem.FunctionSpace,
        mpc: dolfinx_mpc.MultiPointConstraint,
        bcs: list,
        dxs: list[ufl.Measure],
    ) -> None:
        mesh = V.mesh
        self.comm = mesh.comm
        P = fem.Constant(mesh, np.zeros((2, 2), dtype=PETSc.ScalarType))
        Q = fem.Constant(mesh, np.zeros((2, 2), dtype=PETSc.ScalarType))
        z, phi = ufl.TrialFunction(V), ufl.TestFunction(V)
        forms = [cell_problems.gradient_product_form(z, phi, P, Q, dx) for dx in dxs]
        products = [fem.form(form) for form in forms]
        walls = products[0] if len(forms) == 1 else fem.form(sum(forms[1:], forms[0]))
        # zero selectors: only the diagonal that dolfinx_mpc puts on Dirichlet and slave rows
        # (diagval); in dolfinx_mpc's own AIJ matrix over all the walls, whose pattern all
        # others share
        dof_matrix = dolfinx_mpc.assemble_matrix(walls, mpc, bcs=bcs, diagval=1.0)
        self.order = np.arange(dof_matrix.getLocalSize()[0], dtype=PETSc.IntType)
        if self.comm.size == 1:
            self._ordered_pattern(dof_matrix)
            self.diagonal = self._new_matrix(dof_matrix)
            dolfinx_mpc.assemble_matrix(walls, mpc, bcs=bcs, diagval=1.0, A=self.diagonal)
            dof_matrix.destroy()
        else:
            self.diagonal = dof_matrix
        self.products = []
        for product in products:
            part = []
            for p, q in self.PAIRS:
                P.value[:], Q.value[:] = _selector(p), _selector(q)
                B = self._new_matrix(self.diagonal)
                dolfinx_mpc.assemble_matrix(product, mpc, bcs=bcs, diagval=0.0, A=B)
                part.append(B)
            self.products.append(part)
        moments = [self._moments(V, mpc, bcs, Q, dx) for dx in dxs]
        self.reduced = np.stack([r for r, _ in moments])
        self.full = np.stack([f for _, f in moments])

    def _moments(
        self, V: fem.FunctionSpace, mpc, bcs: list, Q: fem.Constant, dx: ufl.Measure
    ) -> tuple[np.ndarray, np.ndarray]:
        """(owned dofs, 4) moments ``int d_c phi_j`` over ``dx``: reduced and full."""
        moment = fem.form(cell_problems.gradient_moment_form(ufl.TestFunction(V), Q, dx))
        reduced, full = [], []
        for q in range(4):
            Q.value[:] = _selector(q)
            b = dolfinx_mpc.assemble_vector(moment, mpc)
            b.ghostUpdate(addv=PETSc.InsertMode.ADD_VALUES, mode=PETSc.ScatterMode.REVERSE)
            fem.petsc.set_bc(b, bcs)
            f = fem.petsc.assemble_vector(moment)
            f.ghostUpdate(addv=PETSc.InsertMode.ADD_VALUES, mode=PETSc.ScatterMode.REVERSE)
            reduced.append(b.array[self.order])
            full.append(f.array.copy())
            b.destroy()
            f.destroy()
        return np.stack(reduced, axis=1), np.stack(full, axis=1)

    def _ordered_pattern(self, dof_matrix: PETSc.Mat) -> None:
        """Nested-dissection order of the node blocks and the upper block pattern in it."""
        I, J, _ = dof_matrix.getValuesCSR()
        rows = np.repeat(np.arange(len(I) - 1), np.diff(I))
        corner = (rows % 2 == 0) & (J % 2 == 0)  # one entry per 2x2 node block
        n_nodes = (len(I) - 1) // 2
        rows, cols = rows[corner] // 2, J[corner] // 2
        csr = (_csr_pointer(rows, n_nodes), cols.astype(PETSc.IntType))
        graph = PETSc.Mat().createAIJ((n_nodes, n_nodes), csr=csr, comm=self.comm)
        nodes = graph.getOrdering("nd")[0].getIndices()
        graph.destroy()
        self.order = (2 * nodes[:, None] + np.arange(2)).ravel().astype(PETSc.IntType)
        position = np.argsort(nodes)  # node -> its place in the order
        rows, cols = position[rows], position[cols]
        upper = cols >= rows
        rows, cols = rows[upper], cols[upper]
        by_row = np.lexsort((cols, rows))
        self._pattern = (_csr_pointer(rows, n_nodes), cols[by_row].astype(PETSc.IntType))
        self._lgmap = PETSc.LGMap().create(position.astype(PETSc.IntType), bsize=2, comm=self.comm)

    def _new_matrix(self, template: PETSc.Mat) -> PETSc.Mat:
        """An empty stored matrix that dolfinx_mpc assembles into (in dof numbering)."""
        if self.comm.size > 1:
            return template.duplicate()
        n = len(self.order)
        M = PETSc.Mat().createSBAIJ((n, n), 2, csr=self._pattern, comm=self.comm)
        M.setLGMap(self._lgmap, self._lgmap)
        M.setOption(PETSc.Mat.Option.IGNORE_LOWER_TRIANGULAR, True)  # symmetric: K^T A K
        return M

    def matrix(self, S: list[np.ndarray], A: PETSc.Mat) -> None:
        """``A = sum_f sum_pq S_f[q, p] B^f_qp + diagonal`` (stored): the matrix of the cell
        problems, ``S[f]`` the weights of wall part f."""
        same = PETSc.Mat.Structure.SAME_NONZERO_PATTERN
        self.diagonal.copy(A, same)
        for S_f, products in zip(S, self.products, strict=True):
            for (p, q), B in zip(self.PAIRS, products, strict=True):
                A.axpy(S_f[p, q] if p != q else 0.5 * S_f[p, p], B, same)

    def factorization(self, A: PETSc.Mat, prefix: str) -> PETSc.KSP:
        """PREONLY KSP that factorizes the stored A: Cholesky in the stored (nested-dissection)
        order on one rank, MUMPS' LU on several. Its symbolic factorization is reused while
        only the values of A change."""
        ksp = PETSc.KSP().create(self.comm)
        ksp.setOptionsPrefix(prefix)
        ksp.setOperators(A)
        ksp.setType("preonly")
        pc = ksp.getPC()
        if self.comm.size == 1:
            pc.setType("cholesky")
            pc.setFactorSolverType("petsc")
            pc.setFactorOrdering("natural")  # the storage is in nested-dissection order
        else:
            pc.setType("lu")
            pc.setFactorSolverType("mumps")
        ksp.setFromOptions()
        return ksp

    def in_dof_order(self, A: PETSc.Mat) -> PETSc.Mat:
        """A stored matrix as an AIJ matrix in dof order (a new matrix), i.e. as dolfinx_mpc
        assembles it."""
        if self.comm.size > 1:
            return A.copy()
        aij = A.convert("aij", PETSc.Mat())
        inverse = PETSc.IS().createGeneral(
            np.argsort(self.order).astype(PETSc.IntType), comm=self.comm
        )
        out = aij.permute(inverse, inverse)
        aij.destroy()
        inverse.destroy()
        return out
