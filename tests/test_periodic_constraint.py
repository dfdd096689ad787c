"""Periodic identifications, periodic mesh and the dolfinx_mpc constraint (docs/model.md section 2).

The constrained operator must be the explicit reduction K^T A K of the unconstrained one, every
side/corner dof must be slaved exactly once, and the computed correctors must be periodic.
Solvers are on ``MPI.COMM_WORLD`` (distributed under mpirun); data is gathered for the checks.
"""

from __future__ import annotations

import itertools

import dolfinx.fem.petsc
import numpy as np
import pytest
from dolfinx_mpc.utils.test import compare_mpc_lhs
from mpi4py import MPI
from scipy.spatial import cKDTree

from plantgrowth.meshes.honeycomb import GeometryError, HoneycombCell
from plantgrowth.meshes.unit_cell import domain_polygon, periodic_domain
from plantgrowth.unitcell.solver import CellSolver

pytestmark = pytest.mark.mpi  # scripts/README.md, "Tests": every test also runs on 2 ranks

# A coarse cell (resolution 1, thick walls): small matrices for the explicit reduction.
SMALL = HoneycombCell(w=0.2)
ELONGATED = HoneycombCell(l1=1.5, theta_deg=40.0, w=0.15)
SHEAR = np.array([[1.2, 0.3], [0.0, 1.0]])
DOMAINS = [
    (SMALL, "hexagon", (0.0, 0.0)),
    (SMALL, "parallelogram", (-0.3, -0.2)),
    (ELONGATED, "hexagon", (0.0, 0.0)),
    (ELONGATED, "parallelogram", (0.1, -0.45)),
]
DOMAIN_IDS = ["hexagon", "parallelogram", "elongated-hexagon", "elongated-parallelogram"]
# gmsh copies periodic nodes by the exact affine map and dolfinx places P2 dofs at edge
# midpoints: image points coincide up to round-off on O(1) coordinates.
GEOM_TOL = 1e-9


@pytest.fixture(scope="module")
def solver():
    """``solver(cell, shape, origin)``: CellSolver at resolution 1 on COMM_WORLD, cached."""
    cache: dict = {}

    def get(cell, shape, origin):
        key = (cell, shape, tuple(origin))
        if key not in cache:
            cache[key] = CellSolver(cell, 1, MPI.COMM_WORLD, shape=shape, origin=origin)
        return cache[key]

    yield get
    cache.clear()


def _is_lattice_vector(cell: HoneycombCell, v: np.ndarray) -> bool:
    a = cell.lattice_coordinates(np.asarray(v)[None, :])[0]
    return bool(np.allclose(a, np.round(a), atol=1e-10))


def _on_segment(x: np.ndarray, p: np.ndarray, q: np.ndarray, tol: float) -> np.ndarray:
    """Mask of the rows of x (n, 2) on the closed segment p-q."""
    d = q - p
    t = (x - p) @ d / (d @ d)
    dist = np.linalg.norm(p + t[:, None] * d - x, axis=1)
    return (dist < tol) & (t > -tol) & (t < 1 + tol)


def _gather_owned(V, values: np.ndarray | None = None):
    """Coordinates (n, 2) of all owned dof blocks on all ranks, and the block values if given."""
    n = V.dofmap.index_map.size_local
    x = V.tabulate_dof_coordinates()[:n, :2]
    xs = np.vstack(V.mesh.comm.allgather(x))
    if values is None:
        return xs, None
    return xs, np.vstack(V.mesh.comm.allgather(values.reshape(-1, 2)[:n]))


# --- periodic identifications (pure geometry) ----------------------------------------------


@pytest.mark.parametrize("cell, shape, origin", DOMAINS, ids=DOMAIN_IDS)
def test_periodic_domain_pairs_sides_and_corners(cell, shape, origin):
    polygon = domain_polygon(cell, shape, origin)
    domain = periodic_domain(cell, polygon)
    n = len(polygon)
    assert len(domain.sides) == n // 2  # 3 pairs for the hexagon, 2 for the parallelogram
    # the n corners fall into lattice classes (2 for the hexagon, 1 for the parallelogram); all
    # but one per class are slaves
    assert len(domain.corners) == (4 if shape == "hexagon" else 3)
    vertices = [tuple(np.round(v, 12)) for v in polygon]
    slave_corners = {tuple(np.round(c.point, 12)) for c in domain.corners}
    for side in domain.sides:
        assert _is_lattice_vector(cell, side.shift)
        assert tuple(np.round(side.p + side.shift, 12)) in vertices
        assert tuple(np.round(side.q + side.shift, 12)) in vertices
    for corner in domain.corners:
        assert _is_lattice_vector(cell, corner.shift)
        master = tuple(np.round(corner.point + corner.shift, 12))
        assert master in vertices and master not in slave_corners
    # every side of the polygon is a slave side or the image of one, exactly once
    slave_edges = {(tuple(np.round(s.p, 12)), tuple(np.round(s.q, 12))) for s in domain.sides}
    master_edges = {
        (tuple(np.round(s.q + s.shift, 12)), tuple(np.round(s.p + s.shift, 12)))
        for s in domain.sides
    }
    edges = {(vertices[i], vertices[(i + 1) % n]) for i in range(n)}
    assert slave_edges | master_edges == edges
    assert not slave_edges & master_edges
    # the pin point is a void vertex strictly inside the domain
    void_vertices = [
        v + k1 * cell.b1 + k2 * cell.b2
        for v in cell.void()
        for k1, k2 in itertools.product(range(-2, 3), repeat=2)
    ]
    assert min(np.linalg.norm(v - domain.pin_point) for v in void_vertices) < 1e-12


