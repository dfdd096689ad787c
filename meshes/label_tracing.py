"""A checked label image traced into cells with shared walls (issue 34, docs/real_tissues.md).

On the graph of pixel corners (the image padded with background):

1. Boundary segments: the pixel sides between two different labels, each with its label pair.
2. Walls: each pair's segments merged (shapely ``linemerge``) into polylines, which end at the
   junctions, the corners whose 2 x 2 pixels hold >= 3 labels (background counted): there each
   pair's boundary ends, since the checks leave no cell touching itself across a corner (a cell
   with background all round is one closed polyline). Each polyline is
   simplified by Douglas-Peucker with tolerance :data:`SIMPLIFY_PIXELS`, its ends kept.
3. Tiny walls: a wall shorter than :data:`COLLAPSE_PIXELS` (simplified) is removed and its two
   junctions merged into one (at their mean): a corner where four cells meet, or a three-way
   junction that the pixels split into two.
4. Cells: each cell's walls, run with the cell on their left, joined end to start into one
   counter-clockwise loop; neighbours thus share their wall's vertices exactly.

Coordinates: a corner at image column j, row i is ``(j, n_rows - i) * pixel_size``: the row axis
is flipped so that x2 points up, and the image's lower-left corner is the origin (x2 >= 0).
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np
from shapely.geometry import LinearRing, LineString, MultiLineString, Polygon
from shapely.ops import linemerge

from .cell_polygons import CellPolygons
from .geometry_error import GeometryError
from .polygon_table import check_overlaps

SIMPLIFY_PIXELS = 1.5
"""Douglas-Peucker tolerance of a wall, in pixels: the corners of the staircase of pixel sides
and its end junctions are within half a pixel's diagonal (0.71) of the straight wall they
sample, so within 1.41 of the chord between the ends: a straight wall becomes one segment
(at 0.5 or 1.0 the staircase stays and perimeters come out 5-20 pixels too long)."""
COLLAPSE_PIXELS = 2.0
"""Walls shorter than this (simplified, in pixels) are collapsed into a point."""


def _segments(padded: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every pixel side between two labels: (n, 2, 2) corner (row, column) pairs, directed
    so that the first label of the (n, 2) label pairs lies on the left (x2 up)."""
    above, below = padded[:-1, :], padded[1:, :]
    i, j = np.nonzero(above != below)  # horizontal sides at corner row i + 1
    horizontal = np.stack([np.column_stack([i + 1, j]), np.column_stack([i + 1, j + 1])], 1)
    h_labels = np.column_stack([above[i, j], below[i, j]])  # run +x1: the pixel above on the left
    left, right = padded[:, :-1], padded[:, 1:]
    i, j = np.nonzero(left != right)  # vertical sides at corner column j + 1
    vertical = np.stack([np.column_stack([i, j + 1]), np.column_stack([i + 1, j + 1])], 1)
    v_labels = np.column_stack([right[i, j], left[i, j]])  # run down (-x2): the right on the left
    return np.concatenate([horizontal, vertical]), np.concatenate([h_labels, v_labels])


def _walls(padded: np.ndarray) -> list[tuple[int, int, np.ndarray]]:
    """(left label, right label, (k, 2) corner points) for every wall between junctions."""
    segments, labels = _segments(padded)
    by_pair: dict[tuple[int, int], list] = defaultdict(list)
    for seg, (a, b) in zip(segments, labels, strict=True):
        by_pair[(a, b) if a < b else (b, a)].append(seg if a < b else seg[::-1])
    walls = []
    for (a, b), segs in by_pair.items():
        merged = linemerge(MultiLineString([s.tolist() for s in segs]))
        lines = merged.geoms if hasattr(merged, "geoms") else [merged]
        for line in lines:
            points = np.asarray(line.coords)
            if _left_label(padded, points[0], points[1] - points[0]) != a:  # linemerge turned it
                points = points[::-1]
            walls.append((int(a), int(b), points))
    return walls


