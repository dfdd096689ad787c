"""Each cell's shape against the scene's unit cell (issue 34): shape tensor, stretch, size.

Pure numpy. A cell's *shape tensor* is the area-normalised second moment of its mid-line
polygon P about its centroid c (exact polygon formula, :func:`second_moment`)::

    J(P) = (1/|P|) int_P (x - c) (x - c)^T dA,     J(M P) = M J(P) M^T  for any linear map M

The *stretch* of a cell is the symmetric positive definite F with ``F J0 F = J`` (J0: the unit
cell's hexagon, scaled by the tissue's reference scale ``delta``), the unique SPD solution

    F = J0^{-1/2} (J0^{1/2} J J0^{1/2})^{1/2} J0^{-1/2}

(:func:`stretch_between`; for an isotropic J0 = k I, F = (J / k)^{1/2}). For an affine image
``M H`` of the hexagon H with M symmetric positive definite, F = M exactly; a rotated hexagon
``R H`` gives F = I, as does any hexagon the unit cell's own symmetries map onto itself.

The *initial growth* keeps the area exactly: ``Fg0 = sqrt(|P| / (|H| det F)) F``, so that
``det Fg0 |H| = |P|`` and ``Fg0 J0 Fg0 = J`` up to a scalar factor (exactly for affine
images, where the factor is 1). Its unimodular part ``Fg0 / sqrt(det Fg0)`` carries the cell's
anisotropy and orientation; its ``sqrt(det Fg0)`` the cell's size relative to delta. The
*size* of a cell is ``sqrt(|P| / |Y|)``: the factor the unit cell's l1, l2 are scaled by to
the cell's area (|Y| the unit cell's area, in the scene's length unit per unit cell length).

A cell cut by the symmetry plane x2 = 0 (by default every cell with a side on it) is half of a
cell mirrored about it: its shape is that of the polygon united with its mirror image (centroid
on x2 = 0, area doubled). A cell that meets its own mirror image on x2 = 0 across a wall (a
generated tissue's cell beside the plane) is a whole cell: its own polygon's shape.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cell_polygons import CellPolygons, polygon_centroid
from .geometry_error import GeometryError
from .honeycomb import HoneycombCell, polygon_area


def second_moment(polygon: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(area, centroid (2,), S (2, 2)) of a counter-clockwise polygon (k, 2), with
    ``S = int_P (x - c)(x - c)^T dA`` by the exact vertex formulas (Green's theorem)::

        S_11 = (1/12) sum_i a_i (x_i^2 + x_i x_j + x_j^2),   a_i = x_i y_j - x_j y_i, j = i + 1
        S_22 = (1/12) sum_i a_i (y_i^2 + y_i y_j + y_j^2)
        S_12 = (1/24) sum_i a_i (x_i y_j + 2 x_i y_i + 2 x_j y_j + x_j y_i)

    evaluated on the vertices taken relative to the centroid."""
    p = np.asarray(polygon, dtype=float)
    centroid = polygon_centroid(p)
    return polygon_area(p), centroid, _moment_about(p - centroid)


def _moment_about(p: np.ndarray) -> np.ndarray:
    """``int_P x x^T dA`` of a CCW polygon about the origin."""
    q = np.roll(p, -1, axis=0)
    (x, y), (xn, yn) = p.T, q.T
    a = x * yn - xn * y
    s11 = np.sum(a * (x * x + x * xn + xn * xn)) / 12.0
    s22 = np.sum(a * (y * y + y * yn + yn * yn)) / 12.0
    s12 = np.sum(a * (x * yn + 2.0 * x * y + 2.0 * xn * yn + xn * y)) / 24.0
    return np.array([[s11, s12], [s12, s22]])


