"""Turgor continuation for Newton's solve in finite kinematics (the micro model, and the macro
model without water; docs/real_tissues.md, the micro model on cells).

Newton starts from the linear-kinematics solution (plantgrowth.models.newton). On an irregular
tissue that guess is far off: the walls' network bends under turgor where the honeycomb's is only
stretched, and the linear solution rotates walls by radians (median 1.4 rad at the walls a
linear run flags, r = 0.5, Nx = 4), so Newton can fail at the first step although the finite
problem has an elliptic solution; the macro model from such cells (each cell's own unit cell,
some very soft) can fail likewise (an element inverted at Nx = 8, r = 1, seed 1). Then the solve
is repeated along the turgor ``s P1``, ``s = s_1 < s_2 < ... < 1``, each solve starting from the
last one's solution: the increment starts at :data:`FIRST`, doubles after a success and halves
after a failure, down to :data:`SMALLEST` (then the first failure is raised). A solve that
converges directly is unchanged.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from plantgrowth.base.errors import RunError
from plantgrowth.models.newton import NewtonReport, NewtonSolver

log = logging.getLogger("plantgrowth")

FIRST = 0.25
"""The first turgor increment of the ramp (a fraction of P1)."""
SMALLEST = 1.0 / 256.0
"""The smallest increment tried before the solve is given up."""


def solve_ramped(newton: NewtonSolver, scale: Callable[[float], None]) -> NewtonReport:
    """Collective: ``newton.solve()``; if it fails, the ramp of the module docstring, ``scale(s)``
    setting the turgor to ``s P1`` (left at P1 on return)."""
    u = newton.u.x.array
    start = u.copy()
    try:
        return newton.solve()
    except RunError as e:
        failure = e
    u[:] = start
    done, step, solves = 0.0, FIRST, 0
    try:
        while done < 1.0:
            s = min(1.0, done + step)
            scale(s)
            before = u.copy()
            try:
                report = newton.solve()
            except RunError:
                u[:] = before
                step *= 0.5
                if step < SMALLEST:
                    raise RunError(
                        f"{failure} (also with the turgor ramped up in steps down to "
                        f"{SMALLEST:g} P1, stuck at {done:.4g} P1)"
                    ) from None
                continue
            done, step, solves = s, 2.0 * step, solves + 1
    finally:
        scale(1.0)
    log.warning(
        "warning: Newton failed from the linear guess; solved with the turgor ramped up in %d "
        "steps (docs/real_tissues.md)", solves,
    )  # fmt: skip
    return report
