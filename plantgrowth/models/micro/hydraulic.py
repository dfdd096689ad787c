"""Wiring of the water step into the micro model (docs/model.md, water fluxes): building it from a
scene and the model's pieces, and the summary.csv columns it reports."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import ufl
from dolfinx import fem

from plantgrowth.forms import micro as micro_forms
from plantgrowth.meshes.cell_walls import wall_network
from plantgrowth.meshes.honeycomb import polygon_area
from plantgrowth.meshes.tissue import clip_below
from plantgrowth.models.micro.turgor_solve import TurgorSolve
from plantgrowth.models.micro.water import CellWater
from plantgrowth.scene import Scene

if TYPE_CHECKING:
    from plantgrowth.models.micro.model import MicroModel


def lumen_areas(model: MicroModel) -> np.ndarray:
    """(n,) each cell's reference lumen area (its void; the bottom row's cut at x2 = 0)."""
    layout = model.layout
    cut = range(layout.cut_cells.start, layout.cut_cells.stop)
    return np.array([
        polygon_area(clip_below(layout.void(i)) if i in cut else layout.void(i))
        for i in range(layout.n_cells)
    ])  # fmt: skip


def turgor_solve(
    model: MicroModel, scene: Scene, test: ufl.Argument, normal, membrane: ufl.Measure
) -> TurgorSolve:
    """The water step of ``model`` (built up to its solver; ``scene`` over the tissue's extent),
    with ``test`` the displacement test function and ``membrane`` the membranes' measure."""
    layout, hydraulics = model.layout, scene.hydraulics
    centres = layout.centres.T
    water = CellWater(
        hydraulics, wall_network(layout), hydraulics.osmotic(*centres),
        hydraulics.conductivity(*centres),
        {s.name: scene.regions[s.name].inside(layout.centres) for s in hydraulics.regions()},
        np.array([polygon_area(layout.hexagon(i)) for i in range(layout.n_cells)]),
    )  # fmt: skip
    indicator = fem.Function(fem.FunctionSpace(model.mesh, ("DG", 0)))  # one cell's, per cell
    column = fem.form(
        micro_forms.membrane_pressure_rhs(test, model.Fg, indicator, normal, membrane)
    )
    return TurgorSolve(
        model._linear_solve, model.A, model.b, model.ksp, model.u, column, indicator,
        model._set, model.bcs, water, lumen_areas(model), scene.time.dt, model.comm,
    )  # fmt: skip


def water_measures(turgor: TurgorSolve, weights: np.ndarray) -> dict[str, float]:
    """The step's summary row: turgor mean (weighted by the cells' reference areas), min, max;
    the water held; the water balance error (what came in over the step minus the change of the
    water held: 0 at t = 0); each supply's inflow rate."""
    state = turgor.last
    row = {
        "turgor_mean": float(weights @ state.P), "turgor_min": float(state.P.min()),
        "turgor_max": float(state.P.max()), "water": float(state.water.sum()),
        "water_balance_error": turgor.balance_error,
    }  # fmt: skip
    return row | {f"inflow.{label}": value for label, value in state.supplied.items()}
