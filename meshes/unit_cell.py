"""Periodic mesh of the honeycomb unit cell (docs/model.md section 2), built with gmsh.

Two fundamental domains of the same wall lattice can be meshed:
- ``"hexagon"``: the mid-line hexagon A..F, three pairs of opposite sides;
- ``"parallelogram"``: the cell spanned by b1, b2 from a chosen origin (cuts through walls and
  voids), two pairs of sides. Results must not depend on the choice (a test checks it).
Opposite sides are meshed identically (gmsh ``setPeriodic``), so periodic constraints map nodes
onto nodes. gmsh runs on ``model_rank`` only; the mesh is distributed over ``comm``.
gmsh (and dolfinx's gmshio, which imports it) is imported by the functions that mesh, through
:func:`gmsh_api.gmsh_api`: its 0.35-0.45 s are paid only when a mesh is built.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from .gmsh_api import gmsh_api
from .honeycomb import GeometryError, HoneycombCell

CELL_TAGS = {"walls": 1}
FACET_TAGS = {"membrane": 1, "periodic_boundary": 2}
"""Physical tags looked up by name: ``membrane`` is Gamma, the boundary of the void."""

SHAPES = ("hexagon", "parallelogram")


@dataclass(frozen=True)
class PeriodicSide:
    """A slave side ``p -> q``; its points x are constrained to x + shift (on the master side)."""

    p: np.ndarray
    q: np.ndarray
    shift: np.ndarray


@dataclass(frozen=True)
class PeriodicCorner:
    """A slave corner point, constrained to point + shift (its class's master corner)."""

    point: np.ndarray
    shift: np.ndarray


@dataclass(frozen=True)
class PeriodicDomain:
    """A fundamental domain polygon of the lattice and its periodic identifications.

    Corners where several periodic pairs meet are excluded from the sides and constrained on
    their own, each class of lattice-equivalent corners to one master corner that is no slave.
    """

    polygon: np.ndarray
    sides: tuple[PeriodicSide, ...]
    corners: tuple[PeriodicCorner, ...]
    pin_point: np.ndarray
    """A mesh vertex on the membrane away from the periodic boundary (removes translations)."""


def _is_lattice_vector(cell: HoneycombCell, v: np.ndarray, tol: float) -> bool:
    a = cell.lattice_coordinates(v[None, :])[0]
    return bool(np.all(np.abs(a - np.round(a)) < tol))


def domain_polygon(cell: HoneycombCell, shape: str, origin: tuple[float, float]) -> np.ndarray:
    """CCW vertices of the fundamental domain."""
    if shape == "hexagon":
        return cell.hexagon()
    if shape == "parallelogram":
        o = np.asarray(origin, dtype=float)
        return np.array([o, o + cell.b1, o + cell.b1 + cell.b2, o + cell.b2])
    raise GeometryError(f"shape = {shape!r} is invalid: it must be one of {SHAPES}")


def void_polygons(cell: HoneycombCell, polygon: np.ndarray) -> list[np.ndarray]:
    """The voids of all lattice translates that may meet the domain polygon."""
    centre = polygon.mean(axis=0)
    reach = np.linalg.norm(polygon - centre, axis=1).max()
    reach += np.linalg.norm(cell.hexagon(), axis=1).max()
    base = cell.void()
    voids = []
    for k1, k2 in itertools.product(range(-2, 3), repeat=2):
        shift = k1 * cell.b1 + k2 * cell.b2
        if np.linalg.norm(shift - centre) < reach:
            voids.append(base + shift)
    return voids


def periodic_domain(cell: HoneycombCell, polygon: np.ndarray) -> PeriodicDomain:
    """Pair opposite sides and group corners of a fundamental-domain polygon by the lattice."""
    tol = 1e-8
    n = len(polygon)
    sides = []
    for i, j in itertools.combinations(range(n), 2):
        # side j reversed is side i translated by t = p_i - p_{j+1}
        t = polygon[i] - polygon[(j + 1) % n]
        if np.allclose(polygon[(i + 1) % n], polygon[j] + t, atol=tol) and _is_lattice_vector(
            cell, t, tol
        ):
            sides.append(PeriodicSide(polygon[j], polygon[(j + 1) % n], t))
    if 2 * len(sides) != n:
        raise GeometryError("the domain polygon is not a fundamental domain of the lattice")
    corners = []
    masters: list[np.ndarray] = []
    for v in polygon:
        master = next((m for m in masters if _is_lattice_vector(cell, m - v, tol)), None)
        if master is None:
            masters.append(v)
        else:
            corners.append(PeriodicCorner(v, master - v))
    pin = _pin_point(cell, polygon)
    return PeriodicDomain(polygon, tuple(sides), tuple(corners), pin)


def _pin_point(cell: HoneycombCell, polygon: np.ndarray) -> np.ndarray:
    """A void vertex strictly inside the domain (a membrane vertex of the mesh)."""
    scale = np.linalg.norm(cell.b1)
    for void in void_polygons(cell, polygon):
        for v in void:
            if _inside_convex(polygon, v, margin=1e-3 * scale):
                return v
    raise GeometryError("no membrane vertex lies inside the domain; shift the origin")


def _inside_convex(polygon: np.ndarray, x: np.ndarray, margin: float) -> bool:
    n = len(polygon)
    for i in range(n):
        d = polygon[(i + 1) % n] - polygon[i]
        normal = np.array([-d[1], d[0]]) / np.linalg.norm(d)
        if (x - polygon[i]) @ normal < margin:
            return False
    return True


MAX_TRIANGLES = 4e5
"""Largest unit-cell mesh built (about 1.6e6 P2 dofs): beyond it a typo, not a study."""


def check_resolution(name: str, resolution: object) -> int:
    """An integer >= 1, or a GeometryError naming ``name``."""
    if isinstance(resolution, bool) or not isinstance(resolution, int) or resolution < 1:
        raise GeometryError(f"{name} = {resolution!r} is invalid: it must be an integer >= 1")
    return resolution


def check_triangles(name: str, resolution: int, area: float, h: float, limit: float) -> None:
    """Refuse a mesh of about ``area / (sqrt(3)/4 h^2)`` triangles above ``limit``."""
    estimate = area / (0.25 * np.sqrt(3.0) * h * h)
    if estimate > limit:
        largest = max(1, int(resolution * np.sqrt(limit / estimate)))
        raise GeometryError(
            f"{name} = {resolution} would mesh about {estimate:.3g} triangles (limit {limit:g}): "
            f"use {name} <= {largest}"
        )


def mesh_size(cell: HoneycombCell, resolution: int, name: str = "resolution") -> float:
    """Target element size: ``resolution`` elements across the wall thickness w.

    Capped by a quarter of the shortest wall so thick walls still resolve their length;
    a mesh above :data:`MAX_TRIANGLES` is refused with an error naming ``name``.
    """
    check_resolution(name, resolution)
    h = min(cell.w, 0.25 * min(cell.l1, cell.l2)) / resolution
    check_triangles(name, resolution, cell.phi_w * cell.area, h, MAX_TRIANGLES)
    return h


def _on_segment(x: np.ndarray, p: np.ndarray, q: np.ndarray, tol: float) -> bool:
    d = q - p
    t = float((x - p) @ d / (d @ d))
    return -tol <= t <= 1 + tol and float(np.linalg.norm(p + t * d - x)) < tol * np.linalg.norm(d)


def _curve_on_side(ends: np.ndarray, domain: PeriodicDomain, i: int, tol: float) -> bool:
    p, q = domain.polygon[i], domain.polygon[(i + 1) % len(domain.polygon)]
    return all(_on_segment(e, p, q, tol) for e in ends)


def _add_polygon(points: np.ndarray) -> int:
    gmsh = gmsh_api()

    occ = gmsh.model.occ
    tags = [occ.addPoint(x, y, 0.0) for x, y in points]
    lines = [occ.addLine(tags[i], tags[(i + 1) % len(tags)]) for i in range(len(tags))]
    return occ.addPlaneSurface([occ.addCurveLoop(lines)])


def _curve_ends(curve: int) -> np.ndarray:
    gmsh = gmsh_api()

    ends = gmsh.model.getBoundary([(1, curve)], oriented=False)
    return np.array([gmsh.model.getValue(0, tag, [])[:2] for _, tag in ends])


def _build_gmsh_model(cell: HoneycombCell, domain: PeriodicDomain, h: float) -> None:
    """Walls = domain minus voids, tagged, with periodic sides; meshed with size h."""
    gmsh = gmsh_api()

    gmsh.model.add("unit_cell")
    occ = gmsh.model.occ
    surface = _add_polygon(domain.polygon)
    voids = [(2, _add_polygon(v)) for v in void_polygons(cell, domain.polygon)]
    walls, _ = occ.cut([(2, surface)], voids)
    occ.synchronize()
    wall_tags = [tag for dim, tag in walls if dim == 2]
    gmsh.model.addPhysicalGroup(2, wall_tags, CELL_TAGS["walls"])

    tol = 1e-7
    boundary = [tag for _, tag in gmsh.model.getBoundary(walls, oriented=False, combined=True)]
    ends = {curve: _curve_ends(curve) for curve in boundary}
    n = len(domain.polygon)
    on_side = {
        curve: next((i for i in range(n) if _curve_on_side(ee, domain, i, tol)), None)
        for curve, ee in ends.items()
    }
    membrane = [c for c, side in on_side.items() if side is None]
    periodic = [c for c, side in on_side.items() if side is not None]
    gmsh.model.addPhysicalGroup(1, membrane, FACET_TAGS["membrane"])
    gmsh.model.addPhysicalGroup(1, periodic, FACET_TAGS["periodic_boundary"])

    for side in domain.sides:
        slaves = [c for c in periodic if all(_on_segment(e, side.p, side.q, tol) for e in ends[c])]
        for slave in slaves:
            target = ends[slave] + side.shift
            master = next(
                c
                for c in periodic
                if c not in slaves
                and min(np.abs(ends[c] - target).max(), np.abs(ends[c][::-1] - target).max())
                < tol * 10
            )
            # gmsh's affine map sends the master onto the slave
            dx, dy = -side.shift
            gmsh.model.mesh.setPeriodic(
                1, [slave], [master], [1, 0, 0, dx, 0, 1, 0, dy, 0, 0, 1, 0, 0, 0, 0, 1]
            )

    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.1 * h)
    gmsh.model.mesh.generate(2)


