"""The pointwise checks' sample points (plantgrowth.base.mesh_samples): a P2 field whose det F is
positive at every cell midpoint but negative at a corner is seen inverted."""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI

from plantgrowth.base.mesh_samples import MeshSamples, det_degree

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
