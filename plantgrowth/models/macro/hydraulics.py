"""The macro model's water inputs (docs/model.md, "Water fluxes"), built directly or from the
scene's ``[hydraulics]`` (:func:`from_scene`).

A value is a constant or a field ``f(x1, x2) -> array`` (a scene Field is one). The osmotic
pressure Pi is sampled at the pressure's nodes (P1), the wall conductivity L at the fine cells'
midpoints (per growth unit, like the cell tensors).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from plantgrowth.base.errors import InputError

if TYPE_CHECKING:
    from plantgrowth.scene.hydraulics import Hydraulics
    from plantgrowth.scene.regions import Region

Value = float | Callable[[np.ndarray, np.ndarray], np.ndarray]
Potential = float | Callable[[float], float]
"""A supply's water potential: a constant or a function of time (read at each step's end)."""


def at_time(potential: Potential, t: float) -> float:
    """The potential at time t."""
    return float(potential(t)) if callable(potential) else float(potential)


def sample(value: Value, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """The value at the points (x1, x2), as a float array of their shape."""
    if callable(value):
        return np.broadcast_to(np.asarray(value(x1, x2), dtype=float), np.shape(x1)).copy()
    return np.full(np.shape(x1), float(value))


@dataclass(frozen=True)
class EdgeSupply:
    """An edge in contact with water at potential ``potential`` (psi_s) through the conductance
    ``conductance`` (L_s) per unit grown edge length. ``edge``: a name of the fine mesh's
    boundary (plantgrowth.models.macro.boundary.Boundary.edges: the rectangle's sides, an
    outline's ``edge{i}``, a mesh file's groups)."""

    edge: str
    potential: Potential
    conductance: float

    def __post_init__(self) -> None:
        if not self.conductance >= 0.0:
            raise InputError(f"supply on {self.edge}: conductance must be >= 0")


@dataclass(frozen=True)
class RegionSupply:
    """A region (the fine cells whose midpoints ``inside(x1, x2)`` marks) supplied with water at
    potential ``potential`` (psi_r) through ``conductance`` (L_r) per unit grown area."""

    inside: Callable[[np.ndarray, np.ndarray], np.ndarray]
    potential: Potential
    conductance: float

    def __post_init__(self) -> None:
        if not self.conductance >= 0.0:
            raise InputError("supplied region: conductance must be >= 0")


@dataclass(frozen=True)
class MacroHydraulics:
    """The macro model's water.

    Attributes:
        osmotic: Pi, the osmotic pressure (same units as turgor).
        conductivity: L >= 0, the wall conductivity per unit length of shared wall mid-line.
        cell_scale: the real cells' size over the scene's cell (l1, l2): kappa is proportional
            to it (docs/model.md, "Water fluxes"); a micro tissue of Nx cells across has
            ``TissueLayout(cell, Nx).delta_s = 4 / Nx``.
        edges: the supplied edges (every other edge is sealed).
        regions: the supplied regions.
        initial_potential: psi_0; every point starts in equilibrium at ``P = Pi + psi_0``.
    """

    osmotic: Value = 0.0
    conductivity: Value = 1.0
    cell_scale: float = 1.0
    edges: tuple[EdgeSupply, ...] = ()
    regions: tuple[RegionSupply, ...] = ()
    initial_potential: float = 0.0

    def __post_init__(self) -> None:
        if not self.cell_scale > 0.0:
            raise InputError(f"cell_scale must be > 0, got {self.cell_scale!r}")
        if not callable(self.conductivity) and not self.conductivity >= 0.0:
            raise InputError(f"conductivity must be >= 0, got {self.conductivity!r}")
        names = [s.edge for s in self.edges]
        if len(set(names)) != len(names):
            raise InputError(f"an edge is supplied twice: {names}")


def cell_scale(nx: int) -> float:
    """The real cells' size over the scene's cell for a scene whose cells are those of its micro
    tissue, ``micro.nx = nx`` cells across: ``delta_s = 4 / nx`` (docs/model.md section 7 and
    "The cells' size")."""
    return 4.0 / nx


def from_scene(
    water: Hydraulics, regions: Mapping[str, Region], cell_scale: float
) -> MacroHydraulics:
    """The scene's ``[hydraulics]`` (its supplies' regions named in ``regions``, the scene's
    ``[regions]``) as the macro model's inputs, with the real cells ``cell_scale`` times the
    scene's cell (docs/model.md, "The cells' size")."""
    edges, supplied = [], []
    for supply in water.supplies:
        if supply.kind == "edge":
            edges.append(EdgeSupply(supply.name, supply.potential, supply.conductance))
        else:
            region = regions[supply.name]
            supplied.append(RegionSupply(
                lambda x1, x2, r=region: r.inside(np.column_stack([x1, x2])),
                supply.potential, supply.conductance,
            ))  # fmt: skip
    return MacroHydraulics(
        water.osmotic, water.conductivity, cell_scale, tuple(edges), tuple(supplied),
        water.initial_potential,
    )  # fmt: skip