@dataclass
class UnitCellMesh:
    """A distributed unit-cell mesh with its tags and periodic identifications."""

    mesh: object
    cell_tags: object
    facet_tags: object
    domain: PeriodicDomain
    cell: HoneycombCell
    h: float


def build_unit_cell_mesh(
    cell: HoneycombCell,
    resolution: int,
    comm: MPI.Comm = MPI.COMM_SELF,
    shape: str = "hexagon",
    origin: tuple[float, float] = (0.0, 0.0),
    model_rank: int = 0,
) -> UnitCellMesh:
    """Mesh the walls of one fundamental domain with periodic opposite sides.

    Args:
        cell: the honeycomb parameters.
        resolution: elements across the wall thickness w (see :func:`mesh_size`).
        comm: communicator the mesh is distributed on.
        shape: ``"hexagon"`` or ``"parallelogram"``.
        origin: lower-left corner of the parallelogram (ignored for the hexagon).
        model_rank: rank that runs gmsh.
    """
    gmsh = gmsh_api()
    from dolfinx.io import gmshio

    polygon = domain_polygon(cell, shape, origin)
    domain = periodic_domain(cell, polygon)
    h = mesh_size(cell, resolution)
    try:
        if comm.rank == model_rank:
            _build_gmsh_model(cell, domain, h)
        mesh, cell_tags, facet_tags = gmshio.model_to_mesh(gmsh.model, comm, model_rank, gdim=2)
    finally:
        if comm.rank == model_rank:
            gmsh.model.remove()
    return UnitCellMesh(mesh, cell_tags, facet_tags, domain, cell, h)
