"""Warnings for scene fields that change over distances shorter than the mesh that samples them
(issue 20, item 4): one per field, naming the field, the place and the key to refine.

A field is sampled either per fine cell (its value at the cell's midpoint: P1, eta, tau, and E
with the surrogate; key ``tissue.h``) or at the coarse nodes and P1-interpolated to the cells
(the cell geometry and nu, and E on the exact path; key ``tissue.H``). Either sample of a cell
is compared with the field's mean over the cell, from its values at ``SUB_POINTS`` points (the
centroids of the cell's 16 triangles after two midpoint subdivisions). The field's sampling
error is

    r = sum_c |c| |f_sampled(c) - mean_c f| / sum_c |c| mean_c |f - f_bar|,

the part of its variation about its tissue mean f_bar that the sampling misplaces (0 for a
linear field, sampled either way; of order h / R for a jump along a curve of radius R). Above
``MAX_SAMPLING_ERROR`` the run warns, at the cell where the sample is furthest from the mean.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI

from plantgrowth.scene import Scene

MAX_SAMPLING_ERROR = 0.03
"""Largest sampling error r of a field without a warning, between the measured (docs/
accuracy_cost.md, "Field resolution") largest of the shipped scenes at their own presets, 2.5%
(scenes/biology/stiff_band.toml: E jumps along two lines, h = 0.1), and the soft disc at
``draft``, 3.4% (E, h = 0.2; 1.8% at ``balanced``); every smooth field measures 0."""


def _centroids() -> np.ndarray:
    """Barycentric coordinates (16, 3) of the sub-triangles' centroids after two midpoint
    subdivisions of a triangle (equal areas)."""
    tris = np.eye(3)[None]
    for _ in range(2):
        a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
        ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
        tris = np.concatenate([np.stack(t, axis=1) for t in
                               ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])  # fmt: skip
    return tris.mean(axis=1)


SUB_POINTS = _centroids()


def sampling_error(
    sampled: np.ndarray, values: np.ndarray, areas: np.ndarray, comm: MPI.Comm
) -> tuple[float, np.ndarray]:
    """Collective: the sampling error r of a field (module docstring) from its samples (n,) and
    its values at the sub-cell points (n, k) of this rank's owned cells of the given areas, and
    each cell's ``|sample - mean|`` (n,)."""
    means = values.mean(axis=1)
    total = comm.allreduce(np.array([areas @ means, areas.sum()]), op=MPI.SUM)
    spread = np.abs(values - total[0] / total[1]).mean(axis=1)
    misplaced = np.abs(sampled - means)
    sums = comm.allreduce(np.array([areas @ misplaced, areas @ spread]), op=MPI.SUM)
    return (float(sums[0] / sums[1]) if sums[1] > 0.0 else 0.0), misplaced


def _worst_place(misplaced: np.ndarray, midpoints: np.ndarray, comm: MPI.Comm) -> np.ndarray:
    """Collective: the midpoint of the cell whose sample is furthest from its mean, over the
    ranks (the smallest point among equals, so any number of ranks names the same place)."""
    mine = (np.inf, 0.0, 0.0)
    if len(misplaced):
        i = int(np.argmax(misplaced))
        mine = (-float(misplaced[i]), float(midpoints[i, 0]), float(midpoints[i, 1]))
    return np.array(min(comm.allgather(mine))[1:])


@dataclass(frozen=True)
class Sampling:
    """How well the run's mesh samples one varying field."""

    key: str  # the field's key, e.g. "material.E"
    error: float  # its sampling error r
    place: tuple[float, float]  # the midpoint of the cell whose sample is furthest off
    refine: str  # the key of the mesh that samples it: "tissue.h" or "tissue.H"
    size: float  # that key's value

    @property
    def warning(self) -> str | None:
        """The warning text, or None within ``MAX_SAMPLING_ERROR``."""
        if self.error <= MAX_SAMPLING_ERROR:
            return None
        mesh = "fine mesh" if self.refine == "tissue.h" else "coarse grid"
        return (
            f"{self.key} changes over distances shorter than the {mesh} that samples it: the "
            f"samples misplace {self.error:.1%} of its variation (more than "
            f"{MAX_SAMPLING_ERROR:.0%}), most near x1 = {self.place[0]:.4g}, x2 = "
            f"{self.place[1]:.4g}; refine {self.refine} (now {self.size:g}) for results that "
            "do not depend on the mesh"
        )


def field_sampling(
    scene: Scene,
    vertices: np.ndarray,
    areas: np.ndarray,
    W: sp.csr_matrix,
    nodes: np.ndarray,
    per_cell: bool,
    comm: MPI.Comm,
) -> list[Sampling]:
    """Collective: the sampling of each of the scene's varying fields on this rank's owned
    cells (the same list on every rank).

    Args:
        vertices: (n, 3, 2) the owned fine cells' corners; areas: (n,) their areas.
        W: (n, m) P1 weights of the coarse ``nodes`` (m, 2) at the owned cells' midpoints.
        per_cell: E is sampled per fine cell (the surrogate path), else at the coarse nodes.
    """
    midpoints = vertices.mean(axis=1)
    points = np.einsum("qk,nkd->nqd", SUB_POINTS, vertices)
    coarse = {f"cell.{k}" for k in ("l1", "l2", "theta", "w")} | {"material.nu"}
    if not per_cell:
        coarse.add("material.E")
    out = []
    for key, field in scene.parameter_fields().items():
        if field.is_constant:
            continue
        values = field(points[..., 0], points[..., 1])
        if key in coarse:
            sampled, refine = W @ field(nodes[:, 0], nodes[:, 1]), "tissue.H"
        else:
            sampled, refine = field(midpoints[:, 0], midpoints[:, 1]), "tissue.h"
        r, misplaced = sampling_error(sampled, values, areas, comm)
        size = scene.tissue.H if refine == "tissue.H" else scene.tissue.h
        place = tuple(_worst_place(misplaced, midpoints, comm))
        out.append(Sampling(key, r, place, refine, size))
    return out
