"""A tissue read from a polygon table (issue 34, docs/real_tissues.md).

JSON: ``{"pixel_size": 0.5, "cells": [{"id": 3, "vertices": [[x, y], ...]}, ...]}`` (pixel_size
optional); CSV: a header ``cell_id,x,y`` and one row per vertex, each cell's rows together and
in order. A polygon may repeat its first vertex at the end; clockwise ones are reversed.
Coordinates times the pixel size are the scene's (x1, x2), x2 up; the tissue must lie in
x2 >= 0. Vertices closer than :data:`SNAP` of the tissue's extent are one vertex, and a vertex
lying on a neighbour's side (closer than SNAP) is inserted into that side, so that neighbours
share their walls. A GeometryError names the file, the cell id and the fault: too few vertices,
a non-finite coordinate, a repeated vertex or id, a self-intersecting polygon, overlapping
cells, background enclosed by the tissue, a vertex below x2 = 0.
"""

from __future__ import annotations

import csv
import json
import math

import numpy as np
from shapely.geometry import LinearRing, Polygon
from shapely.ops import unary_union

from .cell_polygons import CellPolygons
from .geometry_error import GeometryError

SNAP = 1e-6
"""Vertex merging and side insertion tolerance, relative to the tissue's extent."""
OVERLAP = 1e-9
"""Overlap area (relative to the smaller cell's) above which two cells overlap."""


def _read_json(path: str, name: str) -> tuple[list, list, float | None]:
    try:
        with open(path, encoding="utf-8") as f:
            data = json.load(f)
    except (OSError, ValueError) as e:
        raise GeometryError(f"{name}: cannot be read as JSON: {e}") from None
    if not isinstance(data, dict) or not isinstance(data.get("cells"), list):
        raise GeometryError(
            f'{name}: expected {{"cells": [{{"id": 1, "vertices": [[x, y], ...]}}]}}'
        )
    unknown = set(data) - {"cells", "pixel_size"}
    if unknown:
        raise GeometryError(
            f"{name}: unknown key {sorted(unknown)[0]!r} (valid: cells, pixel_size)"
        )
    ids, loops = [], []
    for k, cell in enumerate(data["cells"]):
        if not isinstance(cell, dict) or set(cell) != {"id", "vertices"}:
            raise GeometryError(
                f'{name}: cells[{k}]: expected {{"id": 1, "vertices": [[x, y], ...]}}'
            )
        ids.append(cell["id"])
        loops.append(cell["vertices"])
    return ids, loops, data.get("pixel_size")


def _read_csv(path: str, name: str) -> tuple[list, list, None]:
    try:
        with open(path, encoding="utf-8", newline="") as f:
            rows = list(csv.reader(f))
    except (OSError, ValueError) as e:
        raise GeometryError(f"{name}: cannot be read as CSV: {e}") from None
    if not rows or [c.strip() for c in rows[0]] != ["cell_id", "x", "y"]:
        raise GeometryError(f"{name}: expected the header cell_id,x,y (one row per vertex)")
    ids: list = []
    loops: list = []
    for line, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        try:
            cell, x, y = int(row[0]), float(row[1]), float(row[2])
            if len(row) != 3:
                raise ValueError
        except (ValueError, IndexError):
            raise GeometryError(f"{name}: line {line}: expected cell_id,x,y, got {row!r}") from None
        if not ids or ids[-1] != cell:
            ids.append(cell)
            loops.append([])
        loops[-1].append([x, y])
    return ids, loops, None


def _loop(points: object, label: object, name: str) -> np.ndarray:
    """A cell's checked counter-clockwise (k, 2) loop, the closing repeat dropped."""
    where = f"{name}: cell {label}"
    try:
        p = np.array(points, dtype=float)
    except (TypeError, ValueError):
        raise GeometryError(f"{where}: vertices must be [x, y] pairs of numbers") from None
    if p.ndim != 2 or p.shape[1] != 2:
        raise GeometryError(f"{where}: vertices must be [x, y] pairs of numbers")
    if not np.isfinite(p).all():
        raise GeometryError(f"{where}: a vertex is not finite ({p[~np.isfinite(p).all(1)][0]})")
    if len(p) > 1 and np.array_equal(p[0], p[-1]):
        p = p[:-1]
    if len(p) < 3:
        raise GeometryError(f"{where}: {len(p)} vertices: a polygon needs at least 3")
    if len(np.unique(p, axis=0)) < len(p):
        raise GeometryError(f"{where}: a vertex is repeated")
    if not LinearRing(p).is_simple:
        raise GeometryError(f"{where}: its polygon intersects itself")
    area = Polygon(p).area
    if area <= 0.0:
        raise GeometryError(f"{where}: its polygon has no area")
    return p if LinearRing(p).is_ccw else p[::-1]


