"""The coarse grid M of the coupled loop (plantgrowth/models/macro/coarse.py,
docs/model.md section 5).

Pure numpy/scipy on replicated data; the only collective is the split-over-ranks check of
``project_to_nodes``, which every rank reaches. Tolerances are round-off: the interpolation and
the projection are a few flops per point on O(1)..O(10) coordinates.
"""

import numpy as np
import pytest
from mpi4py import MPI

from plantgrowth.models.macro.coarse import CoarseGrid, project_to_nodes

WIDTH, HEIGHT = 6.928203230275509, 3.0  # the reference tissue (docs/model.md section 9)
RNG_SEED = 12345


def linear(points: np.ndarray) -> np.ndarray:
    return 0.7 - 1.3 * points[:, 0] + 2.1 * points[:, 1]


def test_with_edge_picks_the_closest_grid():
    grid = CoarseGrid.with_edge(WIDTH, HEIGHT, 1.0)
    assert (grid.nx, grid.ny) == (7, 3)
    assert CoarseGrid.with_edge(WIDTH, HEIGHT, 100.0).nx == 1  # at least one cell each way
    nodes = grid.nodes
    assert nodes.shape == (8 * 4, 2)
    assert np.allclose(nodes[[0, 7, 8, 31]], [[0, 0], [WIDTH, 0], [0, 1], [WIDTH, HEIGHT]])


def _test_points(grid: CoarseGrid, rng) -> np.ndarray:
    """Random interior points, points on grid lines and diagonals, nodes and corners."""
    dX, dY = grid.width / grid.nx, grid.height / grid.ny
    random = rng.uniform([0, 0], [grid.width, grid.height], size=(500, 2))
    s = rng.uniform(size=100)
    i = rng.integers(0, grid.nx, size=100)
    j = rng.integers(0, grid.ny, size=100)
    on_vertical = np.column_stack([i * dX, (j + s) * dY])
    on_horizontal = np.column_stack([(i + s) * dX, j * dY])
    # on the diagonals that split the cells (lower-right to upper-left corner)
    on_diagonal = np.column_stack([(i + s) * dX, (j + 1 - s) * dY])
    boundary = np.array([[grid.width, y] for y in s * grid.height] + [[x, grid.height] for x in s])
    corners = np.array([[0, 0], [grid.width, 0], [0, grid.height], [grid.width, grid.height]])
    special = [on_vertical, on_horizontal, on_diagonal, boundary, corners, grid.nodes]
    return np.vstack([random, *special])


@pytest.mark.parametrize("shape", [(7, 3), (1, 1), (5, 8)])
def test_interpolation_is_exact_for_linear_functions(shape):
    grid = CoarseGrid(WIDTH, HEIGHT, *shape)
    points = _test_points(grid, np.random.default_rng(RNG_SEED))
    W = grid.interpolation_matrix(points)
    assert W.shape == (len(points), len(grid.nodes))
    # P1 interpolation reproduces linear functions; values are O(10): round-off ~1e-14
    assert np.allclose(W @ linear(grid.nodes), linear(points), rtol=0, atol=1e-12)
    assert np.allclose(W @ grid.nodes, points, rtol=0, atol=1e-12)
    # barycentric weights of a point inside its triangle are >= 0; on a diagonal, 1 - a - b is
    # computed as (1 - a) - b and can be -1 ulp (measured: -1.1e-16), harmless round-off
    assert W.data.min() >= -4e-16
    assert np.allclose(np.asarray(W.sum(axis=1)).ravel(), 1.0, rtol=0, atol=1e-14)
    assert np.all(np.diff(W.indptr) <= 3)  # three nodes of one coarse triangle


def test_interpolation_at_nodes_is_the_identity():
    grid = CoarseGrid(WIDTH, HEIGHT, 7, 3)
    W = grid.interpolation_matrix(grid.nodes).toarray()
    assert np.allclose(W, np.eye(len(grid.nodes)), rtol=0, atol=1e-14)


def test_interpolation_clamps_points_just_outside():
    """Round-off outside the rectangle (fine-mesh midpoints never are, vertices may) is clamped."""
    grid = CoarseGrid(WIDTH, HEIGHT, 7, 3)
    outside = np.array([[-1e-13, 0.5], [WIDTH + 1e-13, 2.0], [1.0, HEIGHT + 1e-13]])
    clamped = np.clip(outside, 0.0, [WIDTH, HEIGHT])
    W = grid.interpolation_matrix(outside)
    assert np.allclose(W @ linear(grid.nodes), linear(clamped), rtol=0, atol=1e-12)
    assert W.data.min() >= -4e-16  # round-off, see test_interpolation_is_exact_for_linear_...


def _aligned_fine_cells(grid: CoarseGrid, k: int):
    """Midpoints and areas of a structured fine triangulation with k x k squares per coarse cell.

    Each fine square is split along one diagonal, like dolfinx's create_rectangle.
    """
    nx, ny = grid.nx * k, grid.ny * k
    dx, dy = grid.width / nx, grid.height / ny
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    i, j = i.ravel(), j.ravel()
    lower = np.column_stack([(i + 2 / 3) * dx, (j + 1 / 3) * dy])
    upper = np.column_stack([(i + 1 / 3) * dx, (j + 2 / 3) * dy])
    midpoints = np.vstack([lower, upper])
    return midpoints, np.full(len(midpoints), 0.5 * dx * dy)


