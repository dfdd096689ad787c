"""The fibre director and its mechanical feedback (docs/model.md, fibre-reinforced walls): pure
numpy, vectorised over a stack of growth units (macro: fine cells; micro: cells).

Angles are in **degrees**, anticlockwise from x1, as the scene's ``walls.fibre_angle``. A
director is an axis, ``a ~ a + 180``: every angle this module returns is reduced to the canonical
range (-90, 90] (:func:`reduce_angle`).

- The cue of a symmetric tensor Q (the stress sigma_hom or the strain eps_hom): its principal
  values q1 >= q2, the angle a_Q of q1's eigenvector and the anisotropy
  A = (q1 - q2) / (|q1| + |q2|) (:func:`cue`; closed forms of :mod:`plantgrowth.base.principal`,
  no eigen-solver).
- The director turns toward a_Q, ``da/dt = -(k A / 2) sin(2 (a - a_Q))``; over a step of length
  dt, with a_Q and A frozen at its start, exactly: ``tan(a_new - a_Q) = tan(a_old - a_Q)
  exp(-k A dt)`` (:func:`turn_director`).
- The summary statistics of the director field, collective over MPI (:func:`fibre_statistics`).
- The fibre part of the wall tensor in Voigt storage, for the pointwise stability checks
  (:func:`fibre_voigt`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from mpi4py import MPI

from plantgrowth.base import principal

CUE_FIELD = "cue_anisotropy"
"""The output field of the feedback's cue (macro: per fine cell; micro: per cell): its anisotropy
A, the factor of the turning rate k A."""


class Cue(NamedTuple):
    """The cue of a stack of symmetric 2x2 tensors Q (n, 2, 2), each entry (n,)."""

    q1: np.ndarray  # largest principal value
    q2: np.ndarray  # smallest principal value, q2 <= q1
    angle: np.ndarray  # a_Q: angle of q1's eigenvector, degrees in (-90, 90]
    anisotropy: np.ndarray  # A = (q1 - q2) / (|q1| + |q2|) in [0, 1]; 0 where q1 = q2 = 0


def reduce_angle(a: np.ndarray) -> np.ndarray:
    """An axis angle (degrees) in the canonical range (-90, 90]: ``90 - ((90 - a) mod 180)``,
    the one representative of ``a + 180 k``."""
    return 90.0 - np.mod(90.0 - np.asarray(a, dtype=float), 180.0)


def cue(Q: np.ndarray) -> Cue:
    """The cue of the symmetric parts of Q (n, 2, 2), with Q = [[a, b], [b, d]]:
    ``q1,2 = (a + d)/2 +- hypot((a - d)/2, b)``, ``a_Q = atan2(2 b, a - d) / 2`` (degrees, in
    (-90, 90]; 0 where Q is isotropic, where A = 0 makes it irrelevant) and
    ``A = (q1 - q2) / (|q1| + |q2|)`` (0 where q1 = q2 = 0)."""
    q1, q2 = principal.principal_values(Q)
    angle = reduce_angle(np.degrees(principal.principal_angle(Q)))
    return Cue(q1, q2, angle, principal.anisotropy(Q))


def turn_director(
    angle: np.ndarray, cue_angle: np.ndarray, cue_anisotropy: np.ndarray, rate: float, dt: float
) -> np.ndarray:
    """The director angle after one step of the feedback law
    ``da/dt = -(k A / 2) sin(2 (a - a_Q))`` (k = ``rate`` >= 0, dt >= 0; a_Q, A frozen over the
    step), solved exactly: with ``d = a_old - a_Q`` reduced to (-90, 90],
    ``tan(d_new) = tan(d) exp(-k A dt)``, ``a_new = a_Q + d_new`` reduced to (-90, 90].

    Unconditionally stable and monotone: |d_new| <= |d| with d's sign, so a never overshoots
    a_Q, whatever dt. Where ``k A dt = 0`` (an isotropic cue, k = 0 or dt = 0) the angle is
    returned unchanged (reduced). At d = 90 exactly, the unstable equilibrium (the director
    across the cue), the director stays, as the exact solution does: d is taken in degrees, so
    no round-off of pi/2 starts it turning; any other d, however close to 90, turns toward a_Q.
    All angles in degrees; arrays broadcast.
    """
    a_old = reduce_angle(angle)
    d = reduce_angle(a_old - np.asarray(cue_angle, dtype=float))
    factor = np.exp(-rate * np.asarray(cue_anisotropy, dtype=float) * dt)
    d_new = np.degrees(np.arctan(np.tan(np.radians(d)) * factor))
    d_new = np.where(d == 90.0, 90.0, d_new)  # tan(radians(90)) is 1.6e16, not infinite
    return np.where(factor == 1.0, a_old, reduce_angle(cue_angle + d_new))


def follow_cue(angle: np.ndarray, Q: np.ndarray, rate: float, dt: float) -> np.ndarray:
    """The director angles (n,) after one feedback step toward their cue tensors Q (n, 2, 2):
    :func:`turn_director` with the angle and anisotropy of :func:`cue`."""
    q = cue(Q)
    return turn_director(angle, q.angle, q.anisotropy, rate, dt)


def director(angle: np.ndarray) -> np.ndarray:
    """(n, 2) unit director m = (cos a, sin a) of the angles a (n,) in degrees."""
    radians = np.radians(np.asarray(angle, dtype=float))
    return np.stack([np.cos(radians), np.sin(radians)], axis=-1)


def fibre_voigt(
    stiffness: np.ndarray, director: np.ndarray, tangent: np.ndarray, Fg: np.ndarray
) -> np.ndarray:
    """(n, 3, 3) the fibre part ``E_f q (t_g x t_g x t_g x t_g)`` of the wall tensor C_w in
    Voigt storage with engineering shear (``S = C [E11, E22, 2 E12]``, the storage of
    :mod:`plantgrowth.models.stability`): ``E_f q v v^T`` with ``v = (t1^2, t2^2, t1 t2)`` of the
    grown tangent ``t_g = Fg t / |Fg t|`` and ``q = (m . t_g)^2``, since ``t_g . E t_g = v . e``.

    Args:
        stiffness: (n,) E_f.
        director: (n, 2) m, grown frame.
        tangent: (n, 2) t, the reference tangent of the wall's mid-line segment.
        Fg: (n, 2, 2) the growth tensor.
    """
    Ft = np.einsum("nij,nj->ni", Fg, tangent)
    tg = Ft / np.linalg.norm(Ft, axis=1)[:, None]
    q = np.einsum("ni,ni->n", director, tg) ** 2
    v = np.stack([tg[:, 0] ** 2, tg[:, 1] ** 2, tg[:, 0] * tg[:, 1]], axis=1)
    return (np.asarray(stiffness) * q)[:, None, None] * v[:, :, None] * v[:, None, :]


def fibre_statistics(angle: np.ndarray, weight: np.ndarray, comm: MPI.Comm) -> tuple[float, float]:
    """Collective: ``(fibre_order, fibre_angle_mean)`` of the director field, from this rank's
    owned units' angles (degrees) and weights (areas). With the area-weighted mean
    ``z = sum w exp(2 i a) / sum w`` over all ranks (the parts summed with allreduce):
    ``fibre_order = |z|`` in [0, 1] (1: all parallel; 0: e.g. two perpendicular families of
    equal area) and ``fibre_angle_mean = arg(z) / 2`` in degrees, in (-90, 90]; 0 where
    fibre_order <= :data:`plantgrowth.base.principal.ISOTROPIC`, which has no mean direction
    (so that round-off cannot give serial and mpirun runs different arbitrary angles)."""
    two_a = np.radians(2.0 * np.asarray(angle, dtype=float))
    w = np.asarray(weight, dtype=float)
    local = np.array([np.sum(w * np.cos(two_a)), np.sum(w * np.sin(two_a)), np.sum(w)])
    re, im, total = comm.allreduce(local, op=MPI.SUM)
    order = float(np.hypot(re, im) / total)
    if order <= principal.ISOTROPIC:
        return order, 0.0
    return order, float(reduce_angle(np.degrees(0.5 * np.arctan2(im + 0.0, re))))
