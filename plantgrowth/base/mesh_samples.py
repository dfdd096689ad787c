"""A UFL expression sampled at the nodes of a discontinuous space on the owned mesh cells: the
pointwise checks (det F > 0, the walls' ellipticity) at enough points per cell to see a
corner.

``det F`` of a P_k displacement is a polynomial of degree ``2 (k - 1)`` on each triangle:
constant for the macro P1 field (its cell midpoint is exact), quadratic for the micro P2 field,
where DG2's six nodes (vertices and edge midpoints) also see a cell that inverts at a corner
first, which the midpoint misses.
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem, mesh


def det_degree(u: fem.Function) -> int:
    """The polynomial degree of ``det(I + grad u)`` on a triangle for u in P_k (2D):
    ``2 (k - 1)``."""
    return 2 * (u.function_space.ufl_element().degree() - 1)


class MeshSamples:
    """``expr`` at the nodes of DG(``degree``) on this rank's owned cells, and (degree 0 or 2)
    its exact minimum over each cell."""

    def __init__(self, expr: ufl.core.expr.Expr, msh: mesh.Mesh, degree: int) -> None:
        Q = fem.FunctionSpace(msh, ("DG", degree))
        self._function = fem.Function(Q)
        self._expr = fem.Expression(expr, Q.element.interpolation_points())
        owned = msh.topology.index_map(msh.topology.dim).size_local
        per_cell = Q.dofmap.dof_layout.num_dofs
        self._dofs = Q.dofmap.list.array[: owned * per_cell]
        self.points = Q.tabulate_dof_coordinates()[self._dofs, :2]
        """Where the samples are, (n, 2)."""
        self.degree = degree
        geometry = msh.geometry.dofmap.array.reshape(-1, 3)[:owned]  # affine triangles
        self._vertices = msh.geometry.x[geometry, :2]

    @property
    def cell_areas(self) -> np.ndarray:
        """(n_cells,) the owned cells' areas."""
        a, b, c = (self._vertices[:, k] for k in range(3))
        ab, ac = b - a, c - a
        return 0.5 * np.abs(ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0])

    def values(self) -> np.ndarray:
        """The expression at :attr:`points`, evaluated now."""
        self._function.interpolate(self._expr)
        return self._function.x.array[self._dofs]

    def cell_minima(self) -> tuple[np.ndarray, np.ndarray]:
        """The exact minimum of the expression over each owned cell and where it is, (n,) and
        (n, 2): for degree 0 the cell's value; for degree 2 the minimum of the quadratic through
        the six nodes over the closed triangle (:func:`quadratic_minima`)."""
        values = self.values()
        if self.degree == 0:
            return values, self.points
        if self.degree != 2:
            raise ValueError(f"cell_minima: degree {self.degree} is not 0 or 2")
        n = len(self._vertices)
        return quadratic_minima(self.points.reshape(n, 6, 2), values.reshape(n, 6), self._vertices)


def quadratic_minima(
    nodes: np.ndarray, values: np.ndarray, vertices: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Minimum over each triangle of the quadratic ``q`` with ``q(nodes) = values``.

    ``q = a + b x + c y + d x^2 + e x y + f y^2`` in coordinates centred on the triangle's
    centroid and scaled by its size (a well-conditioned 6 x 6 fit per triangle). The minimum of
    a quadratic over a closed triangle is at a vertex, at an edge's interior critical point
    (``q`` along an edge is a parabola), or at the interior critical point ``grad q = 0`` when
    the Hessian is positive definite and that point lies inside: all candidates are compared.

    Args:
        nodes: (n, 6, 2) six distinct points of each triangle that fix a quadratic (the DG2
            nodes: vertices and edge midpoints).
        values: (n, 6) the quadratic's values there.
        vertices: (n, 3, 2) the triangles' vertices.
    Returns:
        (n,) minima and (n, 2) their places.
    """
    centre = vertices.mean(axis=1, keepdims=True)
    size = np.linalg.norm(vertices - centre, axis=2).max(axis=1)[:, None, None]
    size = np.where(size > 0.0, size, 1.0)

    def local(x: np.ndarray) -> np.ndarray:
        return (x - centre) / size

    def basis(x: np.ndarray) -> np.ndarray:  # (n, k, 2) local points -> (n, k, 6)
        X, Y = x[..., 0], x[..., 1]
        return np.stack([np.ones_like(X), X, Y, X * X, X * Y, Y * Y], axis=-1)

    coeff = np.linalg.solve(basis(local(nodes)), values[..., None])[..., 0]  # (n, 6)

    def q(x: np.ndarray) -> np.ndarray:  # (n, k, 2) local -> (n, k)
        return np.einsum("nkj,nj->nk", basis(x), coeff)

    corners = local(vertices)
    candidates = [corners]
    for i, j in ((0, 1), (1, 2), (2, 0)):  # a parabola along each edge: its vertex if inside
        p0, p1 = corners[:, i], corners[:, j]
        mid = 0.5 * (p0 + p1)
        f0, fm, f1 = q(np.stack([p0, mid, p1], axis=1)).T
        curvature = 4.0 * (f0 - 2.0 * fm + f1)  # p(t) = f0 + slope t + curvature t^2 / 2
        slope = 4.0 * fm - 3.0 * f0 - f1
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(curvature > 0.0, -slope / curvature, 0.0)
        t = np.clip(t, 0.0, 1.0)
        candidates.append((p0 + t[:, None] * (p1 - p0))[:, None, :])
    d, e, f = coeff[:, 3], coeff[:, 4], coeff[:, 5]
    hessian = np.stack([np.stack([2 * d, e], -1), np.stack([e, 2 * f], -1)], axis=1)
    det = np.linalg.det(hessian)
    minimum = (det > 0.0) & (hessian[:, 0, 0] > 0.0)
    safe = np.where(minimum[:, None, None], hessian, np.eye(2))
    critical = np.linalg.solve(safe, -coeff[:, 1:3, None])[..., 0]
    bary = np.linalg.solve(  # barycentric coordinates of the critical point
        np.concatenate([np.swapaxes(corners, 1, 2), np.ones((len(coeff), 1, 3))], axis=1),
        np.concatenate([critical, np.ones((len(coeff), 1))], axis=1)[..., None],
    )[..., 0]
    inside = minimum & np.all(bary >= 0.0, axis=1)
    candidates.append(np.where(inside[:, None], critical, corners[:, 0])[:, None, :])
    points = np.concatenate(candidates, axis=1)  # (n, 3 + 3 + 1, 2)
    at = q(points)
    best = np.argmin(at, axis=1)
    rows = np.arange(len(coeff))
    return at[rows, best], points[rows, best] * size[:, 0] + centre[:, 0]
