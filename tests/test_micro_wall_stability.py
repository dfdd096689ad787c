"""The micro walls' stability check with fibred walls (plantgrowth/models/micro/wall_stability.py):
it judges the wall tensor the equations use, ``C_w = C_iso + E_f q (t_g x t_g x t_g x t_g)``
(docs/model.md, fibre-reinforced walls), not the isotropic law.

Small unit-square meshes with P2 displacements that are linear in x (exact in P2) and DG0 fibre
coefficients, as the micro model has them; run serially and under mpirun (every value checked is
local to a triangle or gathered by the check).
"""

from __future__ import annotations

import numpy as np
import pytest
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI

from plantgrowth.base.mesh_samples import MeshSamples
from plantgrowth.forms.elasticity import Fibres, walls_stress
from plantgrowth.models.micro.wall_stability import WallStability
from plantgrowth.models.stability import (
    isotropic_voigt,
    normalised,
    smallest_acoustic_eigenvalue,
    svk_stress,
)

NU, E_F = 0.3, 5.0  # E = 1: the review's case, E_f = 5 E


def _rotation(degrees: float) -> np.ndarray:
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    return np.array([[c, -s], [s, c]])


def _walls(
    Fg, tangent, director, stiffness
) -> tuple[fem.Function, fem.Function, fem.Function, fem.Function, Fibres]:
    """u = 0, Fg, E = 1, nu and the fibre coefficients on a 3 x 3 unit square, each given as a
    function of the points x (3, n) for DG0 interpolation (the triangles' midpoints)."""
    msh = dmesh.create_unit_square(MPI.COMM_WORLD, 3, 3)
    Q0 = fem.FunctionSpace(msh, ("DG", 0))
    V0 = fem.VectorFunctionSpace(msh, ("DG", 0))
    u = fem.Function(fem.VectorFunctionSpace(msh, ("Lagrange", 2)))
    Fg_f = fem.Function(fem.TensorFunctionSpace(msh, ("DG", 0)))
    Fg_f.interpolate(Fg)
    E, nu, f_s = fem.Function(Q0), fem.Function(Q0), fem.Function(Q0)
    E.x.array[:], nu.x.array[:] = 1.0, NU
    f_s.interpolate(stiffness)
    m, t = fem.Function(V0), fem.Function(V0)
    m.interpolate(director)
    t.interpolate(tangent)
    return u, Fg_f, E, nu, Fibres(f_s, m, t)


def _constant(value: np.ndarray):
    """A function of x (3, n) with the constant (flattened) value."""
    return lambda x: np.tile(np.asarray(value, dtype=float).reshape(-1, 1), x.shape[1])


