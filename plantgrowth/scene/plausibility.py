"""Implausible scene parameters (warnings: the run goes on); unbalanced loads are an error
(:mod:`plantgrowth.scene.load_balance`). The states of a run's steps are watched by
:mod:`plantgrowth.runner.step_warnings`.

The model is non-dimensional (docs/model.md sections 1, 4, 9: wall E = 1, turgor P1 = 0.001).
Warnings, before anything runs:

- a non-zero ``P1 / E`` outside ``P1_OVER_E`` ([1e-5, 1e-1]): usually P1 and E in different units;
- ``cell.theta`` below ``MIN_THETA`` (5 degrees): usually radians where degrees are expected.
"""

from __future__ import annotations

import logging

import numpy as np

from plantgrowth.scene.schema import Scene

P1_OVER_E = (1e-5, 1e-1)
MIN_THETA = 5.0  # degrees

log = logging.getLogger("plantgrowth")


def scene_warnings(scene: Scene) -> list[str]:
    """Warnings about a scene's parameters (P1 / E, theta) at the tissue's corners, before
    anything runs."""
    x1, x2 = np.array(scene.corners()).T
    with np.errstate(all="ignore"):  # an expression may be undefined at a corner never used
        P1, E, theta = scene.P1(x1, x2), scene.material.E(x1, x2), scene.cell.theta(x1, x2)
    ratios = [float(p / e) for p, e in zip(P1, E, strict=True) if p != 0.0 and np.isfinite(p / e)]
    out = []
    low, high = P1_OVER_E
    outside = [r for r in ratios if not low <= r <= high]
    if outside:
        out.append(
            f"pressure.P1 / material.E = {outside[0]:.3g} is outside [{low:g}, {high:g}]: the "
            "model is non-dimensional (wall E = 1, reference turgor P1 = 0.001); are P1 and E "
            "in the same units?"
        )
    theta = float(np.nanmin(theta))
    if theta < MIN_THETA:
        out.append(
            f"cell.theta = {theta:g} degrees is below {MIN_THETA:g}: theta is in degrees "
            f"(radians? {theta:g} rad = {np.degrees(theta):.4g} degrees); such flat walls make "
            "the cell extremely compliant"
        )
    return out


def warn_about(scene: Scene) -> None:
    """Log the scene's implausible parameters as warnings (stderr and run.log, rank 0)."""
    for text in scene_warnings(scene):
        log.warning("warning: %s", text)
