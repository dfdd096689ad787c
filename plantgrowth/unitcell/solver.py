"""Solver for the growth-weighted unit-cell problems (docs/model.md section 3, paper Algorithm 3).

One :class:`CellSolver` owns a periodic unit-cell mesh, its constraints and the basis integrals
of :class:`GradientBasis`. ``solve(Fg, E, nu)`` builds the shared bilinear form from them,
factorizes it once and solves the four right-hand sides ([UC_weak] for b_11, b_22, b_12 and
[UCw_weak]); calls with new Fg, E, nu reuse mesh, constraints and basis.

Why a basis: Fg is constant over the cell. With ``G = Fg^{-1}``, ``Jg = det Fg``, C the wall
tensor as a 4x4 matrix and the row-major flattening p = (i, a) of ``grad(z)[i, a] = d_a z_i``,
``vec(grad(z) G) = L vec(grad(z))`` with ``L = I (x) G^T``, and
    a(z, phi)         = int Jg C[grad(z) G] : grad(phi) G = sum_pq S_qp int d_q phi d_p z,
                        S = Jg L^T C L                      (ten symmetrized products),
    -int Jg X : grad(phi) G = -Jg sum_q (L^T vec X)_q r_q   (X = C[b_ij] or I),
    int grad(z) G     = L (r_p . z)_p                       (z back-substituted),
with the moments ``r_q = int grad(phi)_q``. A solve is then a weighted sum of same-pattern
matrices, one factorization, four solves and dot products. The forms of ``forms.cell_problems``
that state [UC_weak], [UCw_weak] and the averages as docs/model.md section 3 writes them are the
reference the tests compare with.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass

import dolfinx_mpc
import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.base.errors import check_growth_tensor, check_wall_material
from plantgrowth.base.tensors import (
    VOIGT_NAMES,
    VOIGT_PAIRS,
    isotropic_tensor,
    orthotropic_moduli,
    unit_strain,
)
from plantgrowth.forms import cell_problems
from plantgrowth.forms.elasticity import wall_bilinear_form
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.meshes.unit_cell import CELL_TAGS, FACET_TAGS, build_unit_cell_mesh, mesh_size
from plantgrowth.unitcell.periodic import periodic_constraint

DEFAULT_RESOLUTION = 3
"""Elements across a wall (P2): about 0.3% error on moduli for the reference cell."""
STRAIN_PROBLEMS = ((0, 0), (1, 1), (0, 1))
"""(i, j) of the unit strains b_ij of the three problems [UC_weak], solved in this order."""


@dataclass(frozen=True)
class CellResult:
    """Homogenized quantities of one cell problem (paper [maacro_E], [maacro_K], [P2]).

    Attributes:
        E_hom: (2, 2, 2, 2) effective elasticity tensor.
        K_hom: (2, 2) effective pressure tensor (None if not computed).
        dbar_w: (2, 2, 2, 2) ``dbar[w^ij]_kl`` (i, j symmetric; None if not computed).
        dbar_v: (2, 2) ``dbar[v]`` (None if not computed).
        phi_w: wall fraction |Y_w| / |Y|.
        P2_matrix: (2, 2) M with ``P2vec = M grad(P1)``, or None for a non-hexagonal domain.
        ndofs: global number of unconstrained displacement dofs.
        seconds: wall time of the solve (assembly, factorization, four solves, averages).
    """

    E_hom: np.ndarray
    K_hom: np.ndarray | None
    dbar_w: np.ndarray | None
    dbar_v: np.ndarray | None
    phi_w: float
    P2_matrix: np.ndarray | None
    ndofs: int
    seconds: float

    @property
    def E_voigt(self) -> np.ndarray:
        """The six components {E1111, E2222, E1122, E1212, E1112, E2212}."""
        return np.array([self.E_hom[i, j, k, l] for (i, j), (k, l) in VOIGT_PAIRS])

    def P2vec(self, grad_P1: np.ndarray) -> np.ndarray:
        """``P2vec = (1/|Y|) int_Gamma P2 N`` for ``P2 = -grad(P1) . y`` ([P2], docs/model.md
        section 6)."""
        if self.P2_matrix is None:
            raise ValueError("P2vec is defined on the hexagonal cell only")
        return self.P2_matrix @ np.asarray(grad_P1, dtype=float)

    def summary(self) -> dict:
        """Flat dictionary of the CLI's JSON keys."""
        E = self.E_voigt
        out = dict(zip(VOIGT_NAMES, E.tolist(), strict=True))
        out.update(K11=self.K_hom[0, 0], K22=self.K_hom[1, 1], K12=self.K_hom[0, 1])
        out.update(orthotropic_moduli(E))
        out.update(phi_w=self.phi_w, ndofs=self.ndofs, seconds=self.seconds)
        return {k: (float(v) if k != "ndofs" else int(v)) for k, v in out.items()}


