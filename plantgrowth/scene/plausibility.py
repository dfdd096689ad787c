"""Scenes a run should not be trusted with: unbalanced loads (an error) and implausible
parameters (warnings: the run goes on). The states of a run's steps are watched by
:mod:`plantgrowth.runner.step_warnings`.

The model is non-dimensional (MODEL.md sections 1, 4, 9: wall E = 1, turgor P1 = 0.001).
Warnings, before anything runs:

- a non-zero ``P1 / E`` outside ``P1_OVER_E`` ([1e-5, 1e-1]): usually P1 and E in different units;
- ``cell.theta`` below ``MIN_THETA`` (5 degrees): usually radians where degrees are expected.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from plantgrowth.scene.loads import resultant

if TYPE_CHECKING:
    from plantgrowth.scene.schema import Scene

P1_OVER_E = (1e-5, 1e-1)
MIN_THETA = 5.0  # degrees
LOAD_BALANCE_TOLERANCE = 1e-6
"""Largest accepted net x1 force, relative to the largest single edge force along x1."""


def unbalanced_load(
    loads: dict[str, tuple],
    lengths: dict[str, tuple[float, str]],
    pin: tuple[float, float] = (0.0, 0.0),
    fix_edge: str = "left",
) -> str:
    """Why the tractions (MODEL.md 4) leave a net x1 force on the reference tissue ('' if they
    do not). The symmetry plane x2 = 0 carries x2 forces; along x1 only the pinned point holds
    the tissue, so the x1 forces must balance: ``sum over the loaded edges of f[0] * length = 0``
    (rectangle: ``f_left[0] height + f_right[0] height + f_top[0] width``; for a load that
    varies along its edge, the integral of f[0] over the edge: plantgrowth.scene.loads.resultant).

    Args:
        loads: edge -> traction f.
        lengths: every loadable edge -> (reference length, its name in the message).
        pin: the pinned point.
        fix_edge: the edge whose load the message suggests changing.
    """
    forces = {edge: resultant(f[0], lengths[edge][0]) for edge, f in loads.items()}
    net = sum(forces.values())
    largest = max((abs(v) for v in forces.values()), default=0.0)
    if abs(net) <= LOAD_BALANCE_TOLERANCE * largest:
        return ""
    varying = any(not isinstance(c, float) for f in loads.values() for c in f)
    old = loads.get(fix_edge, (0.0, 0.0))
    if isinstance(old[0], float) and isinstance(old[1], float):
        fix = f"loads.{fix_edge} = [{old[0] - net / lengths[fix_edge][0]:.10g}, {old[1]:.10g}]"
    else:
        fix = f"add {-net / lengths[fix_edge][0]:.10g} to loads.{fix_edge}[0]"
    formula = " + ".join(f"f_{e}[0] * {lengths[e][1]}" for e in lengths if e in loads)
    where = "origin" if pin == (0.0, 0.0) else f"point ({pin[0]:g}, {pin[1]:g})"
    return (
        f"loads: net x1 force {formula}"
        f"{' (integrals over the edges for the expressions)' if varying else ''} = {net:.6g}, "
        f"not 0 (relative tolerance {LOAD_BALANCE_TOLERANCE:g}): only the pinned {where} holds "
        f"the tissue along x1 and would carry it; balance the x1 components, e.g. {fix} (x2 "
        "loads are carried by the symmetry plane x2 = 0)"
    )


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
