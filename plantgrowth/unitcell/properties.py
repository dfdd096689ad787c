"""One honeycomb cell's reported properties: what ``plantgrowth cell --json`` prints and
``pg.cell`` returns (docs/usage.md, docs/api.md), its inputs checked first."""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from plantgrowth.base.errors import check_growth_tensor, check_number, check_wall_material
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.meshes.unit_cell import mesh_size
from plantgrowth.unitcell.hydraulic_coefficients import hydraulic_summary
from plantgrowth.unitcell.solver import DEFAULT_RESOLUTION, CellSolver


def check_fibres(fibre_stiffness: object, fibre_angle: object, names: tuple[str, str]) -> tuple:
    """E_f / E finite and >= 0, the director angle finite (degrees); errors name ``names``."""
    return (
        check_number(names[0], fibre_stiffness, 0.0, np.inf, low_open=False),
        check_number(names[1], fibre_angle, -np.inf, np.inf),
    )


def cell_properties(
    l1: float, l2: float, theta: float, w: float, E: float, nu: float, Fg: object,
    resolution: int | None, comm: MPI.Comm, resolution_name: str = "resolution",
    fibre_stiffness: float = 0.0, fibre_angle: float = 0.0,
    fibre_names: tuple[str, str] = ("fibre_stiffness", "fibre_angle"),
) -> dict:  # fmt: skip
    """E_hom (six components), K_hom, the orthotropic moduli, phi_w, ndofs, seconds, the
    strain averages dbar_w, dbar_v and the hydraulic coefficients b, inv_M (1/M) and kappa
    (per unit wall conductivity L) of one honeycomb cell (docs/model.md sections 2-3 and
    "Water fluxes") at the growth tensor ``Fg`` (2x2), with fibre-reinforced walls when
    ``fibre_stiffness`` > 0, checked first (errors name the argument; the resolution as
    ``resolution_name``, the fibre parameters as ``fibre_names``)."""
    E, nu = check_wall_material(E, nu)
    Fg = np.array(check_growth_tensor("Fg", Fg))
    fibre_stiffness, fibre_angle = check_fibres(fibre_stiffness, fibre_angle, fibre_names)
    resolution = DEFAULT_RESOLUTION if resolution is None else resolution
    cell = HoneycombCell(l1, l2, theta, w)
    mesh_size(cell, resolution, resolution_name)
    fibres = fibre_stiffness > 0.0
    result = CellSolver(cell, resolution, comm, fibres=fibres).solve(
        Fg, E, nu, fibre_stiffness=fibre_stiffness, fibre_angle=fibre_angle
    )
    hydraulics = hydraulic_summary(result, cell, Fg)
    return {**result.summary(), **result.strain_averages(), **hydraulics}
