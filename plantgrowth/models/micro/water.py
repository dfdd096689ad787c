"""The cells' water (docs/model.md, water fluxes, micro model): the network's conductances, the
water each lumen holds, and the water step's turgor equation (pure numpy, per biological cell,
the same on every rank).

Per step, backward Euler in psi = P - Pi, with V_c(u) the lumen area to first order about the
grown state (:func:`lumen_offset` + B_c . u):
``V_c(u) = W_c^n + dt [ sum_d L ell_cd (psi_d - psi_c) + sum_s g_sc (psi_s - psi_c) ]``
with ``g_sc = L_s ell_cs`` (an edge) or ``L_r A_c`` (a region), i.e.
``B^T u + dt H P = W^n - V0 + dt (H Pi + sum_s g_s psi_s)`` (:meth:`CellWater.step_terms`).

Choices the model leaves open: the two halves of a shared wall belong to its two cells (section
2) and conduct in series, ``L = 2 L_c L_d / (L_c + L_d)`` (0 if either is 0) with L at the cell
centres; its grown length is the mean of ``|Fg t| l`` over the two cells' Fg.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from plantgrowth.meshes.cell_walls import WallNetwork, grown_lengths
from plantgrowth.scene.hydraulics import Hydraulics, Supply

WATER_COLUMNS = ["turgor_mean", "turgor_min", "turgor_max", "water", "water_balance_error"]
"""summary.csv's columns of a scene with ``[hydraulics]``, before each supply's ``inflow.<label>``
(docs/outputs.md)."""


def water_columns(hydraulics: Hydraulics | None) -> list[str]:
    """The summary.csv columns of the scene's water (none without ``[hydraulics]``)."""
    if hydraulics is None:
        return []
    return WATER_COLUMNS + [f"inflow.{s.label}" for s in hydraulics.supplies]


def series(Lc: np.ndarray, Ld: np.ndarray) -> np.ndarray:
    """Conductivity of two half walls in series, ``2 Lc Ld / (Lc + Ld)`` (0 if either is 0)."""
    total = Lc + Ld
    return np.divide(2.0 * Lc * Ld, total, out=np.zeros_like(total), where=total > 0.0)


def lumen_offset(lumen_area: np.ndarray, Fg: np.ndarray) -> np.ndarray:
    """``V_c(0) = Jg A_c (tr Fg^{-1} - 1)``: the linearized lumen area about the grown state at
    u = 0 (A_c the reference lumen area), so that ``V_c(u) = V_c(0) + B_c . u`` equals ``Jg A_c``
    at the grown state ``grad u = Fg - I``."""
    Jg = np.linalg.det(Fg)
    return Jg * lumen_area * (np.trace(np.linalg.inv(Fg), axis1=1, axis2=2) - 1.0)


@dataclass(frozen=True)
class WaterState:
    """One step's solved water: turgor P, potential psi = P - Pi, the water held (lumen areas),
    each cell's net inflow rate and each supply's (by label), all at the step's end."""

    P: np.ndarray
    psi: np.ndarray
    water: np.ndarray
    inflow: np.ndarray
    supplied: dict[str, float]


class CellWater:
    """The water network of a micro tissue.

    Args:
        hydraulics: the scene's ``[hydraulics]``.
        network: the tissue's shared and outer walls (reference mid-line vectors).
        osmotic, conductivity: Pi and L at the cell centres, (n,).
        region_cells: region name -> (n,) True for the cells whose centre lies in it.
        hexagon_area: (n,) the cells' reference areas (mid-line hexagons).
    """

    def __init__(
        self, hydraulics: Hydraulics, network: WallNetwork, osmotic: np.ndarray,
        conductivity: np.ndarray, region_cells: dict[str, np.ndarray], hexagon_area: np.ndarray,
    ) -> None:  # fmt: skip
        self.hydraulics = hydraulics
        self.network = network
        self.n = len(hexagon_area)
        self.Pi = np.broadcast_to(np.asarray(osmotic, dtype=float), self.n).copy()
        L = np.broadcast_to(np.asarray(conductivity, dtype=float), self.n)
        self.L_walls = series(L[network.pairs[:, 0]], L[network.pairs[:, 1]])
        self.region_cells = region_cells
        self.hexagon_area = hexagon_area

    def supply_weights(self, supply: Supply, Fg: np.ndarray) -> np.ndarray:
        """(n,) g_sc: ``L_s`` times the grown length of each cell's outer walls on the edge, or
        ``L_r`` times the grown area of each cell in the region."""
        if supply.kind == "region":
            area = self.hexagon_area * np.linalg.det(Fg)
            return supply.conductance * area * self.region_cells[supply.name]
        net = self.network
        on = net.outer_edge == supply.name
        lengths = grown_lengths(net.outer[on], Fg[net.outer_cell[on]])
        return supply.conductance * np.bincount(net.outer_cell[on], lengths, self.n)

    def conductance(self, Fg: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """H (n, n): the graph Laplacian weighted by ``L ell_cd`` plus each cell's supply
        weights on the diagonal; and the supply weights g_s (n,) by label."""
        net = self.network
        c, d = net.pairs[:, 0], net.pairs[:, 1]
        ell = 0.5 * (grown_lengths(net.shared, Fg[c]) + grown_lengths(net.shared, Fg[d]))
        k = self.L_walls * ell
        H = np.zeros((self.n, self.n))
        np.add.at(H, (c, d), -k)
        np.add.at(H, (d, c), -k)
        H[np.diag_indices(self.n)] = np.bincount(c, k, self.n) + np.bincount(d, k, self.n)
        weights = {s.label: self.supply_weights(s, Fg) for s in self.hydraulics.supplies}
        for g in weights.values():
            H[np.diag_indices(self.n)] += g
        return H, weights

    def supply_terms(self, weights: dict[str, np.ndarray], t: float) -> np.ndarray:
        """(n,) ``sum_s g_sc psi_s(t)``."""
        out = np.zeros(self.n)
        for s in self.hydraulics.supplies:
            out += weights[s.label] * s.potential(t)
        return out

    def step_terms(self, W: np.ndarray, V0: np.ndarray, Fg: np.ndarray, t: float,
                   dt: float) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """H and ``h = W - V0 + dt (H Pi + sum_s g_s psi_s)`` at ``Fg`` and time ``t`` (the
        step's end): the step's water balance reads ``B^T u + dt H P = h``."""
        H, weights = self.conductance(Fg)
        return H, W - V0 + dt * (H @ self.Pi + self.supply_terms(weights, t))

    def state(self, P: np.ndarray, water: np.ndarray, Fg: np.ndarray, t: float) -> WaterState:
        """The water of a solved step: P, psi, the water held and the inflow rates at time t."""
        H, weights = self.conductance(Fg)
        psi = P - self.Pi
        inflow = self.supply_terms(weights, t) - H @ psi
        supplied = {
            s.label: float(weights[s.label] @ (s.potential(t) - psi))
            for s in self.hydraulics.supplies
        }
        return WaterState(P, psi, water, inflow, supplied)
