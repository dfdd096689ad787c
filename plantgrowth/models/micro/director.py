"""The fibre director of the micro model (docs/fibres.md): a state variable per biological cell.

Each cell carries the angle a (degrees from x1, grown frame; ``m = (cos a, sin a)``), initially
the scene's ``walls.fibre_angle`` at the cell's centre, and ``E_f = fibre_stiffness E`` at the
centre, like the cell's E. Each cell owns the half of every wall between its mid-line polygon and
its void, so each half of a shared wall carries its own cell's m and E_f.

The reference tangent t of the wall tensor ``C_w = C_iso + E_f (m . t_g)^2 t_g^4`` is constant
per mesh triangle: that of the side of the cell's own whole mid-line polygon (a cut cell's
united with its mirror image, :meth:`CellTissue.outline`) nearest to the triangle's midpoint.
The walls mesh is not split along the corners' bisectors, so the triangles that the bisectors
cross take one family whole: a wrong tangent on O(h w) of wall area per corner, an O(h) error in
the cell's averages (docs/fibres.md, the micro model).

With ``[feedback]`` the director turns after each step toward the principal direction of the
cell's cue, its own-wall stress or elastic strain average (:meth:`MicroDirector.turn`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from dolfinx import fem, mesh

from plantgrowth.forms.elasticity import Fibres
from plantgrowth.meshes.cell_tissue import CellTissue
from plantgrowth.models import fibres
from plantgrowth.scene.walls import Feedback, Walls


def padded_outlines(tissue: CellTissue) -> tuple[np.ndarray, np.ndarray]:
    """(n, S, 2) each cell's whole outline, S the most sides of any, padded with copies of its
    first vertex (sides of length 0, never nearest), and (n,) each outline's number of sides."""
    loops = [tissue.outline(i) for i in range(tissue.n_cells)]
    counts = np.array([len(loop) for loop in loops])
    out = np.empty((len(loops), counts.max(), 2))
    for i, loop in enumerate(loops):
        out[i, : len(loop)], out[i, len(loop) :] = loop, loop[0]
    return out, counts


def nearest_sides(polygons: np.ndarray, counts: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(n,) the side k (from vertex k to vertex k + 1 mod counts[i]) of ``polygons[i]`` (n, S, 2,
    padded as :func:`padded_outlines`) nearest to ``points[i]`` (n, 2):
    ``argmin_k |p_k + s (q_k - p_k) - x|``, s clipped to [0, 1]."""
    p, q = polygons, np.roll(polygons, -1, axis=1)
    d = q - p
    length2 = np.sum(d * d, axis=2)
    real = np.arange(polygons.shape[1])[None] < counts[:, None]
    s = np.einsum("nki,nki->nk", points[:, None] - p, d) / np.where(real, length2, 1.0)
    distance = np.linalg.norm(p + np.clip(s, 0, 1)[..., None] * d - points[:, None], axis=2)
    return np.argmin(np.where(real, distance, np.inf), axis=1)


def side_tangents(polygons: np.ndarray, sides: np.ndarray) -> np.ndarray:
    """(n, 2) unit tangent of the side ``sides[i]`` of ``polygons[i]`` (n, S, 2, padded)."""
    rows = np.arange(len(sides))
    d = polygons[rows, (sides + 1) % polygons.shape[1]] - polygons[rows, sides]
    return d / np.linalg.norm(d, axis=1)[:, None]


class MicroDirector:
    """The director and fibre stiffness per biological cell, and the wall tangents per mesh cell.

    Args:
        walls: the scene's fibred walls.
        feedback: the scene's feedback (None: a fixed director).
        tissue: the micro tissue.
        msh: the walls mesh.
        cell_id: (n_owned,) the biological cell of each owned mesh cell.
        E: (n_cells,) the cells' Young's moduli.
        set_values: sets a DG0 function from values per biological cell.
    """

    def __init__(
        self, walls: Walls, feedback: Feedback | None, tissue: CellTissue, msh: mesh.Mesh,
        cell_id: np.ndarray, E: np.ndarray,
        set_values: Callable[[fem.Function, np.ndarray], None],
    ) -> None:  # fmt: skip
        self.feedback = feedback
        centres = tissue.centres.T
        self.angle = fibres.reduce_angle(
            np.broadcast_to(walls.fibre_angle(*centres), tissue.n_cells)
        )
        self._set = set_values
        scalar = fem.FunctionSpace(msh, ("DG", 0))
        vector = fem.VectorFunctionSpace(msh, ("DG", 0))
        self.stiffness = fem.Function(scalar, name="fibre_stiffness")
        set_values(self.stiffness, walls.fibre_stiffness(*centres) * E)
        self.m = fem.Function(vector, name="fibre_director")
        self.tangent = fem.Function(vector, name="wall_tangent")
        n_owned = len(cell_id)
        # whole outlines: the cut at x2 = 0 is a symmetry plane, not a wall
        outlines, counts = padded_outlines(tissue)
        midpoints = mesh.compute_midpoints(msh, 2, np.arange(n_owned, dtype=np.int32))[:, :2]
        self.side = nearest_sides(outlines[cell_id], counts[cell_id], midpoints)
        """(n_owned,) the side of its cell's outline each owned wall triangle belongs to."""
        dofs = vector.dofmap.list.array[:n_owned]
        self.tangent.x.array.reshape(-1, 2)[dofs] = side_tangents(outlines[cell_id], self.side)
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
