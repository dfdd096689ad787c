"""A tissue given as a simple polygon (``tissue.outline``) and its fine mesh, with gmsh.

Pure geometry (orientation, simplicity, edges on the symmetry plane x2 = 0) and the mesh builder.
Edge i runs from point i to point i + 1 (the last one back to point 0), in the order given;
its boundary facets carry the tag ``i + 1`` (:func:`edge_tag`). gmsh runs on ``model_rank``
only; the mesh is distributed over ``comm``.
gmsh (and dolfinx's gmshio, which imports it) is imported by the functions that mesh, through
:func:`gmsh_api.gmsh_api`: its 0.35-0.45 s are paid only when a mesh is built.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from .gmsh_api import gmsh_api


def edge_tag(i: int) -> int:
    """Facet tag of edge i of an outline mesh."""
    return i + 1


def edge_lengths(points: np.ndarray) -> np.ndarray:
    """Length of each edge i (point i to point i + 1)."""
    return np.linalg.norm(np.roll(points, -1, axis=0) - points, axis=1)


def _orientation(a: np.ndarray, b: np.ndarray, c: np.ndarray, tol: float) -> int:
    cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    return 0 if abs(cross) <= tol else (1 if cross > 0 else -1)


def _on_segment(a: np.ndarray, b: np.ndarray, p: np.ndarray, tol: float) -> bool:
    return bool(np.all(np.minimum(a, b) - tol <= p) and np.all(p <= np.maximum(a, b) + tol))


def _segments_meet(a, b, c, d, tol: float, area_tol: float) -> bool:
    """Closed segments ab and cd share a point (collinear overlaps included)."""
    o1, o2 = _orientation(a, b, c, area_tol), _orientation(a, b, d, area_tol)
    o3, o4 = _orientation(c, d, a, area_tol), _orientation(c, d, b, area_tol)
    if o1 != o2 and o3 != o4 and 0 not in (o1, o2, o3, o4):
        return True
    return (
        (o1 == 0 and _on_segment(a, b, c, tol))
        or (o2 == 0 and _on_segment(a, b, d, tol))
        or (o3 == 0 and _on_segment(c, d, a, tol))
        or (o4 == 0 and _on_segment(c, d, b, tol))
    )


def first_crossing(points: np.ndarray) -> tuple[int, int] | None:
    """The first pair of edges (i, j), i < j, that meet other than at their shared end point,
    or None for a simple polygon (O(n^2) segment test; round-off ``1e-12`` of the size)."""
    n = len(points)
    scale = float(np.ptp(points, axis=0).max()) or 1.0
    tol = 1e-12 * scale * scale  # of a cross product: a length squared
    for i in range(n):
        a, b = points[i], points[(i + 1) % n]
        for j in range(i + 1, n):
            c, d = points[j], points[(j + 1) % n]
            if j == i + 1 or (i == 0 and j == n - 1):  # neighbours share one end point
                shared = b if j == i + 1 else a
                far = d if j == i + 1 else c
                # they meet elsewhere only if they fold back onto each other
                if _orientation(a, b, far, tol) == 0 and not np.allclose(far, shared):
                    direction = np.dot(b - a, far - shared) * (1 if j == i + 1 else -1)
                    if direction < 0:
                        return i, j
                continue
            if _segments_meet(a, b, c, d, 1e-12 * scale, tol):
                return i, j
    return None


def bottom_edges(points: np.ndarray) -> list[int]:
    """Indices of the edges that lie on x2 = 0 (both end points exactly on it)."""
    n = len(points)
    return [i for i in range(n) if points[i, 1] == 0.0 and points[(i + 1) % n, 1] == 0.0]


def pin_point(points: np.ndarray) -> tuple[float, float]:
    """The bottom-left-most vertex on x2 = 0 (u1 = 0 there removes the x1 translation)."""
    on_axis = points[points[:, 1] == 0.0]
    return float(on_axis[:, 0].min()), 0.0


def _build_model(points: np.ndarray, h: float, names: dict[str, list[int]] | None = None) -> None:
    """The polygon's gmsh model, meshed: one curve group per edge (tag edge_tag(i)), or, with
    ``names``, one named curve group per name (its edges), the point group "pinned" at the
    :func:`pin_point` and the surface group "tissue" (a .msh file for ``tissue.mesh``)."""
    gmsh = gmsh_api()

    gmsh.model.add("polygon")
    geo = gmsh.model.geo
    tags = [geo.addPoint(x, y, 0.0, h) for x, y in points]
    n = len(tags)
    lines = [geo.addLine(tags[i], tags[(i + 1) % n]) for i in range(n)]
    surface = geo.addPlaneSurface([geo.addCurveLoop(lines)])
    geo.synchronize()
    model = gmsh.model
    if names is None:
        for i, line in enumerate(lines):
            model.addPhysicalGroup(1, [line], edge_tag(i))
        model.addPhysicalGroup(2, [surface], 1)
    else:
        for tag, (name, edges) in enumerate(names.items(), start=1):
            group = model.addPhysicalGroup(1, [lines[i] for i in edges], tag)
            model.setPhysicalName(1, group, name)
        pin = tags[int(np.flatnonzero(np.all(points == pin_point(points), axis=1))[0])]
        model.setPhysicalName(0, model.addPhysicalGroup(0, [pin], 1), "pinned")
        model.setPhysicalName(2, model.addPhysicalGroup(2, [surface], 1), "tissue")
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.1 * h)
    model.mesh.generate(2)


def build_polygon_mesh(
    points: np.ndarray, h: float, comm: MPI.Comm = MPI.COMM_WORLD, model_rank: int = 0
):
    """Triangle mesh of a simple polygon with edges about ``h``: ``(mesh, cell_tags,
    facet_tags)``, the facets of edge i tagged :func:`edge_tag` (i)."""
    gmsh = gmsh_api()
    from dolfinx.io import gmshio

    try:
        if comm.rank == model_rank:
            _build_model(np.asarray(points, dtype=float), h)
        return gmshio.model_to_mesh(gmsh.model, comm, model_rank, gdim=2)
    finally:
        if comm.rank == model_rank:
            gmsh.model.remove()


def write_polygon_msh(points: np.ndarray, h: float, names: dict[str, list[int]], path: str) -> None:
    """Write a polygon's mesh as a gmsh .msh file (format 4.1) for ``tissue.mesh``: the curve
    groups ``names`` (name -> edge indices, e.g. ``{"symmetry": [0], "top": [2]}``), the point
    group "pinned" (:func:`pin_point`) and the surface group "tissue". Serial."""
    gmsh = gmsh_api()

    try:
        _build_model(np.asarray(points, dtype=float), h, names)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.write(str(path))
    finally:
        gmsh.model.remove()
