"""Implausible scene parameters (warnings: the run goes on); unbalanced loads are an error
(:mod:`plantgrowth.scene.load_balance`). The states of a run's steps are watched by
:mod:`plantgrowth.runner.step_warnings`.

The model is non-dimensional (docs/model.md sections 1, 4, 9: wall E = 1, turgor P1 = 0.001).
Warnings, before anything runs:

- a non-zero ``P1 / E`` outside ``P1_OVER_E`` ([1e-5, 1e-1]): usually P1 and E in different units;
- an angle key (``ANGLES``: ``cell.theta``, ``walls.fibre_angle``) other than 0 but below
  ``MIN_ANGLE`` (5 degrees) in magnitude: usually radians where degrees are expected (pi / 2 =
  1.5708 for 90 degrees).
"""

from __future__ import annotations

import logging

import numpy as np

from plantgrowth.scene.schema import Scene

P1_OVER_E = (1e-5, 1e-1)
MIN_ANGLE = 5.0
"""Degrees: a non-zero angle key smaller in magnitude is likely radians (a radian value of a
right angle or less, pi / 2 = 1.5708, is below it; so are pi and 2 pi / 3)."""
ANGLES = {
    "cell.theta": "such flat walls make the cell extremely compliant",
    "walls.fibre_angle": "the fibres then lie almost along x1",
}
"""Every angle key of a scene (degrees) -> what so small a value means."""

log = logging.getLogger("plantgrowth")


def scene_warnings(scene: Scene) -> list[str]:
    """Warnings about a scene's parameters (P1 / E, the angles) at the tissue's corners,
    before anything runs."""
    x1, x2 = np.array(scene.corners()).T
    with np.errstate(all="ignore"):  # an expression may be undefined at a corner never used
        P1, E = scene.P1(x1, x2), scene.material.E(x1, x2)
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
    fields = scene.parameter_fields()
    for key in (k for k in ANGLES if k in fields):
        with np.errstate(all="ignore"):
            values = np.broadcast_to(fields[key](x1, x2), x1.shape)
        out += [radians_hint(key, float(a)) for a in values if 0.0 < abs(a) < MIN_ANGLE][:1]
    return out


def radians_hint(key: str, angle: float) -> str:
    """The warning of an angle key (degrees) whose value looks like radians."""
    return (
        f"{key} = {angle:g} degrees is below {MIN_ANGLE:g} in magnitude: {key} is in degrees "
        f"(radians? {angle:g} rad = {np.degrees(angle):.4g} degrees); {ANGLES[key]}"
    )


def warn_about(scene: Scene) -> None:
    """Log the scene's implausible parameters as warnings (stderr and run.log, rank 0)."""
    for text in scene_warnings(scene):
        log.warning("warning: %s", text)