def test_non_fundamental_polygon_is_rejected():
    cell = HoneycombCell()
    with pytest.raises(GeometryError):
        periodic_domain(cell, 0.5 * cell.hexagon())
    with pytest.raises(GeometryError, match="shape"):
        domain_polygon(cell, "triangle", (0.0, 0.0))


# --- periodic mesh -------------------------------------------------------------------------------


@pytest.mark.parametrize("cell, shape, origin", DOMAINS, ids=DOMAIN_IDS)
def test_mesh_nodes_are_periodic(solver, cell, shape, origin):
    s = solver(cell, shape, origin)
    x = np.vstack(MPI.COMM_WORLD.allgather(s.unit_cell.mesh.geometry.x[:, :2]))
    tree = cKDTree(x)
    for side in s.unit_cell.domain.sides:
        on_side = x[_on_segment(x, side.p, side.q, GEOM_TOL)]
        assert len(on_side) >= 2  # the side crosses at least one wall
        dist, _ = tree.query(on_side + side.shift)
        assert dist.max() < GEOM_TOL


# --- the constraint ------------------------------------------------------------------------------


@pytest.mark.parametrize("cell, shape, origin", DOMAINS, ids=DOMAIN_IDS)
def test_each_boundary_dof_is_slaved_once(solver, cell, shape, origin):
    """Slaves = both components of every dof point on the slave sides, ends excluded, plus the
    slave corners that are mesh points (a parallelogram's corners may lie in a void); fewer
    means a missed identification, more a double one (issue #21)."""
    s = solver(cell, shape, origin)
    domain = s.unit_cell.domain
    x, _ = _gather_owned(s.V)
    tol = 1e-3 * s.unit_cell.h  # the solver's own locating tolerance
    corners = np.array(domain.polygon)
    away = np.min(np.linalg.norm(x[:, None, :] - corners[None], axis=2), axis=1) > tol
    on_slave_sides = np.zeros(len(x), dtype=bool)
    for side in domain.sides:
        on_slave_sides |= _on_segment(x, side.p, side.q, tol)
    tree = cKDTree(x)
    corner_dofs = sum(tree.query(c.point)[0] < tol for c in domain.corners)
    if shape == "hexagon":
        assert corner_dofs == 4  # the hexagon's corners are wall joints
    expected = 2 * (np.count_nonzero(on_slave_sides & away) + corner_dofs)
    assert MPI.COMM_WORLD.allreduce(s.mpc.num_local_slaves, op=MPI.SUM) == expected


@pytest.mark.parametrize("cell, shape, origin", DOMAINS, ids=DOMAIN_IDS)
def test_constrained_matrix_is_explicit_reduction(solver, cell, shape, origin):
    """The MPC matrix equals K^T A K (K the slave-to-master map), to 1e-10 absolute on O(1)
    entries (dolfinx_mpc's own check; the two assemblies differ by summation order only)."""
    s = solver(cell, shape, origin)
    s.solve(SHEAR, 2.0, 0.25)  # re-assembles s.A with these constants
    A_org = dolfinx.fem.petsc.assemble_matrix(s.bilinear_form, bcs=s.bcs)
    A_org.assemble()
    compare_mpc_lhs(A_org, s.A, s.mpc, root=0)
    A_org.destroy()


@pytest.mark.parametrize("cell, shape, origin", DOMAINS, ids=DOMAIN_IDS)
def test_corrector_is_periodic(solver, cell, shape, origin):
    """After solve, the pressure corrector v (the last of the four solves) takes the same value
    at every boundary dof and its lattice image (back-substitution copies masters exactly)."""
    s = solver(cell, shape, origin)
    s.solve(SHEAR, 1.0, 0.3)
    # CellSolver keeps its last solution in the private ``_z`` (no public handle); it is v
    V = s._z.function_space
    x, values = _gather_owned(V, s._z.x.array)
    scale = np.abs(values).max()
    assert scale > 0
    tree = cKDTree(x)
    for side in s.unit_cell.domain.sides:
        on_side = _on_segment(x, side.p, side.q, GEOM_TOL)
        dist, image = tree.query(x[on_side] + side.shift)
        assert dist.max() < GEOM_TOL
        np.testing.assert_allclose(values[image], values[on_side], rtol=0, atol=1e-12 * scale)
        # not trivially periodic: v varies along the side
        assert np.ptp(values[on_side]) > 1e-3 * scale
    # the pinned point carries zero displacement
    pin = tree.query(s.unit_cell.domain.pin_point)[1]
    np.testing.assert_array_equal(values[pin], 0.0)