@pytest.mark.parametrize("finite", [True, False])
@pytest.mark.parametrize("turn", [0.0, 20.0])
def test_a_wall_compressed_along_its_fibres_is_judged_by_the_fibred_law(finite, turn):
    """A fibred wall compressed to a stretch of 0.90 along its fibres (q = 1), E_f = 5 E: the
    fibred law has lost strong ellipticity (-0.193 of its mean shear modulus; the smallest
    acoustic eigenvalue itself -0.195), the isotropic law has not (+0.713 of mu; +0.274), so the
    isotropic check the walls had before was not conservative. The wall's
    tangent is turned by -``turn`` and grown by the rotation Fg = R(turn), so only the grown
    tangent t_g = Fg t / |Fg t| lies along the fibres (m = e1, grown frame): the check must use
    t_g. Linear kinematics: the elastic strain whose stretch sqrt(I + 2 eps) is the same.
    The expected values come from the closed form with C_w written out by hand
    (C_iso + E_f e11 (x) e11 in Voigt storage); 1e-9: the direction search's round-off."""
    A = np.diag([0.9, 1.0])
    Fg = _rotation(turn)
    t = Fg.T @ np.array([1.0, 0.0])
    B = A if finite else np.eye(2) + 0.5 * (A @ A - np.eye(2))  # sqrt(I + 2 (B - I)) = A
    fibred = np.diag([1.0, 0.0, 0.0]) * E_F + isotropic_voigt(1.0, NU)
    isotropic = isotropic_voigt(1.0, NU)
    expected = [normalised(A[None], svk_stress(A[None], C[None]), C[None])[0]
                for C in (fibred, isotropic)]  # fmt: skip
    assert expected[0] == pytest.approx(-0.19292517, abs=1e-8)  # computed once, kept as a guard
    assert expected[1] == pytest.approx(0.71318681, abs=1e-8)
    raw = [smallest_acoustic_eigenvalue(A[None], svk_stress(A[None], C[None]), C[None])[0][0]
           for C in (fibred, isotropic)]  # fmt: skip
    assert raw == pytest.approx([-0.194780, 0.274303], abs=1e-6)  # the review's -0.195, +0.274
    u, Fg_f, E, nu, fibres = _walls(_constant(Fg), _constant(t), _constant([1.0, 0.0]),
                                    _constant(E_F))  # fmt: skip
    u.interpolate(lambda x: (B @ Fg - np.eye(2)) @ x[:2])
    for law, value in zip((fibres, None), expected, strict=True):
        walls = WallStability(u, Fg_f, E, nu, finite, law)
        assert np.allclose(walls.cell_minima(), value, rtol=1e-9, atol=0.0)
        # the check and Newton's ranking of its guesses: exact where negative, else a positive
        # lower bound (the screening of plantgrowth.models.stability.normalised)
        check = walls.check()
        assert check.nonelliptic_area_fraction == (1.0 if value < 0.0 else 0.0)
        for smallest in (check.smallest, walls.smallest()[0]):
            assert smallest == pytest.approx(value, rel=1e-9) if value < 0.0 else smallest > 0.0


def test_the_voigt_wall_tensor_is_the_ufl_wall_tensor():
    """At every sample point, ``C_w e`` from WallStability's Voigt tensor (engineering shear)
    equals ``walls_stress(e, E, nu, Fg, fibres)`` of forms/elasticity.py, the tensor the micro
    equations assemble, for a fixed non-symmetric-looking strain and per-triangle E_f,
    director, tangent and an Fg with stretch, shear and rotation that vary over the mesh. 1e-12
    relative: the two evaluate the same products in another order (round-off)."""

    def Fg(x):
        return np.stack([1.2 + 0.3 * x[0], 0.4 * x[1], -0.2 + 0.1 * x[0], 0.9 + 0.5 * x[1]])

    def unit(degrees):
        return np.stack([np.cos(np.radians(degrees)), np.sin(np.radians(degrees))])

    u, Fg_f, E, nu, fibres = _walls(
        Fg, lambda x: unit(150.0 * x[0] - 40.0), lambda x: unit(60.0 * x[1] + 35.0 * x[0]),
        lambda x: 1.0 + 4.0 * x[0] * x[1],
    )  # fmt: skip
    e = np.array([[0.013, -0.021], [-0.021, -0.007]])
    walls = WallStability(u, Fg_f, E, nu, False, fibres)
    C = walls.tangent()
    S = C @ np.array([e[0, 0], e[1, 1], 2.0 * e[0, 1]])
    msh = u.function_space.mesh
    stress = walls_stress(ufl.as_matrix(e.tolist()), E, nu, Fg_f, fibres)
    expected = np.stack(
        [MeshSamples(stress[i, j], msh, 2).values() for i, j in ((0, 0), (1, 1), (0, 1))], axis=1
    )
    assert len(S) > 0
    scale = np.abs(expected).max()
    assert np.abs(S - expected).max() <= 1e-12 * scale
    isotropic = isotropic_voigt(1.0, NU) @ np.array([e[0, 0], e[1, 1], 2.0 * e[0, 1]])
    assert np.abs(expected - isotropic).max() > 1e-3 * scale  # the fibres do act here
