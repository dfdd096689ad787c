"""A uniform growth tensor is a change of variables (docs/model.md sections 3 and 7): exact checks.

With Fg constant, ``x = Fg y`` maps the reference walls onto the grown walls, ``grad_x = grad_y
Fg^{-1}``, ``dx = Jg dy`` and, on the membrane, ``n dgamma_x = Jg Fg^{-T} N dgamma_y`` (Nanson).
So every growth-weighted form of the code (``Jg``, ``grad(.) Fg^{-1}``, ``Fg^{-T} N``) is the
growth-free form on the mapped domain. On a mesh of straight triangles the mapped P2 space is
the P2 space of the mapped mesh, so the identity holds for the *discrete* problems too, to the
round-off of their LU solves: it tests the transpositions and Jacobians that isotropic growth
(Fg = g I, symmetric and commuting with everything) cannot see.

- Cell problems: Fg = s R (R a rotation) on the cell Y is the growth-free problem on the rotated
  cell R Y, whose solutions are the rotated ones (isotropic walls), so E_hom, dbar[w] rotate as
  4th-order tensors and K_hom, dbar[v] as 2nd-order ones (s drops out, docs/model.md section 3).
- Micro model: a uniform Fg = A on the tissue is the growth-free tissue with its mesh mapped by
  A; with F = I + grad u, ``F A^{-1}`` is the same in both, so ``u_A(y) = (A - I) y +
  u_I(A y)`` (the linear part lies in P2), and the wall averages satisfy
  ``int_ref X dy = (1/Jg) int_grown X dx``. A21 = 0 keeps the bottom edge on the symmetry plane
  x2 = 0 and the origin in place, so the boundary conditions map onto each other.

Tolerances: round-off of the LU solves, 1e-9 relative to the largest entry (measured: cell
problems ~1e-14; micro tissue, Nx = 4 with w = 0.1, 1e-11 relative to max |u_A|; thinner walls
make the soft tissue worse conditioned: 2e-10 at w = 0.05 with a larger shear).
"""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI
from scipy.spatial import cKDTree

from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.models.micro.model import MicroModel
from plantgrowth.scene import parse_scene
from plantgrowth.unitcell.solver import CellSolver

ROUND_OFF = 1e-9  # LU round-off (module docstring)


def rotation(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def rotate2(R: np.ndarray, T: np.ndarray) -> np.ndarray:
    return R @ T @ R.T


def rotate4(R: np.ndarray, T: np.ndarray) -> np.ndarray:
    return np.einsum("ia,jb,kc,ld,abcd->ijkl", R, R, R, R, T)


def relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


@pytest.mark.parametrize("scale", [1.0, 1.3])
def test_rotated_growth_rotates_the_homogenized_tensors(scale):
    """Cell l1 = 1.5 (orthotropic, not isotropic: a rotation shows), Fg = scale R(0.4 rad)."""
    solver = CellSolver(HoneycombCell(l1=1.5, w=0.1), 1, MPI.COMM_WORLD)
    r0 = solver.solve(np.eye(2), 1.0, 0.3)
    R = rotation(0.4)
    r = solver.solve(scale * R, 1.0, 0.3)
    print(f"rotation: E_hom relative error {relative(r.E_hom, rotate4(R, r0.E_hom)):.1e}")
    assert relative(r.E_hom, rotate4(R, r0.E_hom)) < ROUND_OFF
    assert relative(r.dbar_w, rotate4(R, r0.dbar_w)) < ROUND_OFF
    assert relative(r.K_hom, rotate2(R, r0.K_hom)) < ROUND_OFF
    assert relative(r.dbar_v, rotate2(R, r0.dbar_v)) < ROUND_OFF
    # the check tells R from R^T (a transposed Fg^{-1} rotates the other way)
    assert relative(rotate4(R.T, r0.E_hom), rotate4(R, r0.E_hom)) > 1e-2


A = np.array([[1.1, 0.15], [0.0, 0.95]])  # A21 = 0 (module docstring); not symmetric, det 1.045


def micro_step(Fg: np.ndarray, mapped: bool) -> tuple[MicroModel, np.ndarray]:
    """First solve of a Nx = 4 stress-law tissue (P1 = 0.001), one P2 element across a wall,
    with the growth tensor Fg in every cell, its mesh mapped by A if ``mapped``."""
    scene = parse_scene(
        {
            "model": "micro",
            "cell": {"w": 0.1},
            "growth": {"law": "stress"},
            "micro": {"nx": 4, "resolution": 1},
        }
    )
    model = MicroModel(scene, MPI.COMM_WORLD)
    if mapped:
        x = model.mesh.geometry.x
        x[:, :2] = x[:, :2] @ A.T
    return model, model.step(np.tile(Fg, (model.layout.n_cells, 1, 1))).G


def gather_dofs(model: MicroModel) -> tuple[np.ndarray, np.ndarray]:
    """(positions, values) of the displacement dofs of all ranks, on every rank."""
    x = model.V.tabulate_dof_coordinates()[:, :2]
    u = model.u.x.array.reshape(-1, 2)[: len(x)]
    parts = model.comm.allgather((x, u))
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


def test_uniform_micro_growth_is_the_mapped_tissue():
    """u and the growth rate of the tissue grown by A equal those of the growth-free tissue on
    the mapped mesh: ``u_A = (A - I) y + u_I`` at every dof, and G_I = Jg G_A (the wall means
    are taken over the reference wall areas; eta = 1, tau = 0 and [.]_+ is positively
    homogeneous, so the factor Jg passes through the growth law below the clamp)."""
    grown, G_grown = micro_step(A, mapped=False)
    mapped, G_mapped = micro_step(np.eye(2), mapped=True)
    # dofs matched by position (the two meshes may be partitioned differently under MPI)
    y, u_grown = gather_dofs(grown)
    x, u_mapped = gather_dofs(mapped)
    distance, index = cKDTree(x @ np.linalg.inv(A).T).query(y)
    assert distance.max() < 1e-12  # the same mesh, mapped: a precondition, not the check
    expected = y @ (A - np.eye(2)).T + u_mapped[index]
    error = float(np.abs(u_grown - expected).max())
    elastic, size = float(np.abs(u_mapped).max()), float(np.abs(u_grown).max())
    # turgor deforms the tissue: the elastic part, the one under test, is far above round-off
    assert elastic > 1e-3 * size
    print(f"uniform growth A: max |u_A - (A - I) y - u_I| = {error:.2e} (max |u_A| = {size:.3g},"
          f" max |u_I| = {elastic:.3g})")  # fmt: skip
    # the LU round-off scales with the solved field u_A, dominated by (A - I) y
    assert error <= ROUND_OFF * size
    Jg = np.linalg.det(A)
    assert np.abs(G_grown).max() > 1e-3
    assert relative(G_mapped, Jg * G_grown) < ROUND_OFF
