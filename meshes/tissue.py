"""The cellular tissue of the microscopic model and its outline (docs/model.md section 7),
built with gmsh.

``Nx/2`` rows of ``Nx`` cells, each the honeycomb unit cell scaled by ``delta_s = 4 / Nx``; row r
has its centres at ``x2 = r delta_s (l1 + s)``, ``x1 = (k + 1/2 + (r mod 2)/2) delta_s 2c``. The
bottom row is cut at x2 = 0 (symmetry plane). Each cell owns the walls between its mid-line
hexagon and its void (so a shared wall is 2w thick and an outer wall w thick). gmsh runs on
``model_rank`` only; meshes are distributed over ``comm``.
gmsh (and dolfinx's gmshio, which imports it) is imported by the functions that mesh, through
:func:`gmsh_api.gmsh_api`: its 0.35-0.45 s are paid only when a mesh is built.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from .cell_tissue import CellTissue, as_tissue
from .gmsh_api import gmsh_api
from .honeycomb import GeometryError, HoneycombCell
from .unit_cell import check_resolution, check_triangles

FACET_TAGS = {"membrane": 1, "bottom": 2, "outer": 3}
"""Facet tags of the walls mesh; cell tags are ``cell id + 1``."""
OUTLINE_TAG = 1
"""Cell tag of the outline (macro) mesh."""


PLANE_TOLERANCE = 1e-3
"""A wall's boundary curve with both ends within this many w of x2 = 0 is on the symmetry plane
(the nearest other boundary is at least w away)."""

MAX_NX = 256
"""Largest Nx accepted (32768 cells)."""
MAX_TRIANGLES = 2e6
"""Largest walls mesh built (about 8e6 P2 dofs)."""


def check_nx(name: str, nx: object) -> int:
    """An even integer in [2, MAX_NX], or a GeometryError naming ``name``."""
    if isinstance(nx, bool) or not isinstance(nx, int) or not 2 <= nx <= MAX_NX or nx % 2:
        raise GeometryError(
            f"{name} = {nx!r} is invalid: it must be an even integer in [2, {MAX_NX}] "
            "(Nx/2 rows of Nx cells)"
        )
    return nx


def clip_below(polygon: np.ndarray) -> np.ndarray:
    """The part x2 >= 0 of a convex polygon (Sutherland-Hodgman clip, order kept)."""
    side = polygon[:, 1]
    out = []
    n = len(polygon)
    for k in range(n):
        a, b, sa, sb = polygon[k], polygon[(k + 1) % n], side[k], side[(k + 1) % n]
        if sa >= 0.0:
            out.append(a)
        if (sa >= 0.0) != (sb >= 0.0):
            out.append(a + (b - a) * sa / (sa - sb))
    return np.array(out)


@dataclass(frozen=True)
class TissueLayout:
    """Where the cells of an ``Nx`` tissue are (pure geometry, no mesh).

    Attributes:
        cell: the unit cell (before scaling).
        nx: cells per row, even, >= 2.
    """

    cell: HoneycombCell
    nx: int

    def __post_init__(self) -> None:
        check_nx("micro.nx", self.nx)

    @property
    def delta_s(self) -> float:
        """Scale of one cell: ``4 / Nx`` (docs/model.md section 7)."""
        return 4.0 / self.nx

    @property
    def n_cells(self) -> int:
        return self.nx * self.nx // 2

    @property
    def centres(self) -> np.ndarray:
        """(n_cells, 2) cell centres, id = row * Nx + k."""
        d, c = self.delta_s, self.cell.c
        rows, ks = np.divmod(np.arange(self.n_cells), self.nx)
        x1 = (ks + 0.5 + 0.5 * (rows % 2)) * d * 2.0 * c
        x2 = rows * d * (self.cell.l1 + self.cell.s)
        return np.column_stack([x1, x2])

    @property
    def cut_cells(self) -> slice:
        """Ids of the bottom row, whose cells are cut at mid-height by the symmetry plane."""
        return slice(0, self.nx)

    def hexagon(self, cell_id: int) -> np.ndarray:
        """Mid-line hexagon of a cell, cut at x2 = 0 for the bottom row."""
        poly = self.delta_s * self.cell.hexagon() + self.centres[cell_id]
        return clip_below(poly) if cell_id < self.cut_cells.stop else poly

    def void(self, cell_id: int) -> np.ndarray:
        """Void of a cell (not cut: the bottom row's voids are open at x2 = 0)."""
        return self.delta_s * self.cell.void() + self.centres[cell_id]

    @property
    def bounding_box(self) -> tuple[float, float]:
        """(width, height) of the smallest rectangle [0, width] x [0, height] holding the tissue."""
        points = np.vstack([self.hexagon(i) for i in range(self.n_cells)])
        return float(points[:, 0].max()), float(points[:, 1].max())


def _add_polygon(points: np.ndarray) -> int:
    gmsh = gmsh_api()

    occ = gmsh.model.occ
    tags = [occ.addPoint(x, y, 0.0) for x, y in points]
    lines = [occ.addLine(tags[i], tags[(i + 1) % len(tags)]) for i in range(len(tags))]
    return occ.addPlaneSurface([occ.addCurveLoop(lines)])


def _build_walls_model(tissue: CellTissue, h: float) -> None:
    gmsh = gmsh_api()

    gmsh.model.add("tissue")
    occ = gmsh.model.occ
    n = tissue.n_cells
    polygons = [(2, _add_polygon(tissue.polygon(i))) for i in range(n)]
    voids = [(2, _add_polygon(tissue.void(i))) for i in range(n)]
    _, pieces = occ.fragment(polygons, voids)
    occ.synchronize()
    # a polygon's pieces are its walls and its void; a void's pieces are void only
    void_surfaces = sorted({tag for piece in pieces[n:] for _, tag in piece})
    owner = {i: sorted({t for _, t in pieces[i]} - set(void_surfaces)) for i in range(n)}
    membrane = {
        tag for s in void_surfaces for _, tag in gmsh.model.getBoundary([(2, s)], oriented=False)
    }
    occ.remove([(2, s) for s in void_surfaces], recursive=False)
    occ.synchronize()
    for cell_id, surfaces in owner.items():
        gmsh.model.addPhysicalGroup(2, surfaces, cell_id + 1)
    walls = [(2, s) for surfaces in owner.values() for s in surfaces]
    boundary = [t for _, t in gmsh.model.getBoundary(walls, oriented=False, combined=True)]
    groups: dict[str, list[int]] = {"membrane": [], "bottom": [], "outer": []}
    # a foot on x2 = 0 whose end gmsh's fragment moved onto a void corner just below it (a cut
    # cell's side a little off perpendicular: measured 2e-7 = 1.6e-5 w) is still on the plane
    plane = max(tissue.tolerance, PLANE_TOLERANCE * tissue.w)
    for curve in boundary:
        y = [gmsh.model.getValue(0, p, [])[1] for _, p in gmsh.model.getBoundary([(1, curve)])]
        if curve in membrane:
            groups["membrane"].append(curve)
        elif max(abs(v) for v in y) < plane:
            groups["bottom"].append(curve)
        else:
            groups["outer"].append(curve)
    for name, curves in groups.items():
        gmsh.model.addPhysicalGroup(1, curves, FACET_TAGS[name])
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.1 * h)
    gmsh.model.mesh.generate(2)


