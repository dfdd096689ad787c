"""Deformed area and first moment of each biological cell of the micro tissue (cells.csv).

A cell is its own walls and its void (at reference: its mid-line hexagon). With X = x + u and
F = I + grad u, over the reference walls and, by Green's theorem, over the membrane Gamma that
bounds the void (n: the walls' outward normal, which points into the void, so that
``dX = F t ds`` with t = (-n2, n1) runs round the void clockwise, hence the minus signs):
``area = int_walls det F dx - 1/2 int_Gamma (X1 dX2 - X2 dX1)``,
``moment = int_walls X det F dx - int_Gamma (X1^2/2 dX2, -X2^2/2 dX1)``.
A cut bottom cell's void is closed by the symmetry line x2 = 0, where X2 = 0 and dX2 = 0: it
adds nothing. Tested with a DG0 test function, each form gives per-mesh-cell contributions that
sum to the biological cells' values; over all cells the areas add up to the area enclosed by the
deformed outer boundary (``micro.enclosed_area_form``).
"""

from __future__ import annotations

import ufl


def _deformed(u, n):
    X = ufl.SpatialCoordinate(u.ufl_function_space().mesh) + u
    F = ufl.Identity(2) + ufl.grad(u)
    dX = ufl.dot(F, ufl.as_vector([-n[1], n[0]]))
    return X, F, dX


def deformed_area_form(u, q, n, dx, ds_membrane) -> ufl.Form:
    """Per mesh cell (q a DG0 scalar test function) the deformed area of walls and void."""
    X, F, dX = _deformed(u, n)
    void = -0.5 * (X[0] * dX[1] - X[1] * dX[0])
    return q * ufl.det(F) * dx + q * void * ds_membrane


def deformed_moment_form(u, r, n, dx, ds_membrane) -> ufl.Form:
    """Per mesh cell (r a DG0 vector test function) the first moment ``int X dA`` of walls and
    void in the deformed configuration."""
    X, F, dX = _deformed(u, n)
    void = ufl.as_vector([-0.5 * X[0] ** 2 * dX[1], 0.5 * X[1] ** 2 * dX[0]])
    return ufl.inner(X, r) * ufl.det(F) * dx + ufl.inner(void, r) * ds_membrane
