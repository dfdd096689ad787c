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

import time
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.base.tensors import (
    VOIGT_NAMES,
    VOIGT_PAIRS,
    director,
    fibre_tensor,
    isotropic_tensor,
    orthotropic_moduli,
    symmetric_components,
    unit_strain,
)
from plantgrowth.forms import cell_problems
from plantgrowth.forms.elasticity import Fibres, wall_bilinear_form
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.meshes.unit_cell import FACET_TAGS, build_unit_cell_mesh
from plantgrowth.unitcell.gradient_basis import GradientBasis
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

    def strain_averages(self) -> dict:
        """``dbar_w``: {"11", "22", "12"} -> [d11, d22, d12] of dbar[w^ij]; ``dbar_v``:
        [d11, d22, d12] of dbar[v] (the CLI's JSON; None for what was not computed)."""

        def components(d: np.ndarray | None) -> list[float] | None:
            return None if d is None else symmetric_components(d)

        dbar_w = None
        if self.dbar_w is not None:
            dbar_w = {f"{i + 1}{j + 1}": components(self.dbar_w[i, j]) for i, j in STRAIN_PROBLEMS}
        return {"dbar_w": dbar_w, "dbar_v": components(self.dbar_v)}

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


def tensor_weights(Fg: np.ndarray, C: np.ndarray) -> np.ndarray:
    """(4, 4) symmetric S with ``a(z, phi) = sum_pq S[q, p] int d_q phi d_p z`` ([UC_weak]) on
    walls of tensor C (2, 2, 2, 2): ``S = Jg L^T C L``, p = (i, a) stands for ``d_a z_i``."""
    L = growth_map(Fg)
    return np.linalg.det(Fg) * L.T @ C.reshape(4, 4) @ L