def growth_map(Fg: np.ndarray) -> np.ndarray:
    """(4, 4) matrix L with ``vec(X Fg^{-1}) = L vec(X)`` for the row-major ``vec`` of 2x2 X."""
    return np.kron(np.eye(2), np.linalg.inv(Fg).T)


def stiffness_weights(Fg: np.ndarray, E: float, nu: float) -> np.ndarray:
    """(4, 4) symmetric S with ``a(z, phi) = sum_pq S[q, p] int d_q phi d_p z`` ([UC_weak]).

    ``S = Jg L^T C L``: C is the plane-stress wall tensor, p = (i, a) stands for ``d_a z_i``.
    """
    L = growth_map(Fg)
    return np.linalg.det(Fg) * L.T @ isotropic_tensor(E, nu).reshape(4, 4) @ L


def _csr_pointer(rows: np.ndarray, n: int) -> np.ndarray:
    """Row pointer of a CSR matrix on n rows whose entries have these row indices."""
    return np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=n))]).astype(PETSc.IntType)


def _selector(p: int) -> np.ndarray:
    """``e_i (x) e_a`` for the flat gradient index p = 2 i + a."""
    return np.eye(4)[p].reshape(2, 2)


class GradientBasis:
    """The integrals every cell problem is a weighted sum of, assembled once per geometry.

    ``products``: for p <= q the MPC-reduced ``B_pq + B_qp``, ``B_pq = int d_q phi d_p z``, zero on
    Dirichlet and slave rows (dolfinx_mpc with diagval 0); ``diagonal``: dolfinx_mpc's unit
    diagonal on those rows, added once. ``reduced``/``full``: (owned dofs, 4) moments
    ``int d_c phi_j``, MPC-reduced with the Dirichlet rows zeroed (right-hand sides) and
    unconstrained (the averages).

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
        dx: the wall measure.
    """

    PAIRS = tuple(itertools.combinations_with_replacement(range(4), 2))

    def __init__(
        self,
        V: fem.FunctionSpace,
        mpc: dolfinx_mpc.MultiPointConstraint,
        bcs: list,
        dx: ufl.Measure,
    ) -> None:
        mesh = V.mesh
        self.comm = mesh.comm
        P = fem.Constant(mesh, np.zeros((2, 2), dtype=PETSc.ScalarType))
        Q = fem.Constant(mesh, np.zeros((2, 2), dtype=PETSc.ScalarType))
        z, phi = ufl.TrialFunction(V), ufl.TestFunction(V)
        product = fem.form(cell_problems.gradient_product_form(z, phi, P, Q, dx))
        moment = fem.form(cell_problems.gradient_moment_form(phi, Q, dx))
        # zero selectors: only the diagonal that dolfinx_mpc puts on Dirichlet and slave rows
        # (diagval); in dolfinx_mpc's own AIJ matrix, whose pattern all others share
        dof_matrix = dolfinx_mpc.assemble_matrix(product, mpc, bcs=bcs, diagval=1.0)
        self.order = np.arange(dof_matrix.getLocalSize()[0], dtype=PETSc.IntType)
        if self.comm.size == 1:
            self._ordered_pattern(dof_matrix)
            self.diagonal = self._new_matrix(dof_matrix)
            dolfinx_mpc.assemble_matrix(product, mpc, bcs=bcs, diagval=1.0, A=self.diagonal)
            dof_matrix.destroy()
        else:
            self.diagonal = dof_matrix
        self.products = []
        for p, q in self.PAIRS:
            P.value[:], Q.value[:] = _selector(p), _selector(q)
            B = self._new_matrix(self.diagonal)
            dolfinx_mpc.assemble_matrix(product, mpc, bcs=bcs, diagval=0.0, A=B)
            self.products.append(B)
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
        self.reduced = np.stack(reduced, axis=1)
        self.full = np.stack(full, axis=1)

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

    def matrix(self, S: np.ndarray, A: PETSc.Mat) -> None:
        """``A = sum_pq S[q, p] B_qp + diagonal`` (stored): the matrix of the cell problems."""
        same = PETSc.Mat.Structure.SAME_NONZERO_PATTERN
        self.diagonal.copy(A, same)
        for (p, q), B in zip(self.PAIRS, self.products, strict=True):
            A.axpy(S[p, q] if p != q else 0.5 * S[p, p], B, same)

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