def test_projection_of_a_constant_is_the_constant():
    grid = CoarseGrid(WIDTH, HEIGHT, 7, 3)
    rng = np.random.default_rng(RNG_SEED)
    # unstructured "fine cells": random midpoints with random areas (the formula is a ratio)
    midpoints = rng.uniform([0, 0], [WIDTH, HEIGHT], size=(5000, 2))
    areas = rng.uniform(0.5, 1.5, size=5000)
    W = grid.interpolation_matrix(midpoints)
    Fg = np.tile([1.2, 0.1, -0.05, 0.9], (5000, 1))
    projected = project_to_nodes(W, areas, Fg, MPI.COMM_SELF)
    assert projected.shape == (len(grid.nodes), 4)
    assert np.allclose(projected, Fg[0], rtol=1e-14, atol=0)  # weights sum over ~100 cells


def test_projection_of_a_linear_field_is_exact_at_interior_nodes_only():
    """The lumped projection F_n = sum W_cn |c| F_c / sum W_cn |c| is a weighted mean.

    Exact at a node for linear F when the weighted first moment sum W_cn |c| (x_c - x_n) vanishes:
    true at interior nodes when the fine cells are aligned with the coarse grid (the hat function
    and the set of fine midpoints are both point-symmetric about the node), false at boundary
    nodes (one-sided support: an O(H) shift towards the interior) and, in general, for a fine mesh
    not aligned with the coarse one (the coupled run's h = 0.35, H = 1: O(h) error).
    """
    grid = CoarseGrid(WIDTH, HEIGHT, 7, 3)
    midpoints, areas = _aligned_fine_cells(grid, 4)
    W = grid.interpolation_matrix(midpoints)
    f = linear(midpoints)[:, None]
    error = np.abs(project_to_nodes(W, areas, f, MPI.COMM_SELF)[:, 0] - linear(grid.nodes))
    nodes = grid.nodes
    interior = (
        (nodes[:, 0] > 0) & (nodes[:, 0] < WIDTH) & (nodes[:, 1] > 0) & (nodes[:, 1] < HEIGHT)
    )
    assert error[interior].max() < 1e-12  # round-off on values O(10)
    # boundary nodes: first order, bounded by |grad f| times a coarse edge
    slope = np.hypot(1.3, 2.1)
    assert error[~interior].max() > 1e-3
    assert error[~interior].max() < slope * max(WIDTH / 7, HEIGHT / 3)

    # a non-aligned fine mesh: interior nodes are first-order accurate, not exact
    midpoints, areas = _aligned_fine_cells(CoarseGrid(WIDTH, HEIGHT, 20, 9), 1)
    W = grid.interpolation_matrix(midpoints)
    error = np.abs(
        project_to_nodes(W, areas, linear(midpoints)[:, None], MPI.COMM_SELF)[:, 0] - linear(nodes)
    )
    assert error[interior].max() < slope * WIDTH / 20


@pytest.mark.mpi
def test_projection_split_over_ranks_equals_the_serial_one():
    """Each rank holds a share of the fine cells (as in the coupled loop); the sums are reduced."""
    comm = MPI.COMM_WORLD
    grid = CoarseGrid(WIDTH, HEIGHT, 7, 3)
    rng = np.random.default_rng(RNG_SEED)  # the same data on every rank
    midpoints = rng.uniform([0, 0], [WIDTH, HEIGHT], size=(3000, 2))
    areas = rng.uniform(0.5, 1.5, size=3000)
    values = rng.normal(size=(3000, 4))
    serial = project_to_nodes(grid.interpolation_matrix(midpoints), areas, values, MPI.COMM_SELF)
    mine = np.arange(comm.rank, 3000, comm.size)
    W = grid.interpolation_matrix(midpoints[mine])
    shared = project_to_nodes(W, areas[mine], values[mine], comm)
    assert np.allclose(shared, serial, rtol=1e-13, atol=1e-13)  # summation order only


def test_nodes_without_a_fine_cell_get_the_mean():
    """A coarse node whose triangles hold no fine cell midpoint (outside the outline of a micro
    tissue, or a fine mesh coarser than the coarse one) is never interpolated back; it gets the
    tissue mean so that its cell problem is well posed. Nodes with cells keep their projection."""
    grid = CoarseGrid(WIDTH, HEIGHT, 7, 3)
    midpoints = np.array([[0.1, 0.1], [0.2, 0.05]])
    W = grid.interpolation_matrix(midpoints)
    values = np.array([[1.0], [3.0]])
    areas = np.array([1.0, 3.0])
    nodes = project_to_nodes(W, areas, values, MPI.COMM_SELF)[:, 0]
    supported = np.asarray(W.sum(axis=0)).ravel() > 0.0
    mean = (1.0 * 1.0 + 3.0 * 3.0) / 4.0  # area-weighted
    assert np.all(nodes[~supported] == pytest.approx(mean, rel=1e-14))
    assert supported.sum() == 3  # the corner triangle's nodes
    assert np.all((nodes[supported] >= 1.0) & (nodes[supported] <= 3.0))