class CellSolver:
    """Periodic unit-cell solver, reusable for many (Fg, E, nu, fibres) on one geometry.

    With ``fibres`` the walls are meshed split along the corner bisectors, one part per mid-line
    segment family (their tensors differ), and ``solve`` takes a fibre stiffness and director;
    without, the walls are one part and isotropic (the paper's cell, unchanged).

    Args:
        cell: the honeycomb parameters.
        resolution: elements across the wall thickness.
        comm: communicator of the cell mesh (``COMM_SELF`` inside the coupled loop).
        shape: fundamental domain, ``"hexagon"`` or ``"parallelogram"``.
        origin: lower-left corner of the parallelogram.
        degree: Lagrange degree of the displacement (P2 resolves wall bending; P1 locks).
        fibres: mesh and assemble for fibre-reinforced walls.
    """

    def __init__(
        self,
        cell: HoneycombCell,
        resolution: int = DEFAULT_RESOLUTION,
        comm: MPI.Comm = MPI.COMM_SELF,
        shape: str = "hexagon",
        origin: tuple[float, float] = (0.0, 0.0),
        degree: int = 2,
        fibres: bool = False,
    ) -> None:
        self.cell = cell
        self.shape = shape
        self.comm = comm
        self.fibres = fibres
        self.unit_cell = build_unit_cell_mesh(cell, resolution, comm, shape, origin, fibres=fibres)
        mesh = self.unit_cell.mesh
        self.V = fem.VectorFunctionSpace(mesh, ("Lagrange", degree))
        tol = 1e-3 * self.unit_cell.h
        pin = self.unit_cell.domain.pin_point
        pinned = fem.locate_dofs_geometrical(
            self.V, lambda x: np.hypot(x[0] - pin[0], x[1] - pin[1]) < tol
        )
        self.bcs = [fem.dirichletbc(np.zeros(2, dtype=PETSc.ScalarType), pinned, self.V)]
        self.mpc = periodic_constraint(self.V, self.unit_cell.domain, self.bcs, tol)

        tags = self.unit_cell.wall_tags
        parts = ufl.Measure("dx", domain=mesh, subdomain_data=self.unit_cell.cell_tags)
        dxs = [parts(tag) for tag in tags]
        self.dx = dxs[0] if len(dxs) == 1 else parts(tags)
        """The measure of all the walls."""
        ds = ufl.Measure("ds", domain=mesh, subdomain_data=self.unit_cell.facet_tags)
        self._Fg = fem.Constant(mesh, np.eye(2, dtype=PETSc.ScalarType))
        self._E = fem.Constant(mesh, PETSc.ScalarType(1.0))
        self._nu = fem.Constant(mesh, PETSc.ScalarType(0.3))
        self._S = fem.Constant(mesh, np.zeros((2, 2), dtype=PETSc.ScalarType))
        z, phi = ufl.TrialFunction(self.V), ufl.TestFunction(self.V)
        self._z = fem.Function(self.mpc.function_space)
        self.fibre_coefficients = None
        """:class:`~plantgrowth.forms.elasticity.Fibres` of the last solve (fibred solvers)."""
        if fibres:
            self.fibre_coefficients = Fibres(
                fem.Constant(mesh, PETSc.ScalarType(0.0)),
                fem.Constant(mesh, np.array([1.0, 0.0], dtype=PETSc.ScalarType)),
                self._tangent_field(),
            )
        # The operator that ``A`` equals after ``solve`` (for the same Fg, E, nu, fibres): the
        # definition, against which the tests check the basis.
        self.bilinear_form = fem.form(
            wall_bilinear_form(
                z, phi, self._Fg, self._E, self._nu, self.dx, self.fibre_coefficients
            )
        )

        self.area = cell.area
        areas = [self._integrate(fem.form(fem.Constant(mesh, 1.0) * dx)) for dx in dxs]
        self.part_fractions = np.array(areas) / self.area
        """|Y_f| / |Y| of each wall part f (one part, or the three segment families)."""
        self.wall_area = (
            areas[0]
            if len(areas) == 1
            else self._integrate(fem.form(fem.Constant(mesh, 1.0) * self.dx))
        )
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

        self.basis = GradientBasis(self.V, self.mpc, self.bcs, dxs)
        self._A = self.basis.diagonal.duplicate(copy=True)  # stored as the basis stores
        self.ksp = self.basis.factorization(self._A, "plantgrowth_cell_")
        self._rhs, self._x = self._A.createVecLeft(), self._A.createVecRight()
        self._solutions: list[np.ndarray] = []  # the last solve's back-substituted solutions
        self.ndofs = self.V.dofmap.index_map.size_global * self.V.dofmap.index_map_bs

    def _tangent_field(self) -> fem.Function:
        """DG0 field of the reference tangent t of each wall cell's segment family."""
        T = fem.Function(fem.VectorFunctionSpace(self.unit_cell.mesh, ("DG", 0)))
        tags = self.unit_cell.cell_tags
        values = T.x.array.reshape(-1, 2)
        for tag, t in zip(self.unit_cell.wall_tags, self.cell.wall_tangents(), strict=True):
            cells = tags.indices[tags.values == tag]
            values[T.function_space.dofmap.list.array[cells]] = t
        T.x.scatter_forward()
        return T

    def wall_tensors(
        self, Fg: np.ndarray, E: float, nu: float, fibre_stiffness: float, fibre_angle: float
    ) -> list[np.ndarray]:
        """The wall tensor C_w (2, 2, 2, 2) of each wall part: the isotropic one, or for fibred
        walls ``C_iso + E_f q t_g x t_g x t_g x t_g`` per segment family (E_f =
        fibre_stiffness * E, m at ``fibre_angle`` degrees)."""
        C = isotropic_tensor(E, nu)
        if not self.fibres:
            if fibre_stiffness != 0.0:
                raise ValueError("fibre_stiffness > 0 needs a CellSolver built with fibres=True")
            return [C]
        m = director(fibre_angle)
        return [C + fibre_tensor(Fg, t, m, fibre_stiffness * E) for t in self.cell.wall_tangents()]

    @property
    def A(self) -> PETSc.Mat:
        """The matrix of the last solve in dof order (a new AIJ matrix): what
        ``dolfinx_mpc.assemble_matrix(bilinear_form, mpc, bcs)`` assembles for its Fg, E, nu."""
        return self.basis.in_dof_order(self._A)

    def correctors(self) -> list[fem.Function]:
        """The cell solutions of the last :meth:`solve`, periodic and zero at the pinned point:
        ``w^11, w^22, w^12`` ([UC_weak]) and, if it solved the pressure problem, ``v``
        ([UCw_weak]); new functions, which later solves leave unchanged."""
        if not self._solutions:
            raise ValueError("no cell problem solved yet: call solve() first")
        correctors = []
        for values in self._solutions:
            z = fem.Function(self.mpc.function_space)
            z.x.array[:] = values
            correctors.append(z)
        return correctors

    def _integrate(self, form: fem.FormMetaClass, selector: np.ndarray | None = None) -> float:
        if selector is not None:
            self._S.value[:] = selector
        return self.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM)

    def _gradient_integrals(self, loads: np.ndarray) -> np.ndarray:
        """Solve ``A z = sum_f reduced[f] @ w_f`` for each column of ``loads`` (parts, 4, k);
        returns (parts, 4, k) ``int_{Y_f} grad(z)_p`` of the back-substituted solutions over
        each wall part (the last one stays in ``self._z``)."""
        rhs = sum(reduced @ w for reduced, w in zip(self.basis.reduced, loads, strict=True))
        integrals = np.zeros_like(loads)
        self._solutions = []
        for k in range(loads.shape[2]):
            self._rhs.array[:] = rhs[:, k]
            self.ksp.solve(self._rhs, self._x)
            self._z.x.array[self.basis.order] = self._x.array_r
            self._z.x.scatter_forward()
            self.mpc.backsubstitution(self._z.vector)
            self._solutions.append(self._z.x.array.copy())
            integrals[:, :, k] = self._z.vector.array_r @ self.basis.full
        return self.comm.allreduce(integrals, op=MPI.SUM)

    def solve(
        self,
        Fg: np.ndarray | None = None,
        E: float = 1.0,
        nu: float = 0.3,
        pressure: bool = True,
        strain_averages: bool = True,
        fibre_stiffness: float = 0.0,
        fibre_angle: float = 0.0,
    ) -> CellResult:
        """Homogenize for the growth tensor Fg and wall moduli (E, nu), and for a fibred solver
        the fibre stiffness E_f / E and the director angle (degrees from x1, grown frame).

        Returns E_hom ([maacro_E]) and, when asked for, K_hom ([maacro_K], the pressure problem
        [UCw_weak]) and the strain averages dbar[w^ij], dbar[v] (needed by the strain law only);
        what is not asked for is not computed and is None in the result.
        """
        start = time.perf_counter()
        Fg = np.eye(2) if Fg is None else np.asarray(Fg, dtype=float)
        self._Fg.value[:] = Fg
        self._E.value = E
        self._nu.value = nu
        walls = self.wall_tensors(Fg, E, nu, fibre_stiffness, fibre_angle)
        if self.fibres:
            self.fibre_coefficients.stiffness.value = fibre_stiffness * E
            self.fibre_coefficients.director.value[:] = director(fibre_angle)
        self.basis.matrix([tensor_weights(Fg, C) for C in walls], self._A)
        self.ksp.setOperators(self._A)
        self.ksp.setUp()  # numeric factorization only: the pattern never changes

        # C_f[b_ij] per part f and problem s; right-hand sides -int Jg X : grad(phi) G with
        # X = C_f[b_ij] and I, as moment weights of each part
        wall_b = np.array(
            [[np.einsum("klmn,mn->kl", C, unit_strain(i, j)) for i, j in STRAIN_PROBLEMS]
             for C in walls]
        )  # fmt: skip
        columns = [[x.ravel() for x in list(b) + [np.eye(2)] * pressure] for b in wall_b]
        X = np.stack([np.stack(part, axis=1) for part in columns])
        L = growth_map(Fg)
        integrals = L @ self._gradient_integrals(-np.linalg.det(Fg) * L.T @ X)
        # int_{Y_f} grad(z) Fg^{-1}, one per part and problem
        grad_g = integrals.transpose(0, 2, 1).reshape(len(walls), -1, 2, 2)
        dbar_parts = 0.5 * (grad_g + grad_g.transpose(0, 1, 3, 2)) / self.area
        dbar = dbar_parts.sum(axis=0)
        stress = sum(
            np.einsum("klmn,smn->skl", C, d) for C, d in zip(walls, dbar_parts, strict=True)
        )
        wall_mean = np.einsum("f,fskl->skl", self.part_fractions, wall_b)  # mean of C_w[b_ij]

        phi_w = self.wall_area / self.area
        E_hom = np.zeros((2, 2, 2, 2))
        dbar_w = np.zeros((2, 2, 2, 2)) if strain_averages else None
        for s, (i, j) in enumerate(STRAIN_PROBLEMS):
            E_hom[i, j] = E_hom[j, i] = wall_mean[s] + stress[s]
            if strain_averages:
                dbar_w[i, j] = dbar_w[j, i] = dbar[s]
        K_hom = stress[3] if pressure else None
        dbar_v = dbar[3] if pressure and strain_averages else None
        seconds = self.comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
        return CellResult(E_hom, K_hom, dbar_w, dbar_v, phi_w, self.P2_matrix, self.ndofs, seconds)
