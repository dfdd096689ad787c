"""The acoustic tensor and where a law loses strong ellipticity (issue 20, item 2;
plantgrowth.models.stability), against closed forms for St Venant-Kirchhoff walls."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

import plantgrowth as pg
from plantgrowth.models.stability import (
    isotropic_voigt,
    normalised,
    smallest_acoustic_eigenvalue,
    svk_stress,
)

E, NU = 1.0, 0.3
LAM, MU = E * NU / (1 - NU**2), E / (2 * (1 + NU))  # plane stress


def smallest(Fe: np.ndarray) -> float:
    C = isotropic_voigt(E, NU)[None]
    return float(smallest_acoustic_eigenvalue(Fe[None], svk_stress(Fe[None], C), C)[0][0])


def test_the_unstressed_state_has_the_shear_modulus():
    """At Fe = I: Q(N) = M(N), eigenvalues mu and lam + 2 mu for every N."""
    assert smallest(np.eye(2)) == pytest.approx(MU, rel=1e-12)


def test_equal_biaxial_compression_loses_ellipticity_at_the_closed_form_stretch():
    """Fe = s I: Q(N) = (lam + mu)(s^2 - 1) + mu s^2 on the shear mode, zero at
    s = sqrt((lam + mu) / (lam + 2 mu)) = 0.806 (nu = 0.3); root to 1e-10 (brentq's tolerance;
    the closed form has no direction to sample)."""
    root = brentq(lambda s: smallest(s * np.eye(2)), 0.5, 0.99, xtol=1e-12)
    assert root == pytest.approx(np.sqrt((LAM + MU) / (LAM + 2 * MU)), abs=1e-10)
    assert round(root, 3) == 0.806


def brute_force(Fe: np.ndarray, k: int = 200_000) -> float:
    """min over k directions of the smallest eigenvalue of Q(N), written out from A_iJkL."""
    C = isotropic_voigt(E, NU)
    v = np.array([[0, 2], [2, 1]])
    C4 = C[v[:, :, None, None], v[None, None, :, :]]
    S = svk_stress(Fe[None], C[None])[0]
    A = np.einsum("ik,JL->iJkL", np.eye(2), S) + np.einsum("iM,MJPL,kP->iJkL", Fe, C4, Fe)
    phi = np.linspace(0.0, np.pi, k, endpoint=False)
    N = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    Q = np.einsum("iJkL,nJ,nL->nik", A, N, N)
    return float(np.linalg.eigvalsh(Q)[:, 0].min())


def test_uniaxial_strain_loses_ellipticity_in_an_oblique_direction():
    """Fe = diag(s, 1): the loss at s = 0.65459 (the issue: 0.6545) comes from an oblique N,
    above both principal-direction limits (1/sqrt(3) and sqrt(lam / (lam + 2 mu))); the same
    root as a brute-force sweep of 2e5 directions of the tangent written out index by index
    (1e-8: the sweep's angular spacing 1.6e-5 squared, times the curvature)."""
    root = brentq(lambda s: smallest(np.diag([s, 1.0])), 0.5, 0.99, xtol=1e-12)
    brute = brentq(lambda s: brute_force(np.diag([s, 1.0])), 0.5, 0.99, xtol=1e-12)
    assert root == pytest.approx(brute, abs=1e-8)
    assert 0.6545 <= root < 0.6546
    assert root > max(3**-0.5, np.sqrt(LAM / (LAM + 2 * MU)))


def test_a_rotation_changes_nothing():
    rng = np.random.default_rng(3)
    Fe = np.diag([0.9, 1.1]) + 0.05 * rng.normal(size=(2, 2))
    t = 0.7
    R = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    assert smallest(R @ Fe) == pytest.approx(smallest(Fe), rel=1e-9)


def test_the_homogenized_honeycomb_loses_ellipticity_under_a_percent_of_compression():
    """S = E_hom Ee of the reference cell (resolution 2: the balanced preset's; G12 = 5.9e-4
    against E1111 + E1122 = 0.060): the loss at stretch 0.990 (equal biaxial) and 0.98
    (uniaxial strain), the issue's numbers to the digits it gives."""
    c = pg.cell(resolution=2)
    C = np.array([[c["E1111"], c["E1122"], c["E1112"]], [c["E1122"], c["E2222"], c["E2212"]],
                  [c["E1112"], c["E2212"], c["E1212"]]])[None]  # fmt: skip

    def smallest_hom(Fe: np.ndarray) -> float:
        return float(smallest_acoustic_eigenvalue(Fe[None], svk_stress(Fe[None], C), C)[0][0])

    biaxial = brentq(lambda s: smallest_hom(s * np.eye(2)), 0.9, 0.9999, xtol=1e-12)
    uniaxial = brentq(lambda s: smallest_hom(np.diag([s, 1.0])), 0.9, 0.9999, xtol=1e-12)
    assert round(biaxial, 3) == 0.990 and round(uniaxial, 2) == 0.98


def test_the_normalisation_is_the_shear_modulus_of_isotropic_walls():
    """At rest the normalised value of isotropic walls is 1 (Q(N) = M(N), smallest eigenvalue
    mu); 1e-12: round-off of the parabolic refinement's arithmetic."""
    C = isotropic_voigt(np.array([0.5, 2.0]), np.array([0.2, 0.45]))
    rest = np.tile(np.eye(2), (2, 1, 1))
    assert np.allclose(normalised(rest, np.zeros((2, 2, 2)), C), 1.0, rtol=1e-12, atol=0.0)


@pytest.mark.parametrize("finite", [True, False])
def test_the_walls_are_judged_at_their_p2_samples(finite):
    """WallStability on a P2 field u = (A - I) x (exact in P2), Fg = I: every sample has the
    closed form's value for ``Fe = A`` (finite) or ``Fe = sqrt(I + 2 sym(A - I))`` (linear);
    a uniaxial strain of stretch 0.7 is elliptic and 0.6 is not (the loss is at 0.6545), so the
    whole area is elliptic, then non-elliptic."""
    from dolfinx import fem
    from dolfinx import mesh as dmesh
    from mpi4py import MPI

    from plantgrowth.models.micro.wall_stability import WallStability

    msh = dmesh.create_unit_square(MPI.COMM_WORLD, 3, 3)
    V = fem.VectorFunctionSpace(msh, ("Lagrange", 2))
    Q0 = fem.FunctionSpace(msh, ("DG", 0))
    T0 = fem.TensorFunctionSpace(msh, ("DG", 0))
    u, Fg = fem.Function(V), fem.Function(T0)
    Fg.interpolate(lambda x: np.tile(np.eye(2).reshape(4, 1), x.shape[1]))
    E, nu = fem.Function(Q0), fem.Function(Q0)
    E.x.array[:], nu.x.array[:] = 1.0, NU
    walls = WallStability(u, Fg, E, nu, finite)
    for s, fraction in ((0.7, 0.0), (0.6, 1.0)):
        A = np.diag([s, 1.0]) if finite else np.diag([1.0 + 0.5 * (s * s - 1.0), 1.0])
        u.interpolate(lambda x, A=A: (A - np.eye(2)) @ x[:2])
        check = walls.check()
        expected = smallest(np.diag([s, 1.0])) / MU
        assert check.smallest == pytest.approx(expected, rel=1e-9)
        assert check.nonelliptic_area_fraction == fraction


def test_the_sweep_finds_the_deepest_basin_of_anisotropic_tangents():
    """Random states (stretches of +/- 20%, small prestress) of grown and elongated homogenized
    honeycombs and of isotropic walls, against an 8,000-direction sweep, which can only
    overestimate the minimum: the refined minimum is never above it by more than 1e-9 of the
    shear modulus (round-off). With one basin refined it was up to 9e-3 above."""
    from plantgrowth.models.stability import acoustic_tensor, elasticity_tensor, mean_shear_modulus

    tensors = [isotropic_voigt(1.0, 0.3), isotropic_voigt(1.0, 0.49)]
    for Fg, l1, w in (([[1.5, 0.0], [0.0, 1.0]], 1.0, 0.05), ([[1.0, 0.3], [0.0, 2.5]], 2.0, 0.01)):
        c = pg.cell(resolution=1, l1=l1, w=w, Fg=Fg)
        tensors.append([[c["E1111"], c["E1122"], c["E1112"]], [c["E1122"], c["E2222"], c["E2212"]],
                        [c["E1112"], c["E2212"], c["E1212"]]])  # fmt: skip
    rng = np.random.default_rng(1)
    n = 400
    C = np.array(tensors)[rng.integers(len(tensors), size=n)]
    Fe = np.eye(2) * rng.uniform(0.8, 1.2, size=(n, 1, 1)) + rng.normal(0.0, 0.1, (n, 2, 2))
    S = svk_stress(Fe, C) + 1e-3 * rng.normal(size=(n, 1, 1)) * np.ones((2, 2))
    found = smallest_acoustic_eigenvalue(Fe, S, C)[0]
    swept = np.full(n, np.inf)
    for part in np.split(np.linspace(0.0, np.pi, 8000, endpoint=False), 8):
        N = np.broadcast_to(np.stack([np.cos(part), np.sin(part)], axis=1), (n, len(part), 2))
        Q = acoustic_tensor(Fe, S, elasticity_tensor(C), N)
        swept = np.minimum(swept, np.linalg.eigvalsh(Q)[..., 0].min(axis=1))
    assert np.all((found - swept) / mean_shear_modulus(C) <= 1e-9)
    assert np.mean(swept < 0.0) > 0.1  # the sample reaches past the loss, not only near rest
