"""A UFL expression sampled at the nodes of a discontinuous space on the owned mesh cells: the
pointwise checks (det F > 0, the elastic stretch floor) at enough points per cell to see a
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
    """``expr`` at the nodes of DG(``degree``) on this rank's owned cells."""

    def __init__(self, expr: ufl.core.expr.Expr, msh: mesh.Mesh, degree: int) -> None:
        Q = fem.FunctionSpace(msh, ("DG", degree))
        self._function = fem.Function(Q)
        self._expr = fem.Expression(expr, Q.element.interpolation_points())
        owned = msh.topology.index_map(msh.topology.dim).size_local
        per_cell = Q.dofmap.dof_layout.num_dofs
        self._dofs = Q.dofmap.list.array[: owned * per_cell]
        self.points = Q.tabulate_dof_coordinates()[self._dofs, :2]
        """Where the samples are, (n, 2)."""

    def values(self) -> np.ndarray:
        """The expression at :attr:`points`, evaluated now."""
        self._function.interpolate(self._expr)
        return self._function.x.array[self._dofs]
