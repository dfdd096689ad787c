"""The micro model's supports: what removes the walls' rigid motions (docs/real_tissues.md).

A tissue with the symmetry plane x2 = 0 (cut cells): ``u2 = 0`` on the cut cells' sides on it
and ``u1 = 0`` at its leftmost point there (the honeycomb's origin). A free tissue (no side on
x2 = 0, an imported one): ``u = 0`` at its lowest (then leftmost) outer corner A and ``u2 = 0``
at the outer corner B farthest from A along x1. Both hold exactly three rigid motions in 2D and
no more: the loads (turgor on closed membranes, growth's eigenstrain) are self-equilibrated, so
the supports' reactions vanish and the walls deform as if free, up to a rigid motion.
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem, mesh
from petsc4py import PETSc

from plantgrowth.meshes.cell_tissue import CellTissue
from plantgrowth.meshes.tissue import FACET_TAGS


def _at(V: fem.FunctionSpace, point: np.ndarray, tol: float) -> np.ndarray:
    """The mesh's boundary vertex at ``point`` (on whichever ranks hold it)."""
    return mesh.locate_entities_boundary(
        V.mesh, 0, lambda x: (np.abs(x[0] - point[0]) < tol) & (np.abs(x[1] - point[1]) < tol)
    )


def outer_corners(tissue: CellTissue) -> np.ndarray:
    """(k, 2) the polygon vertices on outer walls (sides of one cell only)."""
    ends = [side for side, cells in tissue.cells.sides().items() if len(cells) == 1]
    return tissue.cells.vertices[np.unique(np.array(ends).reshape(-1))]


def supports(V: fem.FunctionSpace, facet_tags: mesh.MeshTags, tissue: CellTissue) -> list:
    """The Dirichlet conditions on the displacement space V (module docstring)."""
    zero, tol = PETSc.ScalarType(0.0), tissue.tolerance
    if tissue.symmetric:
        bottom = facet_tags.indices[facet_tags.values == FACET_TAGS["bottom"]]
        vertices = tissue.cells.vertices
        on_plane = vertices[np.abs(vertices[:, 1]) < tol]
        left = on_plane[np.argmin(on_plane[:, 0])]
        return [
            fem.dirichletbc(zero, fem.locate_dofs_topological(V.sub(1), 1, bottom), V.sub(1)),
            fem.dirichletbc(
                zero, fem.locate_dofs_topological(V.sub(0), 0, _at(V, left, tol)), V.sub(0)
            ),
        ]
    corners = outer_corners(tissue)
    a = corners[np.lexsort((corners[:, 0], corners[:, 1]))[0]]
    b = corners[np.argmax(np.abs(corners[:, 0] - a[0]))]
    at_a, at_b = _at(V, a, tol), _at(V, b, tol)
    return [fem.dirichletbc(zero, fem.locate_dofs_topological(V.sub(k), 0, at_a), V.sub(k))
            for k in (0, 1)] + [
        fem.dirichletbc(zero, fem.locate_dofs_topological(V.sub(1), 0, at_b), V.sub(1))
    ]  # fmt: skip
