"""A generated tissue (issue 34): the centroidal-Voronoi cells of a perturbed honeycomb lattice.

Pure numpy and scipy.spatial. The rule, for ``N = Nx^2/2`` cells (``Nx`` even: ``Nx/2`` rows of
``Nx`` cells, the tissue of ``micro.nx = Nx``, meshes/tissue.py) and irregularity ``r`` in [0, 1]:

1. Metric. The honeycomb's hexagon is the Voronoi cell of its lattice in the metric
   ``|x|_M^2 = s (l1 + s) x1^2 + c^2 x2^2`` (each side is the M-bisector of the two centres it
   separates: ``e^T M t = 0``); the diagram is built in ``y = (x1 sqrt(s (l1 + s)) / c, x2)``,
   where it is Euclidean, and mapped back. For the regular hexagon M is the identity.
2. Seeds: the honeycomb centres (``TissueLayout.centres``), each moved by ``r rho u`` in y, with
   ``u`` uniform in the unit disk (``numpy.random.default_rng(seed)``, drawn in id order) and
   ``rho`` the smallest distance between neighbouring centres in y; the bottom row moves along
   x1 only and stays on the symmetry plane x2 = 0, the others are reflected into x2 > 0.
3. Mirror and ghosts: the seeds above x2 = 0 are mirrored to x2 < 0, and two rings of lattice
   points around the whole are fixed ghost seeds, so every kept cell is a bounded Voronoi cell.
4. One Lloyd step (each seed moved to its cell's centroid, the bottom row's x2 kept at 0, the
   mirror redone) evens out the smallest cells while keeping the disorder that r made: r = 0
   is a fixed point (the hexagon centres are its centroids).
5. The kept cells are the seeds' Voronoi cells cut at x2 = 0 (the bottom row's, and a few whose
   seeds were reflected near the plane, have a side on it, exactly at x2 = 0); sides shorter
   than :data:`SHORT_SIDE` times the honeycomb's shortest side are collapsed into their
   midpoint (on x2 = 0 if an end is there): near-degenerate Voronoi vertices, which a wall mesh
   could not resolve, become points where four cells meet. None exists at r = 0.
6. The tissue is moved along x1 so that it starts at x1 = 0 (as the honeycomb does; at r > 0
   the outer cells may reach past it): it lies in x1 >= 0, x2 >= 0.

Measured (N = 512, seeds 0-1, interior cells; tests/test_tissue_cells.py checks the trend):
area CV 0.05 / 0.14 / 0.24 and neighbour-count standard deviation 0 / 0.70 / 1.03 at
r = 0.25 / 0.5 / 1 (a Poisson-Voronoi tissue: 0.53 and 1.33); the shortest side 0.18 / 0.026
/ 0.024 times the median side.

At r = 0 the polygons are ``TissueLayout(cell, Nx).hexagon(i)`` to round-off.
"""

from __future__ import annotations

import math

import numpy as np

from .cell_polygons import CellPolygons
from .geometry_error import GeometryError
from .honeycomb import HoneycombCell
from .tissue import MAX_NX, TissueLayout

LLOYD_STEPS = 1
"""Lloyd (centroidal) relaxation steps after the seeds are perturbed."""
GHOST_RINGS = 2
"""Rings of fixed lattice points around the tissue that bound its outer cells."""
SHORT_SIDE = 0.05
"""Sides shorter than this fraction of the honeycomb's shortest side are collapsed."""


def voronoi_nx(n_cells: object, name: str = "tissue.cells.voronoi") -> int:
    """``Nx`` with ``n_cells = Nx^2 / 2`` (Nx even in [2, MAX_NX]), or a GeometryError naming
    ``name`` and the nearest valid counts."""
    valid = isinstance(n_cells, int) and not isinstance(n_cells, bool)
    nx = math.isqrt(2 * n_cells) if valid and n_cells > 0 else 0
    if valid and nx % 2 == 0 and 2 <= nx <= MAX_NX and nx * nx // 2 == n_cells:
        return nx
    near = max(2, min(MAX_NX, 2 * round(math.sqrt(2 * max(n_cells, 0)) / 2) if valid else 2))
    hint = ", ".join(f"{k * k // 2} (Nx = {k})" for k in (near - 2, near, near + 2)
                     if 2 <= k <= MAX_NX)  # fmt: skip
    raise GeometryError(
        f"{name} = {n_cells!r} is invalid: it must be an integer Nx^2/2 with Nx even in "
        f"[2, {MAX_NX}] (Nx/2 rows of Nx cells, the tissue of micro.nx = Nx), e.g. {hint}"
    )


def _lattice(cell: HoneycombCell, nx: int, rows: range, cols: range) -> np.ndarray:
    """Centres of the honeycomb lattice at (row, k) (rows may be negative), in x."""
    d = 4.0 / nx
    r, k = np.meshgrid(np.array(rows), np.array(cols), indexing="ij")
    x1 = (k + 0.5 + 0.5 * (r % 2)) * d * 2.0 * cell.c
    x2 = r * d * (cell.l1 + cell.s)
    return np.column_stack([x1.ravel(), x2.ravel()])


def _clip_below(polygon: np.ndarray, tol: float) -> np.ndarray:
    """The part x2 >= 0 of a convex CCW polygon; points within ``tol`` of x2 = 0 are put on it
    and repeated points dropped."""
    p = polygon.copy()
    p[np.abs(p[:, 1]) <= tol, 1] = 0.0
    out = []
    n = len(p)
    for i in range(n):
        a, b = p[i], p[(i + 1) % n]
        if a[1] >= 0.0:
            out.append(a)
        if (a[1] > 0.0 and b[1] < 0.0) or (a[1] < 0.0 and b[1] > 0.0):
            q = a + (b - a) * a[1] / (a[1] - b[1])
            out.append(np.array([q[0], 0.0]))
    out = np.array(out)
    keep = np.linalg.norm(out - np.roll(out, -1, axis=0), axis=1) > tol
    return out[keep]


