"""The macro model's water outputs (docs/outputs.md): the fields ``P``, ``psi`` and
``water_flux`` of fields.xdmf, and summary.csv's water columns under the micro model's names
(:func:`plantgrowth.models.water_row.water_row`).

Per step: turgor mean ``int P dx / int dx`` (reference area), min and max over the nodes; the
water held ``int m dx``; the balance error ``dt sum_s inflow_s - (water - water_before)``; each
supply's inflow ``int L_s |cof(Fg) N| (psi_s - psi) ds`` (an edge) or ``int Jg L_r (psi_r -
psi) dx`` over the region's fine cells (a region), all at the step's solved state. A step taken
in sub-steps (the adaptive integrator) sums its kept sub-steps' (:class:`WaterLedger`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from plantgrowth.forms.hydraulics import darcy_flux, region_supply_form
from plantgrowth.models.macro.water import MacroWater
from plantgrowth.models.water_row import WaterLedger, water_row
from plantgrowth.scene.hydraulics import Hydraulics
from plantgrowth.scene.regions import Region


class MacroWaterOutputs:
    """The water's fields and summary row of a macro run.

    Args:
        water: the model's water step.
        hydraulics: the scene's ``[hydraulics]`` (its supplies' labels, the regions' L_r and
            psi_r(t)).
        regions: the scene's ``[regions]``.
        fields: the scene's ``[output] fields``.
    """

    def __init__(
        self, water: MacroWater, hydraulics: Hydraulics, regions: Mapping[str, Region],
        fields: tuple[str, ...],
    ) -> None:  # fmt: skip
        pr = water.problem
        self.water, self.supplies, self.fields = water, hydraulics.supplies, fields
        self.psi = fem.Function(water.Q, name="psi")
        self.flux = fem.Function(fem.VectorFunctionSpace(pr.mesh, ("DG", 0)), name="water_flux")
        self._flux = fem.Expression(
            darcy_flux(self.psi, pr.Fg, water.kappa),
            self.flux.function_space.element.interpolation_points(),
        )
        chosen = {"P": water.P, "psi": self.psi, "water_flux": self.flux}
        self.functions = [chosen[name] for name in fields if name in chosen]
        self._turgor = fem.form(water.P * ufl.dx)
        self._area = pr.mesh.comm.allreduce(
            fem.assemble_scalar(fem.form(fem.Constant(pr.mesh, 1.0) * ufl.dx)), op=MPI.SUM
        )
        self._regions = {}  # label -> (L_r on the region's fine cells, psi_r at 1, its form)
        midpoints = pr.midpoints[:, :2]
        for s in hydraulics.regions():
            L_r, psi_r = fem.Function(pr.Q0), fem.Constant(pr.mesh, 0.0)
            pr.set_cell_values(L_r, s.conductance * regions[s.name].inside(midpoints))
            form = region_supply_form(psi_r - (water.P - water.Pi), 1.0, pr.Fg, L_r, ufl.dx)
            self._regions[s.label] = (psi_r, fem.form(form))
        self.ledger = WaterLedger()  # the step's water in, over its kept sub-steps
        self.row: dict[str, float] = {}

    def update(self, dt: float | None, t: float) -> None:
        """Collective, after a solve at time t that advanced the water by dt (None: the initial
        state): psi, the flux if asked for, and the summary row."""
        water, comm = self.water, self.water.problem.mesh.comm
        self.psi.x.array[:] = water.P.x.array - water.Pi.x.array
        if "water_flux" in self.fields:
            self.flux.interpolate(self._flux)
        inflows = {s.label: self._inflow(s.kind, s.name, s.label, s.potential(t))
                   for s in self.supplies}  # fmt: skip
        held = water.water_content()
        error, inflows, _ = self.ledger.record(dt, held, inflows)
        owned = water.P.x.array[: water.Q.dofmap.index_map.size_local]
        turgor = (
            comm.allreduce(fem.assemble_scalar(self._turgor), op=MPI.SUM) / self._area,
            comm.allreduce(float(owned.min(initial=np.inf)), op=MPI.MIN),
            comm.allreduce(float(owned.max(initial=-np.inf)), op=MPI.MAX),
        )
        self.row = water_row(turgor, held, error, inflows)

    def restored(self) -> None:
        """Collective, after the water's state was restored: the water held it starts from."""
        self.ledger.close(self.water.water_content())

    def _inflow(self, kind: str, name: str, label: str, potential: float) -> float:
        if kind == "edge":
            return self.water.inflow(name)
        psi_r, form = self._regions[label]
        psi_r.value = potential
        return self.water.problem.mesh.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM)
