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
WALL_FAMILY_TAGS = (11, 12, 13)
"""Cell tags of a mesh split for fibre-reinforced walls (docs/model.md, "Fibre-reinforced walls"):
the wall points nearest to a mid-line segment of tangent ``HoneycombCell.wall_tangents()[k]``
carry tag ``WALL_FAMILY_TAGS[k]``; an unsplit mesh tags every wall ``CELL_TAGS["walls"]``."""
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


def lattice_shifts(cell: HoneycombCell, polygon: np.ndarray) -> list[np.ndarray]:
    """The lattice vectors whose translate of the mid-line hexagon may meet the domain polygon."""
    centre = polygon.mean(axis=0)
    reach = np.linalg.norm(polygon - centre, axis=1).max()
    reach += np.linalg.norm(cell.hexagon(), axis=1).max()
    shifts = (k1 * cell.b1 + k2 * cell.b2 for k1, k2 in itertools.product(range(-2, 3), repeat=2))
    return [shift for shift in shifts if np.linalg.norm(shift - centre) < reach]


def void_polygons(cell: HoneycombCell, polygon: np.ndarray) -> list[np.ndarray]:
    """The voids of all lattice translates that may meet the domain polygon."""
    base = cell.void()
    return [base + shift for shift in lattice_shifts(cell, polygon)]


def _clip_to_convex(polygon: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """The part of the segment ab inside the CCW convex polygon (Cyrus-Beck), or None."""
    lo, hi = 0.0, 1.0
    n = len(polygon)
    for i in range(n):
        d = polygon[(i + 1) % n] - polygon[i]
        normal = np.array([-d[1], d[0]])  # inward for a CCW polygon
        start, rate = (a - polygon[i]) @ normal, (b - a) @ normal
        if rate == 0.0:
            if start < 0.0:
                return None
        elif rate > 0.0:
            lo = max(lo, -start / rate)
        else:
            hi = min(hi, -start / rate)
    if hi - lo <= 1e-9:
        return None
    return np.array([a + lo * (b - a), a + hi * (b - a)])


def _six_sided_limit(hexagon: np.ndarray) -> float:
    """Largest w that keeps every side of the void: a side of length L between corners of
    interior angles A1, A2 shrinks to ``L - w (cot(A1/2) + cot(A2/2))``."""
    n = len(hexagon)
    half_cot = []
    for k in range(n):
        a, b = hexagon[k - 1] - hexagon[k], hexagon[(k + 1) % n] - hexagon[k]
        angle = np.arccos(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))
        half_cot.append(1.0 / np.tan(0.5 * angle))
    sides = np.linalg.norm(np.roll(hexagon, -1, axis=0) - hexagon, axis=1)
    return float(min(sides[k] / (half_cot[k] + half_cot[(k + 1) % n]) for k in range(n)))


def corner_bisectors(cell: HoneycombCell, polygon: np.ndarray) -> list[np.ndarray]:
    """The wall's split lines inside the domain polygon, as (2, 2) end points.

    At each corner of the mid-line hexagon the wall points nearest to its two sides are
    separated by the corner's bisector, from the corner to the void's corner that the inward
    offset puts on it (docs/model.md, "Fibre-reinforced walls"). A void that lost a side to the
    offset has no such split: a GeometryError.
    """
    hexagon, void = cell.hexagon(), cell.void()
    if len(void) != len(hexagon):
        raise GeometryError(
            f"w = {cell.w} leaves a void with {len(void)} sides: fibre-reinforced walls need all "
            f"six, so w must lie in (0, {_six_sided_limit(hexagon):.6g}) for this cell"
        )
    ends = void[[int(np.argmin(np.linalg.norm(void - v, axis=1))) for v in hexagon]]
    pieces = []
    for shift in lattice_shifts(cell, polygon):
        for v, e in zip(hexagon + shift, ends + shift, strict=True):
            piece = _clip_to_convex(polygon, v, e)
            if piece is not None and np.linalg.norm(piece[1] - piece[0]) > 1e-9 * cell.l2:
                pieces.append(piece)
    return pieces


