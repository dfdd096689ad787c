"""Strong ellipticity of the walls' St Venant-Kirchhoff law at the micro model's P2 sample
points (issue 20, item 2; plantgrowth.models.stability).

At the six DG2 nodes of each owned wall triangle: the elastic deformation ``Fe = (I + grad u)
Fg^-1`` (finite kinematics) or the stretch ``sqrt(I + 2 eps_el)`` of the linear elastic strain,
the wall's own E and nu, and the normalised smallest acoustic eigenvalue there. A triangle is
non-elliptic where one of its samples is.
"""

from __future__ import annotations

import numpy as np
from dolfinx import fem

from plantgrowth.base.mesh_samples import MeshSamples
from plantgrowth.forms.elasticity import elastic_strain
from plantgrowth.forms.finite import elastic_deformation
from plantgrowth.models import stability
from plantgrowth.models.newton import global_extreme

SAMPLES_PER_CELL = 6  # DG2 nodes: vertices and edge midpoints


class WallStability:
    """The walls' :func:`plantgrowth.models.stability.normalised` at the P2 sample points."""

    def __init__(
        self, u: fem.Function, Fg: fem.Function, E: fem.Function, nu: fem.Function, finite: bool
    ) -> None:
        msh = u.function_space.mesh
        self.comm = msh.comm
        self.finite = finite
        tensor = elastic_deformation(u, Fg) if finite else elastic_strain(u, Fg)
        self._parts = [MeshSamples(tensor[i, j], msh, 2) for i in range(2) for j in range(2)]
        first = self._parts[0]
        self.points, self.areas = first.points, first.cell_areas
        E_at, nu_at = (MeshSamples(f, msh, 2).values() for f in (E, nu))
        self._C = stability.isotropic_voigt(E_at, nu_at)

    def values(self, screened: bool = True) -> np.ndarray:
        """(n,) normalised smallest acoustic eigenvalue at each sample point, now (``screened``:
        exact in sign only, plantgrowth.models.stability.normalised)."""
        Fe = self._deformation()
        return stability.normalised(Fe, stability.svk_stress(Fe, self._C), self._C, screened)

    def _deformation(self) -> np.ndarray:
        """(n, 2, 2) Fe at the samples (linear kinematics: the stretch ``sqrt(I + 2 eps_el)``)."""
        T = np.stack([p.values() for p in self._parts], axis=1).reshape(-1, 2, 2)
        return T if self.finite else stability.stretch_of_strain(0.5 * (T + np.swapaxes(T, 1, 2)))

    def check(self) -> stability.Ellipticity:
        """Collective: the step's :class:`plantgrowth.models.stability.Ellipticity`. The micro
        model resolves every wall, so every non-elliptic set counts (no resolution limit)."""
        Fe = self._deformation()
        values = stability.normalised(Fe, stability.svk_stress(Fe, self._C), self._C, True)
        per_cell = values.reshape(-1, SAMPLES_PER_CELL)
        worst = np.arange(len(per_cell)) * SAMPLES_PER_CELL + np.argmin(per_cell, axis=1)
        S = stability.svk_stress(Fe[worst], self._C[worst])
        return stability.check(values[worst], self.areas, self.points[worst], self.comm, S)

    def smallest(self) -> tuple[float, np.ndarray]:
        """Collective: the smallest value over all ranks and where (Newton's ranking)."""
        return global_extreme(self.values(), self.points, self.comm, np.argmin)

    def cell_minima(self) -> np.ndarray:
        """(n_cells,) the smallest value of each owned triangle (the ``stability`` field)."""
        return self.values(screened=False).reshape(-1, SAMPLES_PER_CELL).min(axis=1)
