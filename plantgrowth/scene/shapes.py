"""Tissue shapes other than the rectangle: ``tissue.outline`` (a polygon) and ``tissue.mesh`` (a
gmsh .msh file), checked into a :class:`Shape` (docs/shapes.md, docs/model.md section 4).

Both lie in x1 >= 0, x2 >= 0 with at least one edge on the symmetry plane x2 = 0, so that the
bounding box is ``[0, width] x [0, height]``: the coarse grid covers it, and the fields run from
x1 = 0 to x1 = width as on the rectangle. Errors are :class:`InputError` naming the key.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from plantgrowth.base.errors import InputError, check_number
from plantgrowth.meshes import polygon
from plantgrowth.meshes.msh_file import PINNED, SYMMETRY, MshError, MshInfo, inspect_msh

MAX_POINTS = 500
"""Largest outline accepted (the simplicity test is O(n^2) in Python: 0.3 s at 500 points)."""


@dataclass(frozen=True)
class Shape:
    """A checked tissue shape.

    Attributes:
        key: the scene key that gave it, "tissue.outline" or "tissue.mesh".
        width, height: the bounding box [0, width] x [0, height].
        edges: loadable edge name -> reference length (the keys of ``[loads]``).
        symmetry: names of the edges on x2 = 0 (u2 = 0; they cannot be loaded).
        pin: the vertex where u1 = 0.
        triangles: the number of triangles of a mesh file (None for an outline: gmsh meshes it).
        normal_axes: every edge (loadable or on x2 = 0) -> the axis its normal points along (0:
            the edge is parallel to x2, 1: parallel to x1, None: inclined); a roller there holds
            that component of u (``[supports]``).
    """

    key: str
    width: float
    height: float
    edges: dict[str, float]
    symmetry: tuple[str, ...]
    pin: tuple[float, float]
    triangles: int | None = None
    normal_axes: dict[str, int | None] = field(default_factory=dict)


def _coordinate(key: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{key}: expected a number, got {value!r}")
    try:
        return check_number(key, value, 0.0, 1e6, low_open=False, high_open=False)
    except OverflowError:
        raise InputError(f"{key} is out of range: it must be finite and in [0, 1e6]") from None
    except InputError as e:
        raise InputError(f"{e} (the tissue lies in x1 >= 0 and x2 >= 0)") from None


def outline_points(value: object) -> tuple[tuple[float, float], ...]:
    """``tissue.outline`` as a tuple of points, each in [0, 1e6]^2 (InputError otherwise)."""
    key = "tissue.outline"
    if not isinstance(value, (list, tuple)) or not 3 <= len(value) <= MAX_POINTS:
        shown = f"{len(value)} points" if isinstance(value, (list, tuple)) else repr(value)[:40]
        raise InputError(
            f"{key}: expected an array of 3 to {MAX_POINTS} points [[x1, x2], ...], got {shown}"
        )
    points = []
    for k, p in enumerate(value):
        if not isinstance(p, (list, tuple)) or len(p) != 2:
            raise InputError(f"{key}[{k}]: expected a point [x1, x2], got {repr(p)[:40]}")
        points.append((_coordinate(f"{key}[{k}][0]", p[0]), _coordinate(f"{key}[{k}][1]", p[1])))
    return tuple(points)


def outline_shape(points: tuple[tuple[float, float], ...]) -> Shape:
    """The Shape of a simple polygon with an edge on x2 = 0; edge i (point i to i + 1) is the
    loadable edge ``edge<i>`` unless it lies on x2 = 0. Either orientation."""
    key = "tissue.outline"
    x = np.array(points, dtype=float)
    lengths = polygon.edge_lengths(x)
    if (short := np.flatnonzero(lengths == 0.0)).size:
        i = int(short[0])
        raise InputError(
            f"{key}[{i}] and {key}[{(i + 1) % len(x)}] are the same point: edge {i} has no length"
        )
    if crossing := polygon.first_crossing(x):
        raise InputError(
            f"{key}: edges {crossing[0]} and {crossing[1]} intersect: the outline must be a "
            "simple polygon (no self-intersection; edge i runs from point i to point i + 1)"
        )
    bottom = polygon.bottom_edges(x)
    if not bottom:
        raise InputError(
            f"{key}: no edge lies on x2 = 0: at least one edge (two consecutive points with "
            "x2 = 0) must lie on the symmetry plane x2 = 0"
        )
    names = [f"edge{i}" for i in range(len(x))]
    step = np.roll(x, -1, axis=0) - x  # edge i: exactly parallel to an axis, as x2 = 0 is
    axes = {names[i]: next((a for a in (0, 1) if step[i, a] == 0.0), None) for i in range(len(x))}
    return Shape(
        key, float(x[:, 0].max()), float(x[:, 1].max()),
        {names[i]: float(lengths[i]) for i in range(len(x)) if i not in bottom},
        tuple(names[i] for i in bottom), polygon.pin_point(x), normal_axes=axes,
    )  # fmt: skip


@functools.lru_cache(maxsize=8)
def _inspect(path: str, stamp: tuple[int, int]) -> MshInfo:
    del stamp  # part of the cache key only: a changed file is read again
    return inspect_msh(path)


def mesh_shape(path: str) -> Shape:
    """The Shape of a ``tissue.mesh`` file (an absolute path): MshInfo's checks, plus the
    ``symmetry`` group on x2 = 0 and the triangles in x1 >= 0, x2 >= 0."""
    key = f"tissue.mesh = {path!r}"
    file = Path(path)
    if file.suffix != ".msh":
        raise InputError(f"{key}: not a .msh file (a gmsh mesh, with the groups of docs/shapes.md)")
    if not file.is_file():
        raise InputError(f"{key}: file not found (a relative path is relative to the scene file)")
    try:
        stat = file.stat()
        info = _inspect(path, (stat.st_mtime_ns, stat.st_size))
    except MshError as e:
        raise InputError(f"{key}: {e}") from None
    if SYMMETRY not in info.curves:
        raise InputError(
            f"{key}: no curve group {SYMMETRY!r} (the edges on the symmetry plane x2 = 0); "
            f"curve groups: {', '.join(map(repr, info.curves)) or 'none'}"
        )
    _, _, low, high, _ = info.curves[SYMMETRY]
    size = max(*info.upper, 1.0)
    if max(abs(low), abs(high)) > 1e-12 * size:  # gmsh writes x2 = 0 exactly; 1e-12: round-off
        raise InputError(
            f"{key}: the curve group {SYMMETRY!r} is not on x2 = 0 "
            f"(its x2 spans [{low:g}, {high:g}])"
        )
    if min(info.lower) < -1e-12 * size:
        raise InputError(
            f"{key}: the mesh reaches (x1, x2) = ({info.lower[0]:g}, {info.lower[1]:g}): it must "
            "lie in x1 >= 0 and x2 >= 0 (above its symmetry plane x2 = 0)"
        )
    edges = {name: c[1] for name, c in info.curves.items() if name != SYMMETRY}
    return Shape(
        "tissue.mesh", info.upper[0], info.upper[1], edges, (SYMMETRY,), info.pinned,
        info.n_triangles, {name: c[4] for name, c in info.curves.items()},
    )  # fmt: skip


def unloadable(shape: Shape, edge: str) -> str:
    """Why ``loads.<edge>`` is refused on this shape ('' if it is a loadable edge)."""
    valid = ", ".join(shape.edges) or "none"
    if edge in shape.symmetry:
        return (
            f"loads.{edge}: edge {edge!r} lies on the symmetry plane x2 = 0 (u2 = 0, no "
            f"tangential traction) and cannot be loaded; loadable edges: {valid}"
        )
    if edge == PINNED:
        return f"loads.{edge}: {PINNED!r} is the pinned point, not an edge; loadable edges: {valid}"
    if edge not in shape.edges:
        return f"unknown key 'loads.{edge}' ({shape.key}: loadable edges: {valid})"
    return ""