def wall_family(cell: HoneycombCell, polygon: np.ndarray, point: np.ndarray) -> int:
    """Index k of the family (tangent ``cell.wall_tangents()[k]``) of the mid-line segment
    nearest to ``point``, over the lattice translates of the hexagon's six sides."""
    hexagon = cell.hexagon()
    best, family = np.inf, -1
    tangents = cell.wall_tangents()
    for shift in lattice_shifts(cell, polygon):
        for p, q in zip(hexagon + shift, np.roll(hexagon, -1, axis=0) + shift, strict=True):
            d = q - p
            t = np.clip((point - p) @ d / (d @ d), 0.0, 1.0)
            distance = np.linalg.norm(p + t * d - point)
            if distance < best:
                best, family = distance, int(np.argmax(np.abs(tangents @ d)))
    return family


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


def _split_walls(cell: HoneycombCell, domain: PeriodicDomain, walls: list) -> list:
    """Cut the walls along the corner bisectors (mesh edges) and tag each piece by the family of
    its nearest mid-line segment (:data:`WALL_FAMILY_TAGS`); returns the pieces."""
    gmsh = gmsh_api()
    occ = gmsh.model.occ
    lines = []
    for a, b in corner_bisectors(cell, domain.polygon):
        ends = [occ.addPoint(x, y, 0.0) for x, y in (a, b)]
        lines.append((1, occ.addLine(*ends)))
    pieces, _ = occ.fragment(walls, lines)
    occ.synchronize()
    pieces = [(dim, tag) for dim, tag in pieces if dim == 2]
    by_family: dict[int, list[int]] = {}
    for _, tag in pieces:
        centre = np.array(occ.getCenterOfMass(2, tag)[:2])
        by_family.setdefault(wall_family(cell, domain.polygon, centre), []).append(tag)
    for family, tags in sorted(by_family.items()):
        gmsh.model.addPhysicalGroup(2, tags, WALL_FAMILY_TAGS[family])
    return pieces


def _build_gmsh_model(cell: HoneycombCell, domain: PeriodicDomain, h: float, fibres: bool) -> None:
    """Walls = domain minus voids, tagged (split by segment family if ``fibres``), with periodic
    sides; meshed with size h."""
    gmsh = gmsh_api()

    gmsh.model.add("unit_cell")
    occ = gmsh.model.occ
    surface = _add_polygon(domain.polygon)
    voids = [(2, _add_polygon(v)) for v in void_polygons(cell, domain.polygon)]
    walls, _ = occ.cut([(2, surface)], voids)
    occ.synchronize()
    if fibres:
        walls = _split_walls(cell, domain, walls)
    else:
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
    wall_tags: tuple[int, ...]
    """The cell tags of the walls: ``(CELL_TAGS["walls"],)``, or :data:`WALL_FAMILY_TAGS`."""


def build_unit_cell_mesh(
    cell: HoneycombCell,
    resolution: int,
    comm: MPI.Comm = MPI.COMM_SELF,
    shape: str = "hexagon",
    origin: tuple[float, float] = (0.0, 0.0),
    model_rank: int = 0,
    fibres: bool = False,
) -> UnitCellMesh:
    """Mesh the walls of one fundamental domain with periodic opposite sides.

    Args:
        cell: the honeycomb parameters.
        resolution: elements across the wall thickness w (see :func:`mesh_size`).
        comm: communicator the mesh is distributed on.
        shape: ``"hexagon"`` or ``"parallelogram"``.
        origin: lower-left corner of the parallelogram (ignored for the hexagon).
        model_rank: rank that runs gmsh.
        fibres: split the walls along the corner bisectors and tag them by segment family
            (for fibre-reinforced walls); False keeps the unsplit mesh of the isotropic walls.
    """
    gmsh = gmsh_api()
    from dolfinx.io import gmshio

    polygon = domain_polygon(cell, shape, origin)
    domain = periodic_domain(cell, polygon)
    h = mesh_size(cell, resolution)
    if fibres:
        corner_bisectors(cell, polygon)  # on every rank: a GeometryError before gmsh runs
    try:
        if comm.rank == model_rank:
            _build_gmsh_model(cell, domain, h, fibres)
        mesh, cell_tags, facet_tags = gmshio.model_to_mesh(gmsh.model, comm, model_rank, gdim=2)
    finally:
        if comm.rank == model_rank:
            gmsh.model.remove()
    wall_tags = WALL_FAMILY_TAGS if fibres else (CELL_TAGS["walls"],)
    return UnitCellMesh(mesh, cell_tags, facet_tags, domain, cell, h, wall_tags)
