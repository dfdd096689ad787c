"""Small 2D tensor helpers: the paper's six-component storage and orthotropic moduli.

Storage order (paper appendix, docs/model.md section 1): {E1111, E2222, E1122, E1212, E1112, E2212}.
"""

from __future__ import annotations

import numpy as np

from plantgrowth.forms.elasticity import lame_parameters

VOIGT_PAIRS = (
    ((0, 0), (0, 0)),
    ((1, 1), (1, 1)),
    ((0, 0), (1, 1)),
    ((0, 1), (0, 1)),
    ((0, 0), (0, 1)),
    ((1, 1), (0, 1)),
)
VOIGT_NAMES = ("E1111", "E2222", "E1122", "E1212", "E1112", "E2212")
VOIGT_POSITIONS = ((0, 0), (1, 1), (0, 1), (2, 2), (0, 2), (1, 2))
"""Position of each of the six components in the 3x3 Voigt matrix (see :func:`voigt_matrix`)."""


def unit_strain(i: int, j: int, sym: bool = True) -> np.ndarray:
    """``b_ij = (e_i x e_j + e_j x e_i) / 2`` (or ``e_i x e_j`` when ``sym`` is False)."""
    b = np.zeros((2, 2))
    b[i, j] = 1.0
    return 0.5 * (b + b.T) if sym else b


def orthotropic_moduli(E6: np.ndarray) -> dict[str, float]:
    """E1, E2, nu12, G12 from the six components (paper appendix A)."""
    E1111, E2222, E1122, E1212 = E6[:4]
    return {
        "E1": E1111 - E1122**2 / E2222,
        "E2": E2222 - E1122**2 / E1111,
        "nu12": E1122 / E2222,
        "G12": E1212,
    }


def isotropic_tensor(E: float, nu: float) -> np.ndarray:
    """(2, 2, 2, 2) plane-stress wall tensor with mu = E/(2(1+nu)), lam = E nu/(1-nu^2)."""
    mu, lam = lame_parameters(E, nu)
    I = np.eye(2)
    return lam * np.einsum("ij,kl->ijkl", I, I) + mu * (
        np.einsum("ik,jl->ijkl", I, I) + np.einsum("il,jk->ijkl", I, I)
    )


def director(angle_deg: float) -> np.ndarray:
    """The fibre director ``m = (cos a, sin a)``, a in degrees anticlockwise from x1."""
    a = np.radians(angle_deg)
    return np.array([np.cos(a), np.sin(a)])


def fibre_tensor(Fg: np.ndarray, t: np.ndarray, m: np.ndarray, stiffness: float) -> np.ndarray:
    """(2, 2, 2, 2) fibre part ``E_f q t_g x t_g x t_g x t_g`` of the wall tensor, with the grown
    tangent ``t_g = Fg t / |Fg t|`` and ``q = (m . t_g)^2`` (docs/model.md, "Fibre-reinforced
    walls"); ``stiffness`` is E_f."""
    tg = Fg @ t
    tg = tg / np.linalg.norm(tg)
    q = float(m @ tg) ** 2
    return stiffness * q * np.einsum("i,j,k,l->ijkl", tg, tg, tg, tg)


def voigt_matrix(E_hom: np.ndarray) -> np.ndarray:
    """Voigt matrix C, ``(s11, s22, s12) = C (e11, e22, 2 e12)``, of (..., 2, 2, 2, 2) tensors."""
    idx = ((0, 0), (1, 1), (0, 1))
    return np.stack(
        [np.stack([E_hom[..., i, j, k, l] for k, l in idx], axis=-1) for i, j in idx], axis=-2
    )


def voigt_vector(e: np.ndarray) -> np.ndarray:
    """``(e11, e22, 2 e12)`` of (..., 2, 2) symmetric tensors."""
    return np.stack([e[..., 0, 0], e[..., 1, 1], 2.0 * e[..., 0, 1]], axis=-1)


def symmetric_components(T: np.ndarray) -> list[float]:
    """``[T11, T22, T12]`` of a symmetric 2x2 tensor, as floats (the CLI's JSON lists)."""
    return [float(T[0, 0]), float(T[1, 1]), float(T[0, 1])]


