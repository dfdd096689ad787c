"""Principal values and directions of symmetric 2D tensors (growth rate G, stress sigma_hom).

For T with symmetric part [[a, b], [b, d]], ``m = (a + d) / 2`` and ``r = hypot((a - d) / 2, b)``
give the principal values ``t1 = m + r >= t2 = m - r`` and the direction of t1,
``(cos phi, sin phi)`` with ``phi = atan2(2 b, a - d) / 2``. Closed forms, vectorised over the
leading axes: no eigen-solver, whose eigenvector signs would differ between runs.

Conventions (docs/outputs.md):
- anisotropy = (t1 - t2) / (|t1| + |t2|) = r / max(|m|, r), in [0, 1]: the issue's
  (g1 - g2) / (g1 + g2) whenever both rates are >= 0 (the growth law's positive part makes them
  so unless the clamp M cuts an off-diagonal entry), 1 when one rate is > 0 and the other < 0
  (growth one way, shrinkage the other), and 0 when t1 = t2 = 0;
- direction: the unit vector of t1 with x1 component >= 0 (an axis has no sign; this picks one),
  pointing up (x2 > 0) when it is vertical to within ``AXIS_TOLERANCE``; the zero vector where
  the tensor is isotropic (anisotropy <= ``ISOTROPIC``), which has no preferred direction.
"""

from __future__ import annotations

import numpy as np

ISOTROPIC = 1e-6
"""Anisotropy at or below which a tensor counts as isotropic (direction = zero vector): far
above the round-off of an exactly isotropic state (measured ~1e-13 on the reference scene) and
far below anything a biologist would call anisotropic."""
AXIS_TOLERANCE = 1e-9
"""|x1 component| below which a direction counts as vertical and is made to point up, so that
round-off (serial versus mpirun) cannot flip it between (0, 1) and (0, -1)."""


def _parts(T: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(m, r, a - d, 2 b) of the symmetric part of T (..., 2, 2)."""
    T = np.asarray(T, dtype=float)
    a, d = T[..., 0, 0], T[..., 1, 1]
    b = 0.5 * (T[..., 0, 1] + T[..., 1, 0])
    return 0.5 * (a + d), np.hypot(0.5 * (a - d), b), a - d, 2.0 * b


def principal_values(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t1, t2), t1 >= t2, of the symmetric part of T (..., 2, 2)."""
    m, r, _, _ = _parts(T)
    return m + r, m - r


def trace(T: np.ndarray) -> np.ndarray:
    """tr T = t1 + t2 (for G: the areal growth rate, d ln(det Fg) / dt)."""
    T = np.asarray(T, dtype=float)
    return T[..., 0, 0] + T[..., 1, 1]


def anisotropy(T: np.ndarray) -> np.ndarray:
    """(t1 - t2) / (|t1| + |t2|) = r / max(|m|, r), in [0, 1]; 0 where t1 = t2 = 0."""
    m, r, _, _ = _parts(T)
    scale = np.maximum(np.abs(m), r)
    return np.divide(r, scale, out=np.zeros_like(r), where=scale > 0.0)


def principal_angle(T: np.ndarray) -> np.ndarray:
    """phi = atan2(2 b, a - d) / 2 in (-pi/2, pi/2]: the angle (radians, from x1) of the largest
    principal value's direction; 0 where T is isotropic."""
    _, _, diff, two_b = _parts(T)
    return 0.5 * np.arctan2(two_b + 0.0, diff)  # + 0.0: -0.0 -> 0.0, so atan2 never gives -pi


def principal_direction(T: np.ndarray) -> np.ndarray:
    """(..., 2) unit vector of the largest principal value (x1 >= 0; vertical: pointing up);
    the zero vector where T is isotropic (:data:`ISOTROPIC`)."""
    phi = principal_angle(T)
    direction = np.stack([np.cos(phi), np.sin(phi)], axis=-1)
    vertical = direction[..., 0] <= AXIS_TOLERANCE
    direction[..., 1] = np.where(vertical, np.abs(direction[..., 1]), direction[..., 1])
    return np.where((anisotropy(T) > ISOTROPIC)[..., None], direction, 0.0)
