"""The tissue's elastic strain as a biologist reads it (issue 21, item 3): the field
``elastic_strain`` (largest principal magnitude), ``elastic_strain_tensor`` (the tensor) and
the step's peak with its place (summary.csv ``elastic_strain_max``, ``_x1``, ``_x2``).

The strain is the model's elastic strain in the grown frame: ``eps_el`` with linear
kinematics, the Green-Lagrange ``Ee = (Fe^T Fe - I) / 2`` of ``Fe = (I + grad u) Fg^-1`` with
finite kinematics; macro per fine cell, micro averaged over each cell's own walls (pointwise
wall strains are singular at the walls' re-entrant corners). For a symmetric
``[[a, b], [b, d]]`` with principal values ``m +- r`` (``m = (a + d) / 2``,
``r = hypot((a - d) / 2, b)``) the largest principal magnitude is ``|m| + r``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from dolfinx import fem
from dolfinx.mesh import Mesh
from mpi4py import MPI

from plantgrowth.scene.limits import STRAIN_FIELDS

TIE = 1e-9
"""Units whose value is within this relative distance of the peak count as tied with it; the
place is then the tied unit of smallest (x1, x2), so a uniform tissue reports the same place in
serial and under mpirun (their values differ by round-off, ~1e-14)."""
PLACE_ROUNDING = 1e-9
"""Coordinates are compared after rounding to this (a unit's midpoint carries round-off)."""


def principal_magnitude(eps: np.ndarray) -> np.ndarray:
    """(n,) ``max(|e1|, |e2|) = |m| + r`` of the symmetric part of (n, 2, 2) strains."""
    a, d = eps[:, 0, 0], eps[:, 1, 1]
    b = 0.5 * (eps[:, 0, 1] + eps[:, 1, 0])
    return np.abs(0.5 * (a + d)) + np.hypot(0.5 * (a - d), b)


@dataclass(frozen=True)
class StrainPeak:
    """The largest elastic strain of a step.

    Attributes:
        value: the largest principal magnitude over the tissue.
        place: (x1, x2), reference configuration: the midpoint of the fine cell (macro) or the
            centroid of the biological cell's reference polygon (micro: cells.csv's x1_ref,
            x2_ref) where it is.
    """

    value: float
    place: tuple[float, float]


def strain_peak(magnitudes: np.ndarray, points: np.ndarray, comm: MPI.Comm) -> StrainPeak:
    """Collective: the :class:`StrainPeak` of this rank's units (pass MPI.COMM_SELF for values
    every rank holds whole).

    Args:
        magnitudes: (n,) :func:`principal_magnitude` of the owned units.
        points: (n, 2) their reference places.
    """
    value = comm.allreduce(float(magnitudes.max(initial=0.0)), op=MPI.MAX)
    tied = magnitudes >= value * (1.0 - TIE)
    candidates = np.asarray(points)[tied]
    mine = None
    if len(candidates):
        key = np.round(candidates / PLACE_ROUNDING)
        mine = tuple(float(x) for x in candidates[np.lexsort((key[:, 1], key[:, 0]))[0]])
    found = [p for p in comm.allgather(mine) if p is not None]
    place = min(found, key=lambda p: (round(p[0] / PLACE_ROUNDING), round(p[1] / PLACE_ROUNDING)))
    return StrainPeak(value, place)


class StrainFields:
    """The DG0 output functions of the strain fields in ``fields`` (the others are ignored):
    ``elastic_strain`` (scalar) and ``elastic_strain_tensor`` (2 x 2).

    Args:
        mesh: the mesh the model writes.
        fields: the scene's ``output.fields``.
    """

    def __init__(self, mesh: Mesh, fields: tuple[str, ...]) -> None:
        spaces = {
            "elastic_strain": lambda: fem.FunctionSpace(mesh, ("DG", 0)),
            "elastic_strain_tensor": lambda: fem.TensorFunctionSpace(mesh, ("DG", 0)),
        }
        self.functions = {
            name: fem.Function(spaces[name](), name=name)
            for name in STRAIN_FIELDS
            if name in fields
        }

    def fill(self, eps: np.ndarray, set_values: Callable[[fem.Function, np.ndarray], None]) -> None:
        """Store the asked fields of the (n, 2, 2) strains with ``set_values(function,
        values)`` (the model's per-unit writer: fine cells or biological cells)."""
        for name, function in self.functions.items():
            values = principal_magnitude(eps) if name == "elastic_strain" else eps
            set_values(function, values)