class CellSolver:
    """Periodic unit-cell solver, reusable for many (Fg, E, nu) on one geometry.

    Args:
        cell: the honeycomb parameters.
        resolution: elements across the wall thickness.
        comm: communicator of the cell mesh (``COMM_SELF`` inside the coupled loop).
        shape: fundamental domain, ``"hexagon"`` or ``"parallelogram"``.
        origin: lower-left corner of the parallelogram.
        degree: Lagrange degree of the displacement (P2 resolves wall bending; P1 locks).
    """

    def __init__(
        self,
        cell: HoneycombCell,
        resolution: int = DEFAULT_RESOLUTION,
        comm: MPI.Comm = MPI.COMM_SELF,
        shape: str = "hexagon",
        origin: tuple[float, float] = (0.0, 0.0),
        degree: int = 2,
    ) -> None:
        self.cell = cell
        self.shape = shape
        self.comm = comm
        self.unit_cell = build_unit_cell_mesh(cell, resolution, comm, shape, origin)
        mesh = self.unit_cell.mesh
        self.V = fem.VectorFunctionSpace(mesh, ("Lagrange", degree))
        tol = 1e-3 * self.unit_cell.h
        pin = self.unit_cell.domain.pin_point
        pinned = fem.locate_dofs_geometrical(
            self.V, lambda x: np.hypot(x[0] - pin[0], x[1] - pin[1]) < tol
        )
        self.bcs = [fem.dirichletbc(np.zeros(2, dtype=PETSc.ScalarType), pinned, self.V)]
        self.mpc = periodic_constraint(self.V, self.unit_cell.domain, self.bcs, tol)

        dx = ufl.Measure("dx", domain=mesh, subdomain_data=self.unit_cell.cell_tags)(
            CELL_TAGS["walls"]
        )
        ds = ufl.Measure("ds", domain=mesh, subdomain_data=self.unit_cell.facet_tags)
        self._Fg = fem.Constant(mesh, np.eye(2, dtype=PETSc.ScalarType))
        self._E = fem.Constant(mesh, PETSc.ScalarType(1.0))
        self._nu = fem.Constant(mesh, PETSc.ScalarType(0.3))
        self._S = fem.Constant(mesh, np.zeros((2, 2), dtype=PETSc.ScalarType))
        z, phi = ufl.TrialFunction(self.V), ufl.TestFunction(self.V)
        self._z = fem.Function(self.mpc.function_space)
        # The operator that ``A`` equals after ``solve`` (for the same Fg, E, nu): the
        # definition, against which the tests check the basis.
        self.bilinear_form = fem.form(wall_bilinear_form(z, phi, self._Fg, self._E, self._nu, dx))

        self.area = cell.area
        self.wall_area = self._integrate(fem.form(fem.Constant(mesh, 1.0) * dx))
        self.P2_matrix = None
        if shape == "hexagon":
            x = ufl.SpatialCoordinate(mesh)
            n = ufl.FacetNormal(mesh)
            moment = fem.form(
                cell_problems.membrane_moment_form(self._S, x, n, ds(FACET_TAGS["membrane"]))
            )
            # int_Gamma y_j N_i with the cell centre at the origin; P2 = -grad(P1) . y
            M = np.array(
                [
                    [self._integrate(moment, unit_strain(j, i, sym=False)) for j in range(2)]
                    for i in range(2)
                ]
            )
            self.P2_matrix = -M / self.area

        self.basis = GradientBasis(self.V, self.mpc, self.bcs, dx)
        self._A = self.basis.diagonal.duplicate(copy=True)  # stored as the basis stores
        self.ksp = self.basis.factorization(self._A, "plantgrowth_cell_")
        self._rhs, self._x = self._A.createVecLeft(), self._A.createVecRight()
        self.ndofs = self.V.dofmap.index_map.size_global * self.V.dofmap.index_map_bs

    @property
    def A(self) -> PETSc.Mat:
        """The matrix of the last solve in dof order (a new AIJ matrix): what
        ``dolfinx_mpc.assemble_matrix(bilinear_form, mpc, bcs)`` assembles for its Fg, E, nu."""
        return self.basis.in_dof_order(self._A)

    def _integrate(self, form: fem.FormMetaClass, selector: np.ndarray | None = None) -> float:
        if selector is not None:
            self._S.value[:] = selector
        return self.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM)

    def _gradient_integrals(self, loads: np.ndarray) -> np.ndarray:
        """Solve ``A z = reduced @ w`` for each column w of ``loads`` (4, k); returns (4, k)
        ``int_{Y_w} grad(z)_p`` of the back-substituted solutions (the last one stays in
        ``self._z``)."""
        rhs = self.basis.reduced @ loads
        integrals = np.zeros_like(loads)
        for k in range(loads.shape[1]):
            self._rhs.array[:] = rhs[:, k]
            self.ksp.solve(self._rhs, self._x)
            self._z.x.array[self.basis.order] = self._x.array_r
            self._z.x.scatter_forward()
            self.mpc.backsubstitution(self._z.vector)
            integrals[:, k] = self._z.vector.array_r @ self.basis.full
        return self.comm.allreduce(integrals, op=MPI.SUM)

    def solve(
        self,
        Fg: np.ndarray | None = None,
        E: float = 1.0,
        nu: float = 0.3,
        pressure: bool = True,
        strain_averages: bool = True,
    ) -> CellResult:
        """Homogenize for the growth tensor Fg and wall moduli (E, nu).

        Returns E_hom ([maacro_E]) and, when asked for, K_hom ([maacro_K], the pressure problem
        [UCw_weak]) and the strain averages dbar[w^ij], dbar[v] (needed by the strain law only);
        what is not asked for is not computed and is None in the result.
        """
        start = time.perf_counter()
        Fg = np.eye(2) if Fg is None else np.asarray(Fg, dtype=float)
        self._Fg.value[:] = Fg
        self._E.value = E
        self._nu.value = nu
        self.basis.matrix(stiffness_weights(Fg, E, nu), self._A)
        self.ksp.setOperators(self._A)
        self.ksp.setUp()  # numeric factorization only: the pattern never changes

        wall = isotropic_tensor(E, nu)
        wall_b = [np.einsum("klmn,mn->kl", wall, unit_strain(i, j)) for i, j in STRAIN_PROBLEMS]
        # right-hand sides -int Jg X : grad(phi) G, X = E[b_ij] and I, as moment weights
        X = np.stack([x.ravel() for x in wall_b + [np.eye(2)] * pressure], axis=1)
        L = growth_map(Fg)
        integrals = L @ self._gradient_integrals(-np.linalg.det(Fg) * L.T @ X)
        grad_g = integrals.T.reshape(-1, 2, 2)  # int_{Y_w} grad(z) Fg^{-1}, one per problem
        dbar = 0.5 * (grad_g + grad_g.transpose(0, 2, 1)) / self.area
        stress = np.einsum("klmn,smn->skl", wall, dbar)

        phi_w = self.wall_area / self.area
        E_hom = np.zeros((2, 2, 2, 2))
        dbar_w = np.zeros((2, 2, 2, 2)) if strain_averages else None
        for s, (i, j) in enumerate(STRAIN_PROBLEMS):
            E_hom[i, j] = E_hom[j, i] = phi_w * wall_b[s] + stress[s]
            if strain_averages:
                dbar_w[i, j] = dbar_w[j, i] = dbar[s]
        K_hom = stress[3] if pressure else None
        dbar_v = dbar[3] if pressure and strain_averages else None
        seconds = self.comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
        return CellResult(E_hom, K_hom, dbar_w, dbar_v, phi_w, self.P2_matrix, self.ndofs, seconds)


def cell_properties(
    l1: float, l2: float, theta: float, w: float, E: float, nu: float, Fg: object,
    resolution: int | None, comm: MPI.Comm, resolution_name: str = "resolution",
) -> dict:  # fmt: skip
    """E_hom (six components), K_hom, the orthotropic moduli, phi_w, ndofs and seconds of one
    honeycomb cell (docs/model.md sections 2-3) at the growth tensor ``Fg`` (2x2), checked first
    (errors name the argument; the resolution as ``resolution_name``)."""
    E, nu = check_wall_material(E, nu)
    Fg = np.array(check_growth_tensor("Fg", Fg))
    resolution = DEFAULT_RESOLUTION if resolution is None else resolution
    cell = HoneycombCell(l1, l2, theta, w)
    mesh_size(cell, resolution, resolution_name)
    return CellSolver(cell, resolution, comm).solve(Fg, E, nu).summary()
