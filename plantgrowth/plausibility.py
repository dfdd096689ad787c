"""Physics a run should not be trusted with: unbalanced loads (an error) and implausible
parameters or states (warnings: the run goes on).

The model is linear elasticity for small elastic strains on a non-dimensional tissue (MODEL.md
sections 1, 4, 9: wall E = 1, turgor P1 = 0.001). Warnings, each once per run:

- the largest elastic strain of a step exceeds ``MAX_ELASTIC_STRAIN`` (5%);
- the clamp M is active (some ``|G_ij| = M``) on more than ``MAX_CLAMPED_FRACTION`` (10%) of the
  tissue, area-weighted (macro: fine cells, micro: biological cells by their reference areas);
- a non-zero ``P1 / E`` outside ``P1_OVER_E`` ([1e-5, 1e-1]): usually P1 and E in different units;
- ``cell.theta`` below ``MIN_THETA`` (5 degrees): usually radians where degrees are expected.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from mpi4py import MPI

from plantgrowth.loads import resultant

if TYPE_CHECKING:
    from plantgrowth.scene import Scene
    from plantgrowth.timeloop import StepResult

MAX_ELASTIC_STRAIN = 0.05
MAX_CLAMPED_FRACTION = 0.10
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
    varies along its edge, the integral of f[0] over the edge: plantgrowth.loads.resultant).

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


def largest_strain(eps: np.ndarray, comm: MPI.Comm) -> float:
    """Largest principal magnitude of symmetric (n, 2, 2) strains over all ranks."""
    local = float(np.abs(np.linalg.eigvalsh(eps)).max(initial=0.0))
    return comm.allreduce(local, op=MPI.MAX)


def clamped_fraction(G: np.ndarray, clamp: float, weights: np.ndarray, comm: MPI.Comm) -> float:
    """Weighted fraction of growth units where the clamp is active (some ``|G_ij| >= M``);
    ``G`` and ``weights`` are this rank's share (pass MPI.COMM_SELF for replicated values)."""
    hit = np.any(np.abs(G) >= clamp, axis=(1, 2))
    sums = comm.allreduce(np.array([weights[hit].sum(), weights.sum()]), op=MPI.SUM)
    return float(sums[0] / sums[1]) if sums[1] > 0.0 else 0.0


class StepWarnings:
    """Warnings about the state of a run's steps, each kind at most once per run."""

    def __init__(self) -> None:
        self.given: set[str] = set()

    def check(self, step: int, t: float, result: StepResult) -> list[str]:
        """New warnings for this step's result."""
        out = []
        strain, clamped = result.max_elastic_strain, result.clamped_fraction
        if strain is not None and strain > MAX_ELASTIC_STRAIN:
            out += self._once(
                "strain",
                f"step {step}, t = {t:g}: the largest elastic strain is {strain:.3g} (more than "
                f"{MAX_ELASTIC_STRAIN:.0%}): the model is linear elasticity for small strains, so "
                "the results are not reliable (pressure, loads, E or Fg0 too large?)",
            )
        if clamped is not None and clamped > MAX_CLAMPED_FRACTION:
            out += self._once(
                "clamp",
                f"step {step}, t = {t:g}: the clamp growth.clamp = M is active on {clamped:.0%} "
                f"of the tissue (more than {MAX_CLAMPED_FRACTION:.0%}, area-weighted): the "
                "growth rate there is M, not the growth law's (raise M or lower eta)",
            )
        return out

    def _once(self, kind: str, text: str) -> list[str]:
        if kind in self.given:
            return []
        self.given.add(kind)
        return [text]