def from_voigt_stress(s: np.ndarray) -> np.ndarray:
    """(..., 2, 2) tensors from stress Voigt vectors ``(s11, s22, s12)``."""
    return np.stack(
        [np.stack([s[..., 0], s[..., 2]], -1), np.stack([s[..., 2], s[..., 1]], -1)], -2
    )


def tensor_from_voigt(C: np.ndarray) -> np.ndarray:
    """(..., 2, 2, 2, 2) tensors with minor symmetries from Voigt matrices (inverse of
    :func:`voigt_matrix`)."""
    idx = ((0, 0), (1, 1), (0, 1))
    E = np.zeros((*C.shape[:-2], 2, 2, 2, 2))
    for I, (i, j) in enumerate(idx):
        for J, (k, l) in enumerate(idx):
            for a, b, c, d in ((i, j, k, l), (j, i, k, l), (i, j, l, k), (j, i, l, k)):
                E[..., a, b, c, d] = C[..., I, J]
    return E


def rotate2(R: np.ndarray, T: np.ndarray) -> np.ndarray:
    """``R T R^T`` for stacks (n, 2, 2) of rotations and 2nd-order tensors."""
    return R @ T @ np.swapaxes(R, 1, 2)


def voigt_rotation(R: np.ndarray) -> np.ndarray:
    """(n, 3, 3) the stress transformation of rotations R = [[c, -s], [s, c]] (n, 2, 2),
    ``T = [[c^2, s^2, -2cs], [s^2, c^2, 2cs], [cs, -cs, c^2 - s^2]]``: the tensor components
    (a11, a22, a12) of a symmetric A become those of ``R A R^T`` (the engineering strain's
    transformation is T^-T)."""
    c, s = R[:, 0, 0], R[:, 1, 0]
    cc, ss, cs = c * c, s * s, c * s
    T = np.empty((len(R), 3, 3))
    T[:, 0, 0], T[:, 0, 1], T[:, 0, 2] = cc, ss, -2.0 * cs
    T[:, 1, 0], T[:, 1, 1], T[:, 1, 2] = ss, cc, 2.0 * cs
    T[:, 2, 0], T[:, 2, 1], T[:, 2, 2] = cs, -cs, cc - ss
    return T


def rotate_voigt(R: np.ndarray, C: np.ndarray, T: np.ndarray | None = None) -> np.ndarray:
    """Voigt matrices (n, 3, 3) of :func:`rotate4` applied to the tensors of ``C``, directly:
    ``T C T^T`` with T the stress transformation of R (:func:`voigt_rotation`, or given)."""
    T = voigt_rotation(R) if T is None else T
    return T @ C @ np.swapaxes(T, 1, 2)


SYMMETRIC2 = np.array([0, 3, 1])
"""Positions of (a11, a22, a12) in a flattened 2 x 2 tensor."""
FULL2 = np.array([0, 2, 2, 1])
"""Positions of a11, a12, a21, a22 among (a11, a22, a12)."""
SYMMETRIC4 = (SYMMETRIC2[:, None] * 4 + SYMMETRIC2[None, :]).ravel()
"""Positions of the 3 x 3 tensor components of a flattened 2 x 2 x 2 x 2 tensor with both minor
symmetries (:data:`SYMMETRIC2` on each index pair)."""
FULL4 = (FULL2[:, None] * 3 + FULL2[None, :]).ravel()
"""Positions of the 16 entries among the flattened 3 x 3 components (:data:`FULL2` on each)."""


def rotate_symmetric2(T: np.ndarray, A: np.ndarray) -> np.ndarray:
    """:func:`rotate2` of symmetric (n, 2, 2) tensors A (their (1, 2) entries taken), as the
    stress transformation T (:func:`voigt_rotation`) of their three components: a matrix
    times a vector instead of two 2 x 2 products."""
    n = len(A)  # np.take: columns taken 5 times as fast as by fancy indexing
    turned = (T @ np.take(A.reshape(n, 4), SYMMETRIC2, axis=1)[:, :, None])[:, :, 0]
    return np.take(turned, FULL2, axis=1).reshape(n, 2, 2)