def _regions(points: np.ndarray, n_real: int) -> list[np.ndarray]:
    """The Voronoi cells (CCW vertex arrays) of the first ``n_real`` points."""
    from scipy.spatial import Voronoi  # not at import: the scene key's checks need no scipy

    vor = Voronoi(points)
    out = []
    for i in range(n_real):
        region = vor.regions[vor.point_region[i]]
        if -1 in region or not region:
            raise GeometryError(f"generated cell {i} is unbounded (a ghost ring too few)")
        poly = vor.vertices[region]
        angle = np.arctan2(*(poly - points[i]).T[::-1])
        out.append(poly[np.argsort(angle)])
    return out


def _centroid(p: np.ndarray) -> np.ndarray:
    q = np.roll(p, -1, axis=0)
    cross = p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]
    return ((p + q) * cross[:, None]).sum(axis=0) / (3.0 * cross.sum())


def voronoi_tissue(cell: HoneycombCell, n_cells: int, seed: int, r: float) -> CellPolygons:
    """The generated tissue of ``n_cells`` cells (module docstring); labels 0..n-1 in the
    honeycomb's id order (row * Nx + k)."""
    nx = voronoi_nx(n_cells)
    if not 0.0 <= r <= 1.0:
        raise GeometryError(f"tissue.cells.regularity = {r!r} is invalid: it must lie in [0, 1]")
    layout = TissueLayout(cell, nx)
    rows = nx // 2
    stretch = np.array([math.sqrt(cell.s * (cell.l1 + cell.s)) / cell.c, 1.0])  # x -> y
    seeds = layout.centres * stretch
    bottom = np.arange(n_cells) < nx
    lattice = _lattice(cell, nx, range(-1, 2), range(0, 3)) * stretch  # spacing around (1, 1)
    spacing = np.linalg.norm(lattice - lattice[4], axis=1)
    rho = spacing[spacing > 0].min()
    u = np.random.default_rng(seed).random((n_cells, 2))
    move = np.sqrt(u[:, :1]) * np.column_stack([np.cos(2 * np.pi * u[:, 1]),
                                                np.sin(2 * np.pi * u[:, 1])])  # fmt: skip
    move[bottom, 1] = 0.0
    seeds = seeds + r * rho * move
    seeds[:, 1] = np.abs(seeds[:, 1])
    g = GHOST_RINGS
    ring_rows, ring_cols = range(-rows - g + 1, rows + g), range(-g, nx + g)
    ghosts = _lattice(cell, nx, ring_rows, ring_cols) * stretch
    r_id, k_id = (a.ravel() for a in np.meshgrid(ring_rows, ring_cols, indexing="ij"))
    ghosts = ghosts[(np.abs(r_id) >= rows) | (k_id < 0) | (k_id >= nx)]
    steps = LLOYD_STEPS if r > 0.0 else 0
    for step in range(steps + 1):
        points = np.vstack([seeds, seeds[~bottom] * [1.0, -1.0], ghosts])
        cells = _regions(points, n_cells)
        if step < steps:
            seeds = np.array([_centroid(p) for p in cells])
            seeds[bottom, 1] = 0.0
    tol = 1e-9 * 4.0 * max(cell.l1, cell.l2)
    loops = [p / stretch for p in cells]
    loops = [_clip_below(p, tol) for p in loops]  # others may have a side on x2 = 0 too
    tissue = CellPolygons.from_loops(loops, labels=np.arange(n_cells))
    shortest = SHORT_SIDE * layout.delta_s * min(0.5 * cell.l1, cell.l2)  # the cut sides: l1/2
    tissue = _collapse_short_sides(tissue, shortest)
    left = min(float(tissue.vertices[:, 0].min()), 0.0)  # outer cells may reach past x1 = 0
    tissue = CellPolygons(tissue.vertices - [left, 0.0], tissue.cells, tissue.labels)
    tissue.check()
    return tissue


def _collapse_short_sides(tissue: CellPolygons, shortest: float) -> CellPolygons:
    """The tissue with every side shorter than ``shortest`` collapsed into one vertex at its
    ends' mean (x2 = 0 if one of them is on the symmetry plane)."""
    v = tissue.vertices
    parent = np.arange(len(v))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for a, b in tissue.sides():
        if np.linalg.norm(v[a] - v[b]) < shortest:
            parent[root(b)] = root(a)
    roots = np.array([root(i) for i in range(len(v))])
    if (roots == np.arange(len(v))).all():
        return tissue
    counts = np.bincount(roots, minlength=len(v))
    merged = np.zeros_like(v)
    np.add.at(merged, roots, v)
    merged /= np.maximum(counts, 1)[:, None]  # rows of non-roots are unused
    on_axis = np.bincount(roots, weights=v[:, 1] == 0.0, minlength=len(v)) > 0
    merged[on_axis, 1] = 0.0
    loops = []
    for label, loop in zip(tissue.labels, tissue.cells, strict=True):
        ids = roots[loop]
        ids = ids[ids != np.roll(ids, 1)]
        if len(ids) < 3:
            raise GeometryError(f"generated cell {label} is too small: try another seed")
        loops.append(merged[ids])
    return CellPolygons.from_loops(loops, labels=tissue.labels)