def _insert_hanging(tissue: CellPolygons, tol: float) -> list[np.ndarray]:
    """Each cell's loop with the vertices that lie on its sides (other cells' corners)
    inserted in order along the side."""
    v = tissue.vertices
    loops = []
    for loop in tissue.cells:
        out = []
        for a, b in zip(loop, np.roll(loop, -1), strict=True):
            out.append(a)
            d = v[b] - v[a]
            t = (v - v[a]) @ d / (d @ d)
            gap = np.abs((v[:, 0] - v[a, 0]) * d[1] - (v[:, 1] - v[a, 1]) * d[0]) / math.sqrt(d @ d)
            on = np.flatnonzero((gap < tol) & (t > 0.0) & (t < 1.0))
            on = on[(on != a) & (on != b)]  # t of an end may be a rounding off 0 or 1
            out.extend(on[np.argsort(t[on])].tolist())
        loops.append(v[out])
    return loops


def table_cells(path: str, pixel_size: float | None, name: str) -> CellPolygons:
    """The cells of a polygon table (.json or .csv), in the scene's length unit."""
    ids, raw, own = (_read_json if path.lower().endswith(".json") else _read_csv)(path, name)
    if own is not None and (isinstance(own, bool) or not isinstance(own, (int, float))
                            or not 0.0 < own < math.inf):  # fmt: skip
        raise GeometryError(f"{name}: pixel_size = {own!r} must be a number > 0")
    if own is not None and pixel_size is not None and own != pixel_size:
        raise GeometryError(
            f"{name}: pixel_size = {own!r} in the file, but tissue.pixel_size = {pixel_size!r}"
        )
    scale = own if own is not None else (pixel_size if pixel_size is not None else 1.0)
    if not ids:
        raise GeometryError(f"{name}: no cells")
    seen: set[int] = set()
    for label in ids:
        if isinstance(label, bool) or not isinstance(label, int):
            raise GeometryError(f"{name}: cell id {label!r}: ids must be integers")
        if label in seen:
            raise GeometryError(f"{name}: cell id {label} is repeated: one polygon per cell")
        seen.add(label)
    loops = [_loop(p, label, name) * scale for p, label in zip(raw, ids, strict=True)]
    low = min(float(p[:, 1].min()) for p in loops)
    if low < 0.0:
        label = next(i for i, p in zip(ids, loops, strict=True) if p[:, 1].min() == low)
        raise GeometryError(
            f"{name}: cell {label} reaches x2 = {low:g} < 0: the tissue must lie in x2 >= 0 "
            "(translate the table; x2 = 0 is the symmetry plane)"
        )
    stacked = np.vstack(loops)
    tol = SNAP * max(float(np.ptp(stacked, axis=0).max()), 1e-300)
    check_overlaps([Polygon(p) for p in loops], ids, name)
    snapped = CellPolygons.from_loops(loops, labels=np.array(ids), tol=tol)
    tissue = CellPolygons.from_loops(_insert_hanging(snapped, tol), labels=np.array(ids), tol=tol)
    union = unary_union([Polygon(tissue.polygon(i)) for i in range(tissue.n_cells)])
    for part in getattr(union, "geoms", [union]):
        if part.interiors:
            x, y = part.interiors[0].coords[0]
            raise GeometryError(
                f"{name}: background enclosed by the tissue (a hole between cells, at "
                f"({x:g}, {y:g})): add the missing cell or open the hole to the outside"
            )
    try:
        tissue.check()
    except GeometryError as e:
        raise GeometryError(f"{name}: {e}") from None
    return tissue


def check_overlaps(polygons: list[Polygon], ids: list, name: str) -> None:
    """A GeometryError if two cells share more than OVERLAP of the smaller one's area (their
    bounding boxes compared first)."""
    box = np.array([p.bounds for p in polygons])
    for k, p in enumerate(polygons):
        near = np.flatnonzero(
            (box[k + 1 :, 0] < box[k, 2])
            & (box[k + 1 :, 2] > box[k, 0])
            & (box[k + 1 :, 1] < box[k, 3])
            & (box[k + 1 :, 3] > box[k, 1])
        )
        for m in near + k + 1:
            shared = p.intersection(polygons[m]).area
            if shared > OVERLAP * min(p.area, polygons[m].area):
                raise GeometryError(
                    f"{name}: cells {ids[k]} and {ids[m]} overlap (by {shared:.3g}): cells may "
                    "share walls, not areas"
                )
