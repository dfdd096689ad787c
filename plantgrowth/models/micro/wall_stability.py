"""Strong ellipticity of the walls' St Venant-Kirchhoff law at the micro model's P2 sample
points (issue 20, item 2; plantgrowth.models.stability).

At the six DG2 nodes of each owned wall triangle: the elastic deformation ``Fe = (I + grad u)
Fg^-1`` (finite kinematics) or the stretch ``sqrt(I + 2 eps_el)`` of the linear elastic strain,
the wall's own tensor and the normalised smallest acoustic eigenvalue there. A triangle is
non-elliptic where one of its samples is.

The wall's tensor is the one its equations use (docs/model.md, fibre-reinforced walls):
``C_w = C_iso(E, nu) + E_f q (t_g x t_g x t_g x t_g)`` on fibred walls, both in ``S = C_w Ee``
and as the tangent. The isotropic law alone is not conservative there: a wall compressed along
its fibres (q = 1) to a stretch of 0.9 is elliptic under C_iso (smallest acoustic eigenvalue
+0.274 E, E_f = 5 E, nu = 0.3) and not under C_w (-0.195 E): the fibres' compressive stress
``E_f Ee_tt`` enters ``N . S N`` (tests/test_micro_wall_stability.py).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from dolfinx import fem

from plantgrowth.base.mesh_samples import MeshSamples
from plantgrowth.forms.elasticity import Fibres, elastic_strain
from plantgrowth.forms.finite import elastic_deformation
from plantgrowth.models import fibres as fibre_law
from plantgrowth.models import stability
from plantgrowth.models.newton import global_extreme

SAMPLES_PER_CELL = 6  # DG2 nodes: vertices and edge midpoints
LINEAR_REMEDY = (
    'linear kinematics reads large wall rotations as strain: if the walls turned by order one '
    'here, set kinematics = "finite" (a top-level scene key; docs/real_tissues.md, "Why '
    'irregular tissues stopped at step 0")'
)
"""Appended to a linear run's loss of stability: the remedy (irregular tissues at P1 = 0.001)."""


class WallStability:
    """The walls' :func:`plantgrowth.models.stability.normalised` at the P2 sample points
    (``fibres``: the fibred walls' UFL coefficients, per wall triangle; None: isotropic walls)."""

    def __init__(
        self, u: fem.Function, Fg: fem.Function, E: fem.Function, nu: fem.Function, finite: bool,
        fibres: Fibres | None = None,
    ) -> None:  # fmt: skip
        msh = u.function_space.mesh
        self.comm = msh.comm
        self.finite = finite
        tensor = elastic_deformation(u, Fg) if finite else elastic_strain(u, Fg)
        self._parts = [MeshSamples(tensor[i, j], msh, 2) for i in range(2) for j in range(2)]
        first = self._parts[0]
        self.points, self.areas = first.points, first.cell_areas
        E_at, nu_at = (MeshSamples(f, msh, 2).values() for f in (E, nu))
        self._C = stability.isotropic_voigt(E_at, nu_at)
        self._fibre_parts = []  # E_f, m, t, Fg: DG0 coefficients, sampled once per triangle
        if fibres is not None:
            m, t = fibres.director, fibres.tangent
            parts = [fibres.stiffness, m[0], m[1], t[0], t[1]]
            parts += [Fg[i, j] for i in range(2) for j in range(2)]
            self._fibre_parts = [MeshSamples(p, msh, 0) for p in parts]

    def tangent(self) -> np.ndarray:
        """(n, 3, 3) the wall tensor C_w at each sample point, now (Voigt, engineering shear):
        C_iso plus :func:`plantgrowth.models.fibres.fibre_voigt` of the triangle's E_f, m, t and
        Fg (the director turns, Fg grows)."""
        if not self._fibre_parts:
            return self._C
        f = np.stack([p.values() for p in self._fibre_parts], axis=1)
        fibred = fibre_law.fibre_voigt(f[:, 0], f[:, 1:3], f[:, 3:5], f[:, 5:].reshape(-1, 2, 2))
        return self._C + np.repeat(fibred, SAMPLES_PER_CELL, axis=0)

    def values(self, screened: bool = True) -> np.ndarray:
        """(n,) normalised smallest acoustic eigenvalue at each sample point, now (``screened``:
        exact in sign only, plantgrowth.models.stability.normalised)."""
        Fe, C = self._deformation(), self.tangent()
        return stability.normalised(Fe, stability.svk_stress(Fe, C), C, screened)

    def _deformation(self) -> np.ndarray:
        """(n, 2, 2) Fe at the samples (linear kinematics: the stretch ``sqrt(I + 2 eps_el)``)."""
        T = np.stack([p.values() for p in self._parts], axis=1).reshape(-1, 2, 2)
        return T if self.finite else stability.stretch_of_strain(0.5 * (T + np.swapaxes(T, 1, 2)))

    def check(self) -> stability.Ellipticity:
        """Collective: the step's :class:`plantgrowth.models.stability.Ellipticity`. The micro
        model resolves every wall, so every non-elliptic set counts (no resolution limit); a
        linear run's names :data:`LINEAR_REMEDY`."""
        Fe, C = self._deformation(), self.tangent()
        values = stability.normalised(Fe, stability.svk_stress(Fe, C), C, True)
        per_cell = values.reshape(-1, SAMPLES_PER_CELL)
        worst = np.arange(len(per_cell)) * SAMPLES_PER_CELL + np.argmin(per_cell, axis=1)
        S = stability.svk_stress(Fe[worst], C[worst])
        found = stability.check(values[worst], self.areas, self.points[worst], self.comm, S)
        return found if self.finite else dataclasses.replace(found, remedy=LINEAR_REMEDY)

    def smallest(self) -> tuple[float, np.ndarray]:
        """Collective: the smallest value over all ranks and where (Newton's ranking)."""
        return global_extreme(self.values(), self.points, self.comm, np.argmin)

    def cell_minima(self) -> np.ndarray:
        """(n_cells,) the smallest value of each owned triangle (the ``stability`` field)."""
        return self.values(screened=False).reshape(-1, SAMPLES_PER_CELL).min(axis=1)
