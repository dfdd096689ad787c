"""The resolution rule of the stability check (docs/model.md section 10, "Resolution").

The homogenized model describes a tissue at the scale of a cell and above. Where the law loses
strong ellipticity, the non-elliptic units (macro: fine cells) are grouped into connected sets
(units that share a mesh vertex, across ranks). A set whose grown area ``sum Jg A`` is below the
grown area of one cell there, ``Jg |Y|`` (area-weighted over the set), is a *singular point* of
the macro fields (a held edge's corner, a re-entrant corner, the staircase of a sharp jump):
beneath the model's resolution, reported, never a stop. A larger set is a loss of stability the
model can see. Sets are found on rank 0 from the gathered non-elliptic units (few where a run is
sound; all of them only where the whole tissue fails).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components


@dataclass(frozen=True)
class NonellipticSet:
    """One connected set of non-elliptic units.

    Attributes:
        place: (x1, x2), reference coordinates of its least stable unit.
        area: its grown area, ``sum Jg A`` over its units.
        reference_area: its reference area, ``sum A``.
        cell_area: the grown area of one cell there, ``Jg |Y|`` (area-weighted mean over the
            set); 0 where the model resolves every wall (micro: no set is beneath it).
        smallest: the smallest normalised acoustic eigenvalue in the set.
        stress: (2, 2) the walls' stress S_w at its least stable unit.
    """

    place: tuple[float, float]
    area: float
    reference_area: float
    cell_area: float
    smallest: float
    stress: np.ndarray

    @property
    def cells(self) -> float:
        """Its size in cells, ``area / (Jg |Y|)`` (inf where no cell size applies)."""
        return self.area / self.cell_area if self.cell_area > 0.0 else np.inf

    @property
    def singular(self) -> bool:
        """True if the set fits within one cell: a singular point, not an instability."""
        return self.area < self.cell_area

    def where(self) -> str:
        x1, x2 = self.place
        return f"x1 = {x1:.4g}, x2 = {x2:.4g}"


def connected_sets(vertices: np.ndarray) -> tuple[int, np.ndarray]:
    """(number of sets, (n,) the set of each unit) for units given by (n, k) global vertex
    indices: two units are connected where they share a vertex."""
    n = len(vertices)
    if n == 0:
        return 0, np.zeros(0, dtype=np.int64)
    _, vertex = np.unique(vertices.reshape(-1), return_inverse=True)
    unit = np.repeat(np.arange(n), vertices.shape[1])
    # the bipartite graph unit -- vertex; its components restricted to the units
    graph = coo_matrix((np.ones(len(unit)), (unit, n + vertex)), shape=(n + vertex.max() + 1,) * 2)
    _, labels = connected_components(graph, directed=False)
    labels = labels[:n]
    _, labels = np.unique(labels, return_inverse=True)
    return int(labels.max()) + 1, labels


def sets_of(
    values: np.ndarray,
    vertices: np.ndarray | None,
    areas: np.ndarray,
    grown: np.ndarray,
    cell_areas: np.ndarray,
    points: np.ndarray,
    stress: np.ndarray,
) -> list[NonellipticSet]:
    """The connected sets of the non-elliptic units given (all ranks' gathered), largest first.

    Args:
        values: (n,) each unit's smallest normalised acoustic eigenvalue (negative).
        vertices: (n, k) global vertex indices per unit; None: the units form one set.
        areas: (n,) reference areas A.
        grown: (n,) grown areas ``Jg A``.
        cell_areas: (n,) ``Jg |Y|`` at each unit (0: no resolution limit).
        points: (n, 2) places.
        stress: (n, 2, 2) the walls' stress per unit.
    """
    if vertices is None:
        count, labels = (1, np.zeros(len(values), dtype=np.int64)) if len(values) else (0, None)
    else:
        count, labels = connected_sets(vertices)
    out = []
    for k in range(count):
        mine = np.flatnonzero(labels == k)
        worst = mine[np.argmin(values[mine])]
        area = float(grown[mine].sum())
        cell_area = float(np.dot(grown[mine], cell_areas[mine]) / area) if area > 0.0 else 0.0
        out.append(NonellipticSet(
            tuple(float(x) for x in points[worst]), area, float(areas[mine].sum()), cell_area,
            float(values[worst]), stress[worst].copy(),
        ))  # fmt: skip
    return sorted(out, key=lambda s: -s.area)
