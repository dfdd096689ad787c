"""The balance of a scene's edge loads along x1 (docs/model.md section 4): when only the pinned
point holds the tissue along x1 (no held edge holds u1: Scene.pinned), the tractions' x1 resultant
must vanish."""

from __future__ import annotations

from plantgrowth.scene.loads import EdgeForce, Load, x1_resultant

LOAD_BALANCE_TOLERANCE = 1e-6
"""Largest accepted net x1 force, relative to the largest single edge force along x1."""


def unbalanced_load(
    loads: dict[str, Load],
    lengths: dict[str, tuple[float, str]],
    pin: tuple[float, float] = (0.0, 0.0),
    fix_edge: str = "left",
) -> str:
    """Why the tractions (docs/model.md section 4) leave a net x1 force on the reference tissue (''
    if they do not). The symmetry plane x2 = 0 carries x2 forces; along x1 only the pinned point
    holds the tissue, so the x1 forces must balance:
    ``sum over the loaded edges of f[0] * length = 0`` (rectangle: ``f_left[0] height +
    f_right[0] height + f_top[0] width``; for a load that varies along its edge, the
    integral of f[0] over the edge: plantgrowth.scene.loads.resultant).

    Args:
        loads: edge -> traction f or total force.
        lengths: every loadable edge -> (reference length, its name in the message).
        pin: the pinned point.
        fix_edge: the edge whose load the message suggests changing.
    """
    forces = {edge: x1_resultant(load, lengths[edge][0]) for edge, load in loads.items()}
    net = sum(forces.values())
    largest = max((abs(v) for v in forces.values()), default=0.0)
    if abs(net) <= LOAD_BALANCE_TOLERANCE * largest:
        return ""
    tractions = [f for f in loads.values() if not isinstance(f, EdgeForce)]
    varying = any(not isinstance(c, float) for f in tractions for c in f)
    old = loads.get(fix_edge, (0.0, 0.0))
    if isinstance(old, EdgeForce):
        fix = f"loads.{fix_edge} = {{force = [{old.force[0] - net:.10g}, {old.force[1]:.10g}]}}"
    elif isinstance(old[0], float) and isinstance(old[1], float):
        fix = f"loads.{fix_edge} = [{old[0] - net / lengths[fix_edge][0]:.10g}, {old[1]:.10g}]"
    else:
        fix = f"add {-net / lengths[fix_edge][0]:.10g} to loads.{fix_edge}[0]"
    formula = " + ".join(
        f"F_{e}[0]" if isinstance(loads[e], EdgeForce) else f"f_{e}[0] * {lengths[e][1]}"
        for e in lengths
        if e in loads
    )
    where = "origin" if pin == (0.0, 0.0) else f"point ({pin[0]:g}, {pin[1]:g})"
    return (
        f"loads: net x1 force {formula}"
        f"{' (integrals over the edges for the expressions)' if varying else ''} = {net:.6g}, "
        f"not 0 (relative tolerance {LOAD_BALANCE_TOLERANCE:g}): only the pinned {where} holds "
        f"the tissue along x1 and would carry it; balance the x1 components, e.g. {fix} (x2 "
        "loads are carried by the symmetry plane x2 = 0), or hold an edge that carries the net "
        'force, e.g. supports.<edge> = "clamped"'
    )