def _left_label(padded: np.ndarray, start: np.ndarray, step: np.ndarray) -> int:
    """The label on the left (x2 up) of the unit pixel side from corner ``start`` along
    ``step`` (row, column)."""
    i, j = int(start[0]), int(start[1])
    if step[0] == 0:  # horizontal: +column has the pixel above on its left
        return int(padded[i - 1, j] if step[1] > 0 else padded[i, j - 1])
    return int(padded[i, j] if step[0] > 0 else padded[i - 1, j - 1])  # down: the right pixel


def trace_cells(
    labels: np.ndarray,
    pixel_size: float,
    simplify: float = SIMPLIFY_PIXELS,
    collapse: float = COLLAPSE_PIXELS,
) -> CellPolygons:
    """The cells of a checked label image (meshes/label_checks.py), in the scene's unit."""
    padded = np.pad(labels, 1, constant_values=0)
    walls = [(a, b, np.asarray(LineString(p).simplify(simplify, preserve_topology=False).coords))
             for a, b, p in _walls(padded)]  # fmt: skip
    # collapse the short walls between two junctions: union-find over their end points
    parent: dict[tuple[float, float], tuple[float, float]] = {}

    def root(p: tuple[float, float]) -> tuple[float, float]:
        while parent.get(p, p) != p:
            p = parent[p]
        return p

    kept = []
    for a, b, p in walls:
        ends = (tuple(p[0]), tuple(p[-1]))
        if ends[0] != ends[1] and np.linalg.norm(np.diff(p, axis=0), axis=1).sum() < collapse:
            parent[root(ends[1])] = root(ends[0])
        else:
            kept.append((a, b, p))
    groups: dict[tuple[float, float], list] = defaultdict(list)
    for p in list(parent):
        groups[root(p)].append(p)
    moved = {p: np.mean(members + [r], axis=0) for r, members in groups.items() for p in
             members + [r]}  # fmt: skip
    loops = _cell_loops(kept, moved)
    n_rows = labels.shape[0]
    order = sorted(loops)
    xy = [
        np.column_stack([loops[c][:, 1] - 1.0, n_rows - (loops[c][:, 0] - 1.0)]) * pixel_size
        for c in order
    ]
    for label, p in zip(order, xy, strict=True):
        if len(p) < 3 or not LinearRing(p).is_simple:
            raise GeometryError(
                f"cell {label}: its traced outline ({len(p)} vertices) intersects itself or has "
                f"no area: a cell thinner than the simplification tolerance {simplify:g} pixels?"
            )
    check_overlaps([Polygon(p) for p in xy], order, "the traced cells")
    return CellPolygons.from_loops(xy, labels=np.array(order))


def _cell_loops(walls: list, moved: dict) -> dict[int, np.ndarray]:
    """Each cell's counter-clockwise loop of corner points, its walls joined end to start."""
    runs: dict[int, dict[tuple, np.ndarray]] = defaultdict(dict)
    for a, b, p in walls:
        p = np.array([moved.get(tuple(q), q) for q in p])
        for label, run in ((a, p), (b, p[::-1])):
            if label != 0 and tuple(run[0]) in runs[label]:
                raise GeometryError(
                    f"cell {label}: its outline touches itself once the walls shorter than "
                    f"{COLLAPSE_PIXELS:g} pixels are collapsed (a cell about that thin)"
                )
            if label != 0:
                runs[label][tuple(run[0])] = run
    loops = {}
    for label, by_start in runs.items():
        start = point = next(iter(by_start))
        parts = []
        while not parts or point != start:
            if point not in by_start or len(parts) == len(by_start):
                raise GeometryError(f"cell {label}: its walls do not close into one loop")
            parts.append(by_start[point][:-1])
            point = tuple(by_start[point][-1])
        if len(parts) != len(by_start):
            raise GeometryError(f"cell {label}: its walls make more than one loop")
        loop = np.concatenate(parts)
        keep = np.linalg.norm(loop - np.roll(loop, -1, axis=0), axis=1) > 0.0
        loops[label] = loop[keep]
    return loops
