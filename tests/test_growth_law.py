"""Growth law and time integration (plantgrowth/models/growth.py, docs/model.md
section 4): pure numpy.

No meshes and no MPI collectives: every rank runs the same checks. Tensors carry the cell index
first, (n, 2, 2). Tolerances are round-off tolerances: every identity checked here is exact in
exact arithmetic, and the operations are a handful of flops on O(1) numbers (eigh of a 2x2
matrix, a 2x2 inverse), so 1e-14..1e-12 leaves a margin of 100x or more over float64 round-off.
"""

import numpy as np
import pytest
from scipy.linalg import expm

from plantgrowth.base.tensors import isotropic_tensor, voigt_matrix
from plantgrowth.models import growth

RNG_SEED = 20240607


def rotation(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def stack(*tensors) -> np.ndarray:
    return np.array(tensors, dtype=float)


def random_symmetric(rng, n: int, scale: float = 1.0) -> np.ndarray:
    A = rng.normal(scale=scale, size=(n, 2, 2))
    return 0.5 * (A + np.swapaxes(A, 1, 2))


def random_growth_tensors(rng, n: int) -> np.ndarray:
    """Random Fg with det > 0 (identity plus a moderate perturbation, rows swapped if needed)."""
    Fg = np.eye(2) + rng.normal(scale=0.4, size=(n, 2, 2))
    flip = np.linalg.det(Fg) < 0
    Fg[flip] = Fg[flip][:, ::-1, :]
    assert np.all(np.linalg.det(Fg) > 0)
    return Fg


# --- positive part ------------------------------------------------------------------------------


def test_positive_part_of_known_matrices():
    R = rotation(0.3)
    A = stack(
        np.diag([2.0, -1.0]),  # diagonal, mixed signs
        R @ np.diag([2.0, -1.0]) @ R.T,  # the same, rotated: the eigenvectors must follow
        -np.array([[2.0, 0.5], [0.5, 1.0]]),  # negative definite -> 0
        np.array([[2.0, 0.5], [0.5, 1.0]]),  # positive definite -> itself
        np.zeros((2, 2)),
    )
    expected = stack(
        np.diag([2.0, 0.0]),
        R @ np.diag([2.0, 0.0]) @ R.T,
        np.zeros((2, 2)),
        A[3],
        np.zeros((2, 2)),
    )
    assert np.allclose(growth.positive_part(A), expected, rtol=0, atol=1e-14)  # round-off


def test_positive_part_is_a_projection():
    """A_+ is symmetric positive semi-definite, (A_+)_+ = A_+ and A = A_+ - (-A)_+."""
    rng = np.random.default_rng(RNG_SEED)
    A = random_symmetric(rng, 200)
    P = growth.positive_part(A)
    assert np.allclose(P, np.swapaxes(P, 1, 2), atol=1e-14)
    assert np.all(np.linalg.eigvalsh(P) >= -1e-14)  # round-off of eigh on O(1) entries
    assert np.allclose(growth.positive_part(P), P, atol=1e-13)
    assert np.allclose(P - growth.positive_part(-A), A, atol=1e-13)


# --- growth rate --------------------------------------------------------------------------------


def test_growth_rate_isotropic_driving_force():
    """X = s I gives G = eta (s / phi_w - tau) I when positive, 0 when not (docs/model.md section
    4)."""
    s = np.array([0.01, 0.01, 0.001])
    phi_w = np.array([0.1, 0.2, 0.1])
    eta = np.array([1.5, 0.5, 2.0])
    tau = np.array([0.002, 0.0, 0.02])  # the last one is above s / phi_w = 0.01: no growth
    G = growth.growth_rate(s[:, None, None] * np.eye(2), phi_w, eta, tau, clamp=1.0)
    rate = np.maximum(eta * (s / phi_w - tau), 0.0)
    assert np.allclose(G, rate[:, None, None] * np.eye(2), rtol=1e-14, atol=1e-17)
    assert np.all(G[2] == 0.0)


def test_growth_rate_clamp_is_component_wise():
    one = np.ones(1)
    X = np.diag([3.0, 0.5])[None]  # / phi_w = 0.5, - tau = 1: diag(5, 0) * eta = 2 -> diag(10, 0)
    G = growth.growth_rate(X, 0.5 * one, 2.0 * one, 1.0 * one, clamp=1.0)
    assert np.allclose(G[0], np.diag([1.0, 0.0]), atol=1e-14)
    # rotated by 45 degrees: [[5, -5], [-5, 5]] before the clamp; the negative off-diagonal
    # entries are clipped to -M, not to 0 (clip(G~, -M, M) component-wise, [def_G_11])
    R = rotation(np.pi / 4)
    X = (R @ np.diag([0.0, 10.0]) @ R.T)[None]
    G = growth.growth_rate(X, one, one, 0.0 * one, clamp=2.0)
    assert np.allclose(G[0], [[2.0, -2.0], [-2.0, 2.0]], atol=1e-14)
    # below the clamp nothing changes
    G = growth.growth_rate(X, one, one, 0.0 * one, clamp=100.0)
    assert np.allclose(G[0], [[5.0, -5.0], [-5.0, 5.0]], atol=1e-13)


# --- time integration ---------------------------------------------------------------------------


@pytest.mark.parametrize("dt", [0.1, 1.0, 7.0])
def test_exp_integrator_is_exact_for_constant_diagonal_G(dt):
    G = np.diag([0.02, -0.03])[None]
    Fg = np.eye(2)[None]
    n = 10
    for _ in range(n):
        Fg = growth.advance(Fg, G, dt, "exp")
    t = n * dt
    # n products of exact exponentials: relative round-off ~n * 1e-16
    assert np.allclose(Fg[0], np.diag(np.exp(t * np.diag(G[0]))), rtol=1e-13, atol=0)


def test_exp_integrator_matches_expm_for_symmetric_G():
    rng = np.random.default_rng(RNG_SEED)
    G = random_symmetric(rng, 20, scale=0.5)
    Fg = random_growth_tensors(rng, 20)
    new = growth.advance(Fg, G, 2.5, "exp")
    reference = np.array([expm(2.5 * g) @ F for g, F in zip(G, Fg, strict=True)])
    # closed form (cosh, sinh) vs Pade expm of moderate matrices (|dt G| ~ 2): both to ~1e-14
    assert np.allclose(new, reference, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("dt", [1e-3, 1.0, 50.0])
def test_exp_integrator_det_identity(dt):
    """det(expm(dt G) Fg) = exp(dt tr G) det Fg for any dt (docs/model.md section 4: det Fg never
    drops)."""
    rng = np.random.default_rng(RNG_SEED)
    # |dt G| up to ~2: larger exponents make det(new) itself ill-conditioned to evaluate
    G = random_symmetric(rng, 50, scale=0.02)
    Fg = random_growth_tensors(rng, 50)
    new = growth.advance(Fg, G, dt, "exp")
    expected = np.exp(dt * np.trace(G, axis1=1, axis2=2)) * np.linalg.det(Fg)
    assert np.allclose(np.linalg.det(new), expected, rtol=1e-12, atol=0)  # round-off, relative


def test_euler_integrator_is_the_first_order_formula():
    rng = np.random.default_rng(RNG_SEED)
    G = random_symmetric(rng, 20)
    Fg = random_growth_tensors(rng, 20)
    new = growth.advance(Fg, G, 0.3, "euler")
    assert np.allclose(new, Fg + 0.3 * np.einsum("nij,njk->nik", G, Fg), rtol=1e-15, atol=1e-15)


def test_large_negative_step_euler_loses_det_exp_keeps_it():
    """dt G with an eigenvalue < -1: Euler's I + dt G is singular or reflecting, expm is not."""
    G = np.diag([-0.5, 0.1])[None]
    dt = 3.0  # dt G has the eigenvalue -1.5
    Fg = np.eye(2)[None]
    assert np.linalg.det(growth.advance(Fg, G, dt, "euler"))[0] <= 0.0
    assert np.linalg.det(growth.advance(Fg, G, dt, "exp"))[0] > 0.0
    # the boundary case: eigenvalue exactly -1 makes Euler's Fg singular
    assert np.linalg.det(growth.advance(Fg, G, 2.0, "euler"))[0] == pytest.approx(0.0, abs=1e-15)


def test_unknown_integrator_is_an_error():
    with pytest.raises(ValueError, match="integrator"):
        growth.advance(np.eye(2)[None], np.zeros((1, 2, 2)), 1.0, "rk4")


# --- strains and stresses -----------------------------------------------------------------------


def test_elastic_strain_vanishes_for_grad_u_equal_Fg_minus_I():
    """grad u = Fg - I (the tissue follows its growth) gives eps_el = 0 for any Fg."""
    rng = np.random.default_rng(RNG_SEED)
    Fg = random_growth_tensors(rng, 30)
    eps = growth.elastic_strain(Fg - np.eye(2), Fg)
    assert np.allclose(eps, 0.0, atol=1e-13)  # a 2x2 inverse and a product: round-off


def test_elastic_strain_without_growth_is_the_small_strain():
    rng = np.random.default_rng(RNG_SEED)
    grad_u = rng.normal(scale=0.1, size=(30, 2, 2))
    eps = growth.elastic_strain(grad_u, np.tile(np.eye(2), (30, 1, 1)))
    assert np.allclose(eps, 0.5 * (grad_u + np.swapaxes(grad_u, 1, 2)), atol=1e-15)


def test_elastic_strain_of_growth_without_displacement():
    """u = 0, Fg = g I: eps_el = (1/g - 1) I (an unloaded grown tissue is compressed back)."""
    g = np.array([1.0, 1.5, 0.8])
    eps = growth.elastic_strain(np.zeros((3, 2, 2)), g[:, None, None] * np.eye(2))
    assert np.allclose(eps, (1.0 / g - 1.0)[:, None, None] * np.eye(2), atol=1e-15)


@pytest.mark.parametrize("nu", [0.0, 0.3, -0.5])
def test_homogenized_stress_and_strain_of_a_solid_wall_is_hooke(nu):
    """A 'cell' that is all wall: E_hom = wall tensor, phi_w = 1, dbar = 0, K = 0.

    Then eps_hom = eps_el and sigma_hom = lam tr(eps) I + 2 mu eps (plane stress, docs/model.md
    section 1).
    """
    E = 2.0
    rng = np.random.default_rng(RNG_SEED)
    n = 10
    eps = random_symmetric(rng, n, scale=0.01)
    wall = isotropic_tensor(E, nu)
    C = np.tile(voigt_matrix(wall), (n, 1, 1))
    P1 = np.full(n, 0.001)
    sigma = growth.homogenized_stress(C, eps, None, P1)
    mu, lam = E / (2 * (1 + nu)), E * nu / (1 - nu**2)
    trace = np.trace(eps, axis1=1, axis2=2)
    hooke = lam * trace[:, None, None] * np.eye(2) + 2 * mu * eps
    assert np.allclose(sigma, hooke, rtol=1e-14, atol=1e-16)
    assert np.allclose(sigma, np.einsum("ijkl,nkl->nij", wall, eps), rtol=1e-14, atol=1e-16)
    strain = growth.homogenized_strain(eps, np.ones(n), np.zeros((n, 2, 2, 2, 2)), None, P1)
    assert np.allclose(strain, eps, rtol=0, atol=1e-18)
    # the pressure terms add K P1 and P1 dbar[v]
    K = np.tile(np.array([[0.3, 0.1], [0.1, 0.2]]), (n, 1, 1))
    with_K = growth.homogenized_stress(C, eps, K, P1)
    assert np.allclose(with_K, hooke + 0.001 * K, rtol=1e-14, atol=1e-16)
    with_v = growth.homogenized_strain(eps, np.ones(n), np.zeros((n, 2, 2, 2, 2)), K, P1)
    assert np.allclose(with_v, eps + 0.001 * K, rtol=1e-14, atol=1e-18)


def test_homogenized_strain_counts_off_diagonal_pairs():
    """sum_ij eps_ij dbar[w^ij] over all i, j: a shear strain enters twice (12 and 21)."""
    n = 1
    dbar_w = np.zeros((n, 2, 2, 2, 2))
    dbar_w[0, 0, 1] = dbar_w[0, 1, 0] = np.array([[0.0, 1.0], [1.0, 0.0]])  # symmetric storage
    eps = np.array([[[0.0, 0.01], [0.01, 0.0]]])
    strain = growth.homogenized_strain(eps, np.zeros(n), dbar_w, None, np.zeros(n))
    assert np.allclose(strain[0], [[0.0, 0.02], [0.02, 0.0]], atol=1e-18)
