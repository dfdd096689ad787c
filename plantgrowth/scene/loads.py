"""Edge loads of a scene (``[loads]``, docs/model.md section 4): each component of an edge's
traction is a number or ``{expr = "..."}``, an expression of ``s``, the coordinate along the edge:
``s = x2`` on the left and right edges, ``s = x1`` on the top edge (the arc length from the edge's
end on x2 = 0, resp. x1 = 0, of the macro rectangle; loads exist for model = "macro" only).

An expression's values are checked, and its resultant force computed, with composite
Gauss-Legendre quadrature on the edge (:data:`INTERVALS` intervals of :data:`GAUSS_POINTS`
points): exact to round-off for smooth loads; at a jump (``where``) the resultant is off by at
most ``jump * length / INTERVALS``.
"""

from __future__ import annotations

import numpy as np

from plantgrowth.scene.expression import Expression
from plantgrowth.scene.fields import check_value

VARIABLES = ("s",)
ALONG = {"left": 1, "right": 1, "top": 0}
"""The coordinate (0: x1, 1: x2) that ``s`` is on each loadable edge."""
INTERVALS = 2000
GAUSS_POINTS = 5

Component = float | Expression


def _quadrature(length: float) -> tuple[np.ndarray, np.ndarray]:
    """Points s and weights of the composite Gauss-Legendre rule on [0, length]."""
    t, w = np.polynomial.legendre.leggauss(GAUSS_POINTS)
    h = length / INTERVALS
    left = np.arange(INTERVALS)[:, None] * h
    return (left + (t + 1.0) * h / 2).ravel(), np.tile(w * h / 2, INTERVALS)


def check_component(key: str, component: Component, length: float, bound: float) -> None:
    """SceneError naming ``key`` and the place unless the component is finite with magnitude
    below ``bound`` at the ends of the edge and at the quadrature points."""
    if not isinstance(component, Expression):
        return
    s = np.concatenate([[0.0, length], _quadrature(length)[0]])
    values = component(s=s)
    bad = np.flatnonzero(~np.isfinite(values) | (np.abs(values) >= bound))
    if bad.size:
        i = bad[np.argmin(s[bad])]
        check_value(key, float(values[i]), -bound, bound, place=f"at s = {s[i]:.6g}")


def resultant(component: Component, length: float) -> float:
    """``int_0^length f(s) ds`` (exact for a number, quadrature for an expression)."""
    if not isinstance(component, Expression):
        return component * length
    s, weights = _quadrature(length)
    return float(weights @ component(s=s))


def to_toml(component: Component) -> float | dict[str, str]:
    return component if not isinstance(component, Expression) else {"expr": component.text}
