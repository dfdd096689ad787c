"""The fibre director of the micro model (docs/fibres.md): a state variable per biological cell.

Each cell carries the angle a (degrees from x1, grown frame; ``m = (cos a, sin a)``), initially
the scene's ``walls.fibre_angle`` at the cell's centre, and ``E_f = fibre_stiffness E`` at the
centre, like the cell's E. Each cell owns the half of every wall between its mid-line hexagon and
its void, so each half of a shared wall carries its own cell's m and E_f.

The reference tangent t of the wall tensor ``C_w = C_iso + E_f (m . t_g)^2 t_g^4`` is constant
per mesh triangle: that of the side of the cell's own mid-line hexagon nearest to the triangle's
midpoint. The walls mesh is not split along the corners' bisectors, so the triangles that the
bisectors cross take one family whole: a wrong tangent on O(h w) of wall area per corner, an O(h)
error in the cell's averages (docs/fibres.md, the micro model).

With ``[feedback]`` the director turns after each step toward the principal direction of the
cell's cue, its own-wall stress or elastic strain average (:meth:`MicroDirector.turn`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from dolfinx import fem, mesh

from plantgrowth.forms.elasticity import Fibres
from plantgrowth.meshes.tissue import TissueLayout
from plantgrowth.models import fibres
from plantgrowth.scene.walls import Feedback, Walls


def nearest_sides(hexagons: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(n,) the side k (from vertex k to vertex k + 1 mod 6) of ``hexagons[i]`` (n, 6, 2) nearest
    to ``points[i]`` (n, 2): ``argmin_k |p_k + s (q_k - p_k) - x|``, s clipped to [0, 1]."""
    p, q = hexagons, np.roll(hexagons, -1, axis=1)
    d = q - p
    s = np.clip(np.einsum("nki,nki->nk", points[:, None] - p, d) / np.sum(d * d, axis=2), 0, 1)
    return np.argmin(np.linalg.norm(p + s[..., None] * d - points[:, None], axis=2), axis=1)


def side_tangents(hexagons: np.ndarray, sides: np.ndarray) -> np.ndarray:
    """(n, 2) unit tangent of the side ``sides[i]`` of ``hexagons[i]`` (n, 6, 2)."""
    rows = np.arange(len(sides))
    d = hexagons[rows, (sides + 1) % 6] - hexagons[rows, sides]
    return d / np.linalg.norm(d, axis=1)[:, None]


class MicroDirector:
    """The director and fibre stiffness per biological cell, and the wall tangents per mesh cell.

    Args:
        walls: the scene's fibred walls.
        feedback: the scene's feedback (None: a fixed director).
        layout: the micro tissue.
        msh: the walls mesh.
        cell_id: (n_owned,) the biological cell of each owned mesh cell.
        E: (n_cells,) the cells' Young's moduli.
        set_values: sets a DG0 function from values per biological cell.
    """

    def __init__(
        self, walls: Walls, feedback: Feedback | None, layout: TissueLayout, msh: mesh.Mesh,
        cell_id: np.ndarray, E: np.ndarray,
        set_values: Callable[[fem.Function, np.ndarray], None],
    ) -> None:  # fmt: skip
        self.feedback = feedback
        centres = layout.centres.T
        self.angle = fibres.reduce_angle(
            np.broadcast_to(walls.fibre_angle(*centres), layout.n_cells)
        )
        self._set = set_values
        scalar = fem.FunctionSpace(msh, ("DG", 0))
        vector = fem.VectorFunctionSpace(msh, ("DG", 0))
        self.stiffness = fem.Function(scalar, name="fibre_stiffness")
        set_values(self.stiffness, walls.fibre_stiffness(*centres) * E)
        self.m = fem.Function(vector, name="fibre_director")
        self.tangent = fem.Function(vector, name="wall_tangent")
        n_owned = len(cell_id)
        hexagons = np.stack(
            [layout.delta_s * layout.cell.hexagon() + c for c in layout.centres]
        )  # uncut: the bottom row's cut at x2 = 0 is a symmetry plane, not a wall
        midpoints = mesh.compute_midpoints(msh, 2, np.arange(n_owned, dtype=np.int32))[:, :2]
        self.side = nearest_sides(hexagons[cell_id], midpoints)
        """(n_owned,) the side of its cell's hexagon each owned wall triangle belongs to."""
        dofs = vector.dofmap.list.array[:n_owned]
        self.tangent.x.array.reshape(-1, 2)[dofs] = side_tangents(hexagons[cell_id], self.side)
        self.tangent.x.scatter_forward()
        self._fill()

    def _fill(self) -> None:
        self._set(self.m, fibres.director(self.angle))

    @property
    def fibres(self) -> Fibres:
        """The UFL coefficients of the wall tensor's fibre part."""
        return Fibres(self.stiffness, self.m, self.tangent)

    def turn(self, Q: np.ndarray, dt: float) -> None:
        """The feedback's exact step over dt: each cell's director turns toward the principal
        direction of its cue Q (n_cells, 2, 2),
        ``tan(a_new - a_Q) = tan(a - a_Q) exp(-k A dt)``
        (:func:`plantgrowth.models.fibres.turn_director`). Nothing without feedback."""
        if self.feedback is not None:
            self.angle = fibres.follow_cue(self.angle, Q, self.feedback.rate, dt)
            self._fill()

    def restore(self, angle: np.ndarray) -> None:
        """The saved director (n_cells,)."""
        self.angle = np.asarray(angle, dtype=float).reshape(-1)
        self._fill()
