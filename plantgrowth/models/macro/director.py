"""The fibre director of the macro model (docs/fibres.md): a state variable per fine cell, like Fg.

Each fine cell carries the angle a (degrees from x1, in the grown frame; ``m = (cos a, sin a)``),
initially the scene's ``walls.fibre_angle`` at its midpoint. The walls' ``fibre_stiffness``
(E_f / E) is sampled at the coarse nodes, like nu: it picks the cell problem's table. What the
homogenizer gets:

- surrogate path (``cell_tolerance > 0``): each fine cell's own angle;
- exact path (``cell_tolerance = 0``): the angles at the coarse nodes, by the lumped L2
  projection of the axial vector ``(cos 2a, sin 2a)`` (an angle is an axis, a ~ a + 180, so the
  angles themselves are not averaged), ``a_node = atan2(mean sin 2a, mean cos 2a) / 2``.

With ``[feedback]`` the director turns after each step toward the principal direction of the
step's cue (:meth:`MacroDirector.turn`, the exact step of :func:`plantgrowth.models.fibres.
turn_director`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
from dolfinx import fem
from dolfinx.mesh import Mesh
from mpi4py import MPI

from plantgrowth.models import fibres
from plantgrowth.models.macro.coarse import project_to_nodes
from plantgrowth.scene.walls import Feedback, Walls

FIBRE_FIELD = "fibre_direction"
"""The output field of the director: m as (x1, x2, 0) per fine cell (ParaView's glyphs)."""


class MacroDirector:
    """The director of the fine cells of this rank (ghosts too) and the fibre stiffness of the
    active coarse nodes.

    Args:
        walls: the scene's fibred walls.
        feedback: the scene's feedback (None: a fixed director).
        mesh: the fine mesh (for the output function).
        midpoints: (n_cells, 2) the fine cells' midpoints (owned, then ghosts).
        nodes: (m, 2) the active coarse nodes.
        fields: the scene's ``output.fields``.
    """

    def __init__(
        self, walls: Walls, feedback: Feedback | None, mesh: Mesh, midpoints: np.ndarray,
        nodes: np.ndarray, fields: tuple[str, ...],
    ) -> None:  # fmt: skip
        self.feedback = feedback
        at_cells = np.broadcast_to(walls.fibre_angle(*midpoints.T), len(midpoints))
        self.angle = fibres.reduce_angle(at_cells)
        self.stiffness = np.broadcast_to(walls.fibre_stiffness(*nodes.T), len(nodes)).copy()
        self.function = None
        if FIBRE_FIELD in fields:
            space = fem.VectorFunctionSpace(mesh, ("DG", 0))
            self.function = fem.Function(space, name=FIBRE_FIELD)
        self.anisotropy = None
        if fibres.CUE_FIELD in fields and feedback is not None:
            scalar = fem.FunctionSpace(mesh, ("DG", 0))
            self.anisotropy = fem.Function(scalar, name=fibres.CUE_FIELD)

    @property
    def functions(self) -> list[fem.Function]:
        """The output functions asked for (``fibre_direction``, ``cue_anisotropy``)."""
        return [f for f in (self.function, self.anisotropy) if f is not None]

    def angles_at_nodes(
        self, W_owned: sp.csr_matrix, areas: np.ndarray, active: np.ndarray, comm: MPI.Comm
    ) -> np.ndarray:
        """Collective: the director angles at the active coarse nodes (exact path), from the
        owned cells' weights ``W_owned`` and ``areas``: the axial projection of the module
        docstring."""
        two_a = np.radians(2.0 * self.angle[: len(areas)])
        axial = np.column_stack([np.cos(two_a), np.sin(two_a)])
        mean = project_to_nodes(W_owned, areas, axial, comm)[active]
        return fibres.reduce_angle(0.5 * np.degrees(np.arctan2(mean[:, 1], mean[:, 0])))

    def turn(self, Q: np.ndarray, dt: float) -> None:
        """The feedback's exact step over dt: each cell's director turns toward the principal
        direction of its cue tensor Q (n_cells, 2, 2) (sigma_hom or eps_hom of the step just
        solved), ``tan(a_new - a_Q) = tan(a - a_Q) exp(-k A dt)``
        (:func:`plantgrowth.models.fibres.turn_director`). Nothing without feedback."""
        if self.feedback is not None:
            self.angle = fibres.follow_cue(self.angle, Q, self.feedback.rate, dt)

    def fill(
        self, set_values: Callable[[fem.Function, np.ndarray], None], Q: np.ndarray | None = None
    ) -> None:
        """The output fields asked for: m = (cos a, sin a) per fine cell (the padding to
        (x1, x2, 0) is the XDMF writer's) and the anisotropy A of the step's cue tensors Q
        (n_cells, 2, 2), with feedback."""
        if self.function is not None:
            set_values(self.function, fibres.director(self.angle))
        if self.anisotropy is not None and Q is not None:
            set_values(self.anisotropy, fibres.cue(Q).anisotropy)

    def measures(self, areas: np.ndarray, comm: MPI.Comm) -> dict[str, float]:
        """Collective: summary.csv's ``fibre_order`` and ``fibre_angle_mean`` of the owned
        cells (weights: their reference areas ``areas``)."""
        order, mean = fibres.fibre_statistics(self.angle[: len(areas)], areas, comm)
        return {"fibre_order": order, "fibre_angle_mean": mean}
