"""Statistics of a scene's named regions per step (summary.csv's ``<name>.*`` columns), with the
weights of the whole-tissue columns (docs/outputs.md): for the growth units in the region,

    <name>.area             sum of the units' current areas (macro: int det(I + grad u) over
                            the fine triangles; micro: cells.csv's ``area``, walls and void)
    <name>.growth_rate_ij   sum(A_ref G_ij) / sum(A_ref), A_ref the units' reference areas
                            (fine triangles; cells' hexagons, cut at x2 = 0 in the bottom row)
    <name>.trG              growth_rate_11 + growth_rate_22
    <name>.elastic_strain_max   the largest of the units' elastic strains (summary.csv's
                            ``elastic_strain_max`` restricted to the region)
    <name>.turgor_mean      with water fluxes only: sum(A_ref P) / sum(A_ref), P the units'
                            turgor (macro: at the fine triangles' midpoints; micro: the cells')

A unit belongs to a region when the region's condition holds at its reference midpoint
(:class:`plantgrowth.scene.regions.Region`), so a region covering the whole tissue gives the
global ``area``, ``growth_rate_11``, ``growth_rate_22``, ``growth_rate_area`` and
``elastic_strain_max`` to round-off.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from plantgrowth.scene.regions import Region

STATISTICS = (
    "area", "trG", "growth_rate_11", "growth_rate_22", "growth_rate_12", "elastic_strain_max",
)  # fmt: skip
"""Each region's columns, ``<name>.<statistic>``, in this order."""
WATER_STATISTICS = ("turgor_mean",)
"""After them, with water fluxes (a scene with ``[hydraulics]``)."""


def region_columns(regions: dict[str, Region], water: bool = False) -> list[str]:
    """The summary.csv columns of the regions, in the scene's order (``water``: the scene has
    ``[hydraulics]``)."""
    statistics = STATISTICS + (WATER_STATISTICS if water else ())
    return [f"{name}.{s}" for name in regions for s in statistics]


class RegionStatistics:
    """The regions' memberships of this rank's growth units, and their statistics per step.

    Args:
        regions: the scene's regions.
        midpoints: (n, 2) reference midpoints of this rank's growth units.
        ref_areas: (n,) their reference areas (the weights of the means).
        comm: the communicator the units are shared over (MPI.COMM_SELF when every rank holds
            all of them).
    """

    def __init__(
        self, regions: dict[str, Region], midpoints: np.ndarray, ref_areas: np.ndarray,
        comm: MPI.Comm,
    ) -> None:  # fmt: skip
        self.inside = {name: r.inside(midpoints) for name, r in regions.items()}
        self.ref_areas, self.comm = ref_areas, comm

    def measures(
        self, areas: np.ndarray, G: np.ndarray, strain: np.ndarray,
        turgor: np.ndarray | None = None,
    ) -> dict[str, float]:  # fmt: skip
        """Collective: the columns of :func:`region_columns` for this rank's units' current
        areas (n,), growth rates G (n, 2, 2), elastic strains (n,: the largest principal
        magnitudes, plantgrowth.models.elastic_strain.principal_magnitude) and, with water
        fluxes, turgor (n,)."""
        if not self.inside:
            return {}
        w = self.ref_areas
        columns = [areas, w, w * G[:, 0, 0], w * G[:, 1, 1], w * G[:, 0, 1]]
        parts = np.stack(columns + ([] if turgor is None else [w * turgor]), axis=1)
        local = np.array([parts[mask].sum(axis=0) for mask in self.inside.values()])
        sums = self.comm.allreduce(local, op=MPI.SUM)
        local_peaks = np.array([strain[mask].max(initial=-np.inf) for mask in self.inside.values()])
        peaks = np.empty_like(local_peaks)
        self.comm.Allreduce(local_peaks, peaks, op=MPI.MAX)  # element-wise (pickled max is not)
        out = {}
        for name, (area, weight, g11, g22, g12, *P), peak in zip(self.inside, sums, peaks,
                                                                  strict=True):  # fmt: skip
            g11, g22, g12 = g11 / weight, g22 / weight, g12 / weight
            values = (area, g11 + g22, g11, g22, g12, peak)
            out |= {f"{name}.{s}": float(v) for s, v in zip(STATISTICS, values, strict=True)}
            if P:
                out[f"{name}.turgor_mean"] = float(P[0] / weight)
        return out
