"""The pointwise checks' sample points (plantgrowth.base.mesh_samples): a P2 field whose det F is
positive at every cell midpoint but negative at a corner is seen inverted, and one negative only
inside a cell is found at the exact minimum of its quadratic."""

from __future__ import annotations

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

from plantgrowth.base.mesh_samples import MeshSamples, det_degree, quadratic_minima

pytestmark = pytest.mark.mpi  # scripts/README.md, "Tests": every test also runs on 2 ranks

A = -0.7
"""u = (A x1^2, 0): det F = 1 + 2 A x1, -0.4 at x1 = 1, positive at both cells' centroids of
the unit square (x1 = 1/3, 2/3: 0.53, 0.067)."""


def test_det_of_a_p2_field_is_sampled_at_the_corners_not_only_the_midpoint():
    comm = MPI.COMM_WORLD
    msh = mesh.create_unit_square(comm, 1, 1)
    u = fem.Function(fem.VectorFunctionSpace(msh, ("Lagrange", 2)))
    u.interpolate(lambda x: np.stack([A * x[0] ** 2, np.zeros_like(x[0])]))  # exact in P2
    det = ufl.det(ufl.Identity(2) + ufl.grad(u))
    assert det_degree(u) == 2
    samples = MeshSamples(det, msh, det_degree(u))
    values, points = samples.values(), samples.points
    # exact: det is polynomial of degree 2, evaluated at the DG2 nodes (round-off only)
    np.testing.assert_allclose(values, 1.0 + 2.0 * A * points[:, 0], atol=1e-12)
    smallest = comm.allreduce(values.min(initial=np.inf), op=MPI.MIN)
    assert abs(smallest - (1.0 + 2.0 * A)) < 1e-12
    midpoints = MeshSamples(det, msh, 0).values()
    assert comm.allreduce(midpoints.min(initial=np.inf), op=MPI.MIN) > 0.0  # what it missed


def test_det_of_a_p1_field_is_constant_per_cell_one_sample_each():
    msh = mesh.create_unit_square(MPI.COMM_WORLD, 2, 2)
    u = fem.Function(fem.VectorFunctionSpace(msh, ("Lagrange", 1)))
    samples = MeshSamples(ufl.det(ufl.Identity(2) + ufl.grad(u)), msh, det_degree(u))
    assert det_degree(u) == 0
    assert len(samples.points) == msh.topology.index_map(2).size_local
    np.testing.assert_allclose(samples.values(), 1.0, atol=1e-14)


ALPHA = 0.2
"""The review's field (issue 20, item 3): u with F = I + grad u = [[r1 + ALPHA, -r2], [r2, r1 -
ALPHA]], r = x - c for the centroid c of a cell, so det F = |x - c|^2 - ALPHA^2: positive at the
cell's six DG2 nodes, -ALPHA^2 at its centroid."""


def test_an_inversion_inside_a_p2_cell_is_found_at_its_exact_minimum():
    msh = mesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    u = fem.Function(fem.VectorFunctionSpace(msh, ("Lagrange", 2)))
    samples = MeshSamples(ufl.det(ufl.Identity(2) + ufl.grad(u)), msh, det_degree(u))
    c = msh.geometry.x[msh.geometry.dofmap.links(0), :2].mean(axis=0)
    u.interpolate(lambda x: np.stack([  # exact in P2
        (x[0] - c[0]) ** 2 / 2 + (ALPHA - 1) * x[0] - (x[1] - c[1]) ** 2 / 2,
        (x[0] - c[0]) * (x[1] - c[1]) - (ALPHA + 1) * x[1],
    ]))  # fmt: skip
    assert samples.values().min() > 0.0  # the nodes miss it
    minima, places = samples.cell_minima()
    # exact to round-off: the quadratic through the six nodes is det F itself
    assert abs(minima[0] + ALPHA**2) < 1e-12
    np.testing.assert_allclose(places[0], c, atol=1e-9)


def test_cell_minima_are_the_minima_of_random_quadratics():
    """Against a barycentric grid of spacing 1/400: never above the grid's minimum, and attained
    at the returned place (1e-9: round-off of the 6 x 6 fit in centred, scaled coordinates)."""
    rng = np.random.default_rng(20)
    for _ in range(100):
        V = rng.normal(size=(1, 3, 2))
        if abs(np.linalg.det(np.c_[V[0], np.ones(3)])) < 0.1:
            continue
        nodes = np.concatenate([V, 0.5 * (V[:, [1, 2, 0]] + V[:, [2, 0, 1]])], axis=1)
        a = rng.normal(size=6)

        def q(x, a=a):
            X, Y = x[..., 0], x[..., 1]
            return a[0] + a[1] * X + a[2] * Y + a[3] * X * X + a[4] * X * Y + a[5] * Y * Y

        minimum, place = quadratic_minima(nodes, q(nodes), V)
        s, t = np.meshgrid(np.linspace(0, 1, 401), np.linspace(0, 1, 401))
        inside = s + t <= 1.0
        grid = (
            V[0, 0] + s[inside, None] * (V[0, 1] - V[0, 0]) + t[inside, None] * (V[0, 2] - V[0, 0])
        )
        assert minimum[0] <= q(grid).min() + 1e-9
        assert abs(q(place[0]) - minimum[0]) < 1e-9
