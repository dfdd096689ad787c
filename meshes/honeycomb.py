"""Honeycomb unit-cell geometry of docs/model.md section 2 (pure numpy, no meshing).

The cell is the mid-line hexagon A..F ("pointy-top") of the wall network; the void is that
hexagon offset inwards by the wall thickness ``w``. The lattice is spanned by
``b1 = (2c, 0)`` and ``b2 = (c, l1 + s)`` with ``c = l2 cos(theta)``, ``s = l2 sin(theta)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .geometry_error import GeometryError


def _check_finite_positive(name: str, value: float) -> None:
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        raise GeometryError(f"{name} must be a number, got {value!r}")
    if not math.isfinite(value) or value <= 0.0:
        raise GeometryError(f"{name} = {value!r} is invalid: it must be a finite number > 0")


def polygon_area(vertices: np.ndarray) -> float:
    """Signed area of a polygon (shoelace formula), positive when counter-clockwise."""
    x, y = vertices[:, 0], vertices[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def offset_convex_polygon(vertices: np.ndarray, distance: float) -> np.ndarray:
    """Intersection of the inward half-planes ``n_i . (p - v_i) >= distance`` of a CCW polygon.

    Sutherland-Hodgman clipping; edges that collapse are dropped, so the result is the true
    inward offset even when some sides vanish. Returns an (m, 2) CCW array, m = 0 if empty.
    """
    poly = vertices.copy()
    n = len(vertices)
    for i in range(n):
        p, q = vertices[i], vertices[(i + 1) % n]
        d = q - p
        normal = np.array([-d[1], d[0]]) / np.linalg.norm(d)
        side = (poly - p) @ normal - distance
        clipped = []
        for k in range(len(poly)):
            a, b = poly[k], poly[(k + 1) % len(poly)]
            sa, sb = side[k], side[(k + 1) % len(poly)]
            if sa >= 0.0:
                clipped.append(a)
            if (sa >= 0.0) != (sb >= 0.0):
                clipped.append(a + (b - a) * sa / (sa - sb))
        poly = np.array(clipped).reshape(-1, 2)
        if len(poly) == 0:
            return poly
    # merge vertices closer than a round-off multiple of the cell size
    tol = 1e-9 * float(np.ptp(vertices, axis=0).max())
    keep = np.linalg.norm(poly - np.roll(poly, -1, axis=0), axis=1) > tol
    return poly[keep]


def lattice_area(l1, l2, theta_deg):
    """``|Y| = 2 c (l1 + s)``, ``c = l2 cos(theta)``, ``s = l2 sin(theta)`` (docs/model.md
    section 2), for arrays (the fields' values; HoneycombCell.area for one cell)."""
    theta = np.radians(theta_deg)
    return 2.0 * l2 * np.cos(theta) * (l1 + l2 * np.sin(theta))


@dataclass(frozen=True)
class HoneycombCell:
    """Parameters of the periodic honeycomb cell, validated on construction.

    Attributes:
        l1: length of the walls parallel to x2.
        l2: length of the inclined walls.
        theta_deg: angle of the inclined walls to the x1 axis, in degrees, in (0, 90).
        w: thickness of one cell's own wall (a shared wall is 2w thick).
    """

    l1: float = 1.0
    l2: float = 1.0
    theta_deg: float = 30.0
    w: float = 0.05

    def __post_init__(self) -> None:
        _check_finite_positive("l1", self.l1)
        _check_finite_positive("l2", self.l2)
        _check_finite_positive("w", self.w)
        t = self.theta_deg
        if not isinstance(t, (int, float)) or not math.isfinite(t) or not 0.0 < t < 90.0:
            raise GeometryError(f"theta = {t!r} deg is invalid: it must lie in (0, 90) degrees")
        if self.w >= self.w_max:
            raise GeometryError(
                f"w = {self.w!r} leaves the cell no void: for l1 = {self.l1}, l2 = {self.l2}, "
                f"theta = {t} deg the wall thickness w must lie in (0, {self.w_max:.6g})"
            )

    @property
    def c(self) -> float:
        return self.l2 * math.cos(math.radians(self.theta_deg))

    @property
    def s(self) -> float:
        return self.l2 * math.sin(math.radians(self.theta_deg))

    @property
    def b1(self) -> np.ndarray:
        return np.array([2.0 * self.c, 0.0])

    @property
    def b2(self) -> np.ndarray:
        return np.array([self.c, self.l1 + self.s])

    @property
    def area(self) -> float:
        """|Y| = 2 c (l1 + s)."""
        return 2.0 * self.c * (self.l1 + self.s)

    @property
    def w_max(self) -> float:
        """Largest w that keeps a void: distance from the centre to the nearest side line."""
        return min(self.c, self.c * (self.s + 0.5 * self.l1) / self.l2)

    def hexagon(self) -> np.ndarray:
        """Mid-line hexagon vertices A, B, C, D, E, F (counter-clockwise), shape (6, 2)."""
        c, s, h = self.c, self.s, 0.5 * self.l1
        return np.array([[c, h], [0.0, h + s], [-c, h], [-c, -h], [0.0, -h - s], [c, -h]])

    def wall_tangents(self) -> np.ndarray:
        """Unit tangents of the three mid-line segment families, shape (3, 2): ``e2`` (CD, FA),
        ``(c, s)/l2`` (BC, EF) and ``(-c, s)/l2`` (AB, DE)."""
        c, s = self.c / self.l2, self.s / self.l2
        return np.array([[0.0, 1.0], [c, s], [-c, s]])

    def void(self) -> np.ndarray:
        """The void Y_c: the hexagon offset inwards by w (CCW vertices)."""
        return offset_convex_polygon(self.hexagon(), self.w)

    @property
    def phi_w(self) -> float:
        """Wall fraction |Y_w| / |Y|."""
        return 1.0 - polygon_area(self.void()) / self.area

    def lattice_coordinates(self, points: np.ndarray) -> np.ndarray:
        """Coordinates (a1, a2) of points in the basis (b1, b2); shape (n, 2)."""
        basis = np.column_stack([self.b1, self.b2])
        return np.linalg.solve(basis, np.asarray(points, dtype=float).T).T