def _build_outline_model(layout: TissueLayout, h: float) -> None:
    gmsh = gmsh_api()

    gmsh.model.add("outline")
    occ = gmsh.model.occ
    hexagons = [(2, _add_polygon(layout.hexagon(i))) for i in range(layout.n_cells)]
    # fragment (not fuse) keeps the mesh conforming across the hexagons' shared sides
    pieces, _ = occ.fragment(hexagons[:1], hexagons[1:])
    occ.synchronize()
    gmsh.model.addPhysicalGroup(2, [t for d, t in pieces if d == 2], OUTLINE_TAG)
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.1 * h)
    gmsh.model.mesh.generate(2)


def _to_dolfinx(build, comm: MPI.Comm, model_rank: int):
    gmsh = gmsh_api()
    from dolfinx.io import gmshio

    try:
        if comm.rank == model_rank:
            build()
        return gmshio.model_to_mesh(gmsh.model, comm, model_rank, gdim=2)
    finally:
        if comm.rank == model_rank:
            gmsh.model.remove()


def wall_mesh_size(
    tissue: CellTissue | TissueLayout, resolution: int, name: str = "micro.resolution"
) -> float:
    """``resolution`` elements across one cell's own wall w (capped by the walls' length as in
    the unit cell: :attr:`CellTissue.mesh_length`); a mesh above :data:`MAX_TRIANGLES` is
    refused."""
    check_resolution(name, resolution)
    tissue = as_tissue(tissue)
    h = tissue.mesh_length / resolution
    check_triangles(
        f"{name} (with {tissue.name})", resolution, tissue.wall_area, h, MAX_TRIANGLES
    )
    return h


def build_walls_mesh(
    tissue: CellTissue | TissueLayout, resolution: int, comm: MPI.Comm = MPI.COMM_WORLD,
    model_rank: int = 0,
):  # fmt: skip
    """Mesh of the walls of all cells (a TissueLayout: its honeycomb's): ``(mesh, cell_tags,
    facet_tags)``. Cell tags are ``cell id + 1`` (each cell's own walls); facet tags
    ``FACET_TAGS`` ("bottom": the cut cells' sides on the symmetry plane x2 = 0)."""
    tissue = as_tissue(tissue)
    h = wall_mesh_size(tissue, resolution)
    return _to_dolfinx(lambda: _build_walls_model(tissue, h), comm, model_rank)


def build_outline_mesh(
    layout: TissueLayout, h: float, comm: MPI.Comm = MPI.COMM_WORLD, model_rank: int = 0
):
    """Mesh of the region the cells cover (the union of their mid-line hexagons, cut at x2 = 0),
    the macroscopic domain of a micro-macro comparison: ``(mesh, cell_tags, facet_tags)``."""
    return _to_dolfinx(lambda: _build_outline_model(layout, h), comm, model_rank)
