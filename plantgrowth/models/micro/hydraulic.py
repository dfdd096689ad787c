"""Wiring of the water step into the micro model (docs/model.md, water fluxes): building it from a
scene and the model's pieces, and the summary.csv columns it reports."""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem

from plantgrowth.forms import finite as finite_forms
from plantgrowth.forms import micro as micro_forms
from plantgrowth.meshes.cell_tissue import CellTissue, as_tissue
from plantgrowth.meshes.cell_walls import wall_network
from plantgrowth.meshes.honeycomb import polygon_area
from plantgrowth.meshes.tissue import TissueLayout, clip_below
from plantgrowth.models.micro.cell_columns import CellColumns
from plantgrowth.models.micro.turgor_newton import TurgorNewton
from plantgrowth.models.micro.turgor_solve import ElasticParts, TurgorSolve
from plantgrowth.models.micro.water import CellWater
from plantgrowth.models.micro.water_predictor import WaterPredictor
from plantgrowth.models.newton import NewtonSolver
from plantgrowth.models.water_row import water_row
from plantgrowth.scene import Scene


def lumen_areas(source: CellTissue | TissueLayout) -> np.ndarray:
    """(n,) each cell's reference lumen area (its void; a cut cell's above x2 = 0)."""
    tissue = as_tissue(source)
    return np.array([
        polygon_area(clip_below(tissue.void(i)) if tissue.cut[i] else tissue.void(i))
        for i in range(tissue.n_cells)
    ])  # fmt: skip


def turgor_solve(
    scene: Scene, tissue: CellTissue, hexagon_area: np.ndarray, parts: ElasticParts,
    test: ufl.Argument, normal, membrane: ufl.Measure,
    newton: tuple[NewtonSolver, fem.Function] | None = None,
) -> TurgorSolve | TurgorNewton:  # fmt: skip
    """The water step of a micro tissue (``scene`` over the tissue's extent, its cells'
    reference polygon areas ``hexagon_area``) from its walls' problem ``parts``, with ``test``
    the displacement test function and ``membrane`` the membranes' measure; finite kinematics:
    ``newton``, the walls' Newton solver and the turgor function its residual reads."""
    hydraulics = scene.hydraulics
    centres = tissue.centres.T
    water = CellWater(
        hydraulics, wall_network(tissue), hydraulics.osmotic(*centres),
        hydraulics.conductivity(*centres),
        {s.name: scene.regions[s.name].inside(tissue.centres) for s in hydraulics.regions()},
        hexagon_area,
    )  # fmt: skip
    mesh = parts.u.function_space.mesh
    indicator = fem.Function(fem.FunctionSpace(mesh, ("DG", 0)))  # one cell's, per cell
    support = fem.form(ufl.inner(indicator * ufl.as_vector((1.0, 1.0)), test) * membrane)
    columns = CellColumns(support, indicator, parts.set_cells, water.n, parts.bcs)
    column = fem.form(
        micro_forms.membrane_pressure_rhs(test, parts.Fg, indicator, normal, membrane)
    )
    if newton is not None:
        u = parts.u
        area = finite_forms.lumen_area(u, indicator, normal, membrane)
        share = ufl.TestFunction(indicator.function_space)  # each mesh cell's share of V_c
        forms = [finite_forms.follower_pressure(u, test, indicator, normal, membrane),
                 ufl.derivative(area, u, test),
                 finite_forms.lumen_area(u, share, normal, membrane)]  # fmt: skip
        return TurgorNewton(
            newton[0], parts, newton[1], *(fem.form(f) for f in forms), indicator, columns,
            water, scene.time.dt, WaterPredictor(parts, column, columns, newton[0].offset),
        )  # fmt: skip
    return TurgorSolve(parts, column, columns, water, lumen_areas(tissue), scene.time.dt)


def water_measures(turgor: TurgorSolve, weights: np.ndarray) -> dict[str, float]:
    """The step's summary row: turgor mean (weighted by the cells' reference areas), min, max;
    the water held; the water balance error (what came in over the step minus the change of the
    water held: 0 at t = 0); each supply's inflow rate."""
    state = turgor.last
    turgor_range = (weights @ state.P, state.P.min(), state.P.max())
    return water_row(turgor_range, state.water.sum(), turgor.balance_error, state.supplied)