def mirrored_moment(polygon: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(area, centroid, S) of a polygon lying in x2 >= 0 united with its mirror image about
    x2 = 0: area 2|P|, centroid (c1, 0), ``S = 2 diag(int (x1 - c1)^2, int x2^2)`` (the mixed
    moment cancels between the halves)."""
    area, centroid, _ = second_moment(polygon)
    about = np.asarray(polygon, dtype=float) - [centroid[0], 0.0]
    S = _moment_about(about)
    return 2.0 * area, np.array([centroid[0], 0.0]), 2.0 * np.diag(np.diag(S))


def _spd_power(A: np.ndarray, power: float) -> np.ndarray:
    """A^power of symmetric positive definite matrices (..., 2, 2), by eigen-decomposition."""
    values, vectors = np.linalg.eigh(A)
    return np.einsum("...ik,...k,...jk->...ij", vectors, values**power, vectors)


def stretch_between(J0: np.ndarray, J: np.ndarray) -> np.ndarray:
    """The SPD F (..., 2, 2) with ``F J0 F = J``: ``J0^{-1/2} (J0^{1/2} J J0^{1/2})^{1/2}
    J0^{-1/2}`` (J0 (2, 2), J (..., 2, 2) symmetric positive definite)."""
    root, inverse_root = _spd_power(J0, 0.5), _spd_power(J0, -0.5)
    middle = _spd_power(root @ J @ root, 0.5)
    F = inverse_root @ middle @ inverse_root
    return 0.5 * (F + np.swapaxes(F, -1, -2))


def reference_tensor(cell: HoneycombCell) -> tuple[float, np.ndarray]:
    """(|H|, J0) of the unit cell's mid-line hexagon H (unscaled: J0 scales with delta^2)."""
    area, _, S = second_moment(cell.hexagon())
    return area, S / area


@dataclass(frozen=True)
class CellShapes:
    """Per-cell shape data of a tissue against its unit cell (module docstring).

    Attributes:
        centres: (n, 2) each cell's centre (the centroid; on x2 = 0 for a cut cell).
        areas: (n,) each cell's area (a cut cell's doubled: the whole mirrored cell).
        Fg0: (n, 2, 2) each cell's initial growth, SPD, ``det Fg0 = area / (delta^2 |Y|)``.
        sizes: (n,) ``sqrt(area / |Y|)``, the scale of l1, l2 that gives the cell's area.
        delta: the reference scale: the unit cell scaled by delta is the hexagon Fg0 maps.
    """

    centres: np.ndarray
    areas: np.ndarray
    Fg0: np.ndarray
    sizes: np.ndarray
    delta: float


def cell_shapes(
    cells: CellPolygons, cell: HoneycombCell, delta: float | None = None,
    cut: np.ndarray | None = None,
) -> CellShapes:  # fmt: skip
    """The shapes of ``cells`` against ``cell``'s hexagon scaled by ``delta`` (default: the
    scale that gives the tissue's mean cell area, so a regular honeycomb gets Fg0 = I); ``cut``
    (n,) the cells cut by the symmetry plane, mirrored about it (default: every cell with a
    side on it; a cell beside its own mirror image is a whole cell, not cut)."""
    if np.any(cells.vertices[:, 1] < -1e-9 * float(np.ptp(cells.vertices, axis=0).max())):
        raise GeometryError("tissue.cells: every vertex must lie in x2 >= 0 (x2 = 0 is the "
                            "symmetry plane)")  # fmt: skip
    on_plane = cells.on_symmetry_plane
    cut = on_plane if cut is None else np.asarray(cut, dtype=bool)
    if np.any(cut & ~on_plane):
        raise GeometryError(f"cell {cells.labels[np.flatnonzero(cut & ~on_plane)[0]]} is cut "
                            "but has no side on x2 = 0")  # fmt: skip
    moments = [(mirrored_moment if c else second_moment)(cells.polygon(i))
               for i, c in enumerate(cut)]  # fmt: skip
    areas = np.array([m[0] for m in moments])
    centres = np.array([m[1] for m in moments])
    J = np.array([m[2] / m[0] for m in moments])
    hexagon_area, J0 = reference_tensor(cell)
    if delta is None:
        delta = float(np.sqrt(areas.mean() / hexagon_area))
    if not (np.isfinite(delta) and delta > 0.0):
        raise GeometryError(f"cell scale delta = {delta!r} is invalid: it must be > 0")
    F = stretch_between(delta**2 * J0, J)
    ratio = areas / (delta**2 * hexagon_area)
    Fg0 = np.sqrt(ratio / np.linalg.det(F))[:, None, None] * F
    return CellShapes(centres, areas, Fg0, np.sqrt(areas / cell.area), delta)
