"""Periodic multi-point constraints for a unit-cell mesh (dolfinx_mpc).

Side dofs are constrained to the opposite side without the corners; corners, where several
periodic pairs meet, are constrained on their own to one master corner per lattice class, which
is no slave anywhere (dolfinx_mpc issue #21; docs/model.md section 2).
"""

from __future__ import annotations

import dolfinx_mpc
import numpy as np
from dolfinx import fem

from plantgrowth.meshes.unit_cell import PeriodicDomain


def _near_points(x: np.ndarray, points: list[np.ndarray], tol: float) -> np.ndarray:
    near = np.zeros(x.shape[1], dtype=bool)
    for p in points:
        near |= np.hypot(x[0] - p[0], x[1] - p[1]) < tol
    return near


def _on_segment(x: np.ndarray, p: np.ndarray, q: np.ndarray, tol: float) -> np.ndarray:
    d = q - p
    t = ((x[0] - p[0]) * d[0] + (x[1] - p[1]) * d[1]) / (d @ d)
    dist = np.hypot(p[0] + t * d[0] - x[0], p[1] + t * d[1] - x[1])
    return (dist < tol) & (t > -tol) & (t < 1 + tol)


def periodic_constraint(
    V: fem.FunctionSpace, domain: PeriodicDomain, bcs: list, tol: float
) -> dolfinx_mpc.MultiPointConstraint:
    """Finalized constraint ``u(x) = u(x + shift)`` for every slave side and slave corner.

    Args:
        V: the (vector) function space.
        domain: the fundamental domain with its side pairs and corner classes.
        bcs: Dirichlet conditions (their dofs are neither slaves nor masters).
        tol: geometric tolerance for locating dofs (a small fraction of the mesh size).
    """
    corners = [c.point for c in domain.corners] + [
        p for side in domain.sides for p in (side.p, side.q)
    ]
    mpc = dolfinx_mpc.MultiPointConstraint(V)
    for side in domain.sides:

        def indicator(x, side=side):
            return _on_segment(x, side.p, side.q, tol) & ~_near_points(x, corners, tol)

        def relation(x, shift=side.shift):
            y = x.copy()
            y[0] += shift[0]
            y[1] += shift[1]
            return y

        mpc.create_periodic_constraint_geometrical(V, indicator, relation, bcs)

    slave_corners = list(domain.corners)

    def corner_indicator(x):
        return _near_points(x, [c.point for c in slave_corners], tol)

    def corner_relation(x):
        y = x.copy()
        for c in slave_corners:
            near = _near_points(x, [c.point], tol)
            y[0, near] += c.shift[0]
            y[1, near] += c.shift[1]
        return y

    mpc.create_periodic_constraint_geometrical(V, corner_indicator, corner_relation, bcs)
    mpc.finalize()
    return mpc