def rotate_symmetric4(T: np.ndarray, D: np.ndarray) -> np.ndarray:
    """:func:`rotate4` of (n, 2, 2, 2, 2) tensors with both minor symmetries (D_ijkl =
    D_jikl = D_ijlk; their entries with i <= j, k <= l taken), as ``T D3 T^T`` of their 3 x 3
    matrices of tensor components (:func:`voigt_rotation`'s T on each index pair): two 3 x 3
    products instead of two 4 x 4 ones and no 4 x 4 Kronecker matrix."""
    n = len(D)
    D3 = np.take(D.reshape(n, 16), SYMMETRIC4, axis=1).reshape(n, 3, 3)
    turned = (T @ D3 @ np.swapaxes(T, 1, 2)).reshape(n, 9)
    return np.take(turned, FULL4, axis=1).reshape(n, 2, 2, 2, 2)


def rotate4(R: np.ndarray, T: np.ndarray) -> np.ndarray:
    """``T'_ijkl = R_ia R_jb R_kc R_ld T_abcd`` for stacks (n, ...) of 4th-order tensors, as
    ``Q T Q^T`` with ``Q = R (x) R`` on the index pairs (ij), (kl): two batched 4 x 4 products."""
    n = len(R)
    Q = (R[:, :, None, :, None] * R[:, None, :, None, :]).reshape(n, 4, 4)
    return (Q @ T.reshape(n, 4, 4) @ np.swapaxes(Q, 1, 2)).reshape(n, 2, 2, 2, 2)


def _trigonometric_form(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """q = tr A / 3, p = |A - q I| / sqrt(6) and ``phi = acos(det((A - q I) / p) / 2) / 3`` of
    symmetric (n, 3, 3) matrices: their eigenvalues are ``q + 2 p cos(phi + 2 pi k / 3)``."""
    q = np.trace(A, axis1=1, axis2=2) / 3.0
    off = A[:, 0, 1] ** 2 + A[:, 0, 2] ** 2 + A[:, 1, 2] ** 2
    diag = (A[:, 0, 0] - q) ** 2 + (A[:, 1, 1] - q) ** 2 + (A[:, 2, 2] - q) ** 2
    p = np.sqrt((diag + 2.0 * off) / 6.0)
    safe = np.where(p > 0.0, p, 1.0)
    a, d, f = ((A[:, k, k] - q) / safe for k in range(3))  # B = (A - q I) / p, symmetric
    b, c, e = A[:, 0, 1] / safe, A[:, 0, 2] / safe, A[:, 1, 2] / safe
    r = 0.5 * (a * (d * f - e * e) - b * (b * f - e * c) + c * (b * e - d * c))  # det(B) / 2
    return q, p, np.arccos(np.clip(r, -1.0, 1.0)) / 3.0


def smallest_eigenvalue_sym3(A: np.ndarray) -> np.ndarray:
    """(n,) the smallest eigenvalue of symmetric (n, 3, 3) matrices (the trigonometric closed
    form, :func:`_trigonometric_form`: ``q + 2 p cos(phi + 2 pi / 3)``)."""
    q, p, angle = _trigonometric_form(A)
    return np.where(p > 0.0, q + 2.0 * p * np.cos(angle + 2.0 * np.pi / 3.0), q)


def extreme_eigenvalues_sym3(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(n,) the smallest and the largest eigenvalue of symmetric (n, 3, 3) matrices (closed
    form: :func:`smallest_eigenvalue_sym3` and ``q + 2 p cos(phi)``; a few times faster than
    numpy's batched eigensolver on the per-cell stacks)."""
    q, p, angle = _trigonometric_form(A)
    smallest = np.where(p > 0.0, q + 2.0 * p * np.cos(angle + 2.0 * np.pi / 3.0), q)
    return smallest, np.where(p > 0.0, q + 2.0 * p * np.cos(angle), q)


def det2(A: np.ndarray) -> np.ndarray:
    """(...,) ``A11 A22 - A12 A21`` of (..., 2, 2) matrices (closed form: a few times faster
    than np.linalg.det's batched LU on the per-cell stacks of every step)."""
    return A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] * A[..., 1, 0]


def inv2(A: np.ndarray) -> np.ndarray:
    """(..., 2, 2) inverses ``[[A22, -A12], [-A21, A11]] / det A`` (closed form, as :func:`det2`;
    a singular matrix gives inf or NaN entries rather than an error)."""
    adjugate = np.stack(
        [np.stack([A[..., 1, 1], -A[..., 0, 1]], -1), np.stack([-A[..., 1, 0], A[..., 0, 0]], -1)],
        -2,
    )
    return adjugate / det2(A)[..., None, None]
