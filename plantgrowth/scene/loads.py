"""Edge loads of a scene (``[loads]``, docs/model.md section 4), model = "macro" only, of two kinds:

- a traction ``[f1, f2]`` per unit length of the edge as the forms see it: the grown length
  (``Jg |Fg^-T N|`` times the reference length) with linear kinematics, the current length
  (``|cof(F) N|``) with finite kinematics; each component a number or ``{expr = "..."}``, an
  expression of ``s``, the coordinate along the edge: ``s = x2`` on the left and right edges,
  ``s = x1`` on the top edge (the arc length from the edge's end on x2 = 0, resp. x1 = 0, of the
  macro rectangle). Its resultant follows the edge's length as the tissue grows;
- a force ``{force = [F1, F2]}``: the edge's total force, spread uniformly over that same
  length (:class:`EdgeForce`; how a weight or a clamp pulls), whatever the edge grows to.

An expression's values are checked, and its resultant force computed, with composite
Gauss-Legendre quadrature on the edge (:data:`INTERVALS` intervals of :data:`GAUSS_POINTS`
points): exact to round-off for smooth loads; at a jump (``where``) the resultant is off by at
most ``jump * length / INTERVALS``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from plantgrowth.scene.expression import Expression
from plantgrowth.scene.fields import check_value

VARIABLES = ("s",)
ALONG = {"left": 1, "right": 1, "top": 0}
"""The coordinate (0: x1, 1: x2) that ``s`` is on each loadable edge."""
INTERVALS = 2000
GAUSS_POINTS = 5

Component = float | Expression


@dataclass(frozen=True)
class EdgeForce:
    """An edge's total force ``[F1, F2]``, spread uniformly over the edge's length."""

    force: tuple[float, float]


Load = tuple[Component, Component] | EdgeForce
"""What ``loads.<edge>`` holds."""


def x1_resultant(load: Load, length: float) -> float:
    """The x1 force of a load on an edge of reference length ``length``, before any growth."""
    if isinstance(load, EdgeForce):
        return load.force[0]
    return resultant(load[0], length)


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


def to_toml(load: Load) -> list | dict:
    """A load as the scene file writes it."""
    if isinstance(load, EdgeForce):
        return {"force": list(load.force)}
    return [c if not isinstance(c, Expression) else {"expr": c.text} for c in load]
