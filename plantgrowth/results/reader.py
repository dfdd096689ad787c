"""Read a run's ``fields.xdmf`` + ``fields.h5`` (and ``coarse.xdmf``) back (serial, h5py and
matplotlib's triangle finder only; no dolfinx).

The XDMF files map the meshes and every (function, time) to an HDF5 file and dataset, so they
are the only index read here: no HDF5 path is guessed. That covers every layout ``plantgrowth
run`` has written: dolfinx 0.5's (mesh at ``fields.h5:/Mesh/mesh/geometry``, functions at
``fields.h5:/Function/<name>/<time string>``) and the per-step one (mesh at
``fields.h5:/Mesh/geometry``, functions at ``fields/step_NNNNNN.h5:/<name>``). In all:

- geometry (N x 2, or padded to 3) and topology (triangles, M x 3);
- ``u``: point data at the N geometry nodes, padded to 3 components;
- cell fields (``Fg``, ``G``, ``sigma_hom``, ...): DG0 data in topology order, tensors as 9
  row-major components of a 3 x 3 (the 2D tensor is components 0, 1, 3, 4);
- micro runs: the cells' outlines in ``cells.xdmf`` (2-node lines over the polygon vertices,
  u at the vertices, cell_id per line): :class:`OutlineSeries`;
- E_hom's components (``E1111``, ...): in ``coarse.xdmf``, at the nodes of the coarse grid where
  the cell problems are solved (earlier runs wrote them on the fine cells, in ``fields.xdmf``).
  :meth:`ResultSeries.cell_field` interpolates them to the fine cells as the model does (P1 on
  the coarse triangles at the cell midpoints), so readers of either layout get fine-cell values.

Typical use::

    series = read_series("results/reference_stress")
    t = series.times[-1]
    x = series.points + series.displacement(t)
    trG = series.cell_field("G", t, "tr")
    loops = boundary_outline(series.points, series.triangles)
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from plantgrowth.meshes.honeycomb import polygon_area

COMPONENTS = ("11", "12", "21", "22", "tr", "det")
"""Reductions of a 2D tensor field accepted by :meth:`ResultSeries.cell_field`."""
_INDEX = {"11": 0, "12": 1, "21": 3, "22": 4}  # row-major positions in the padded 3 x 3
NODE_FIELDS = ("u", "P", "psi")
"""The fields written at the fine mesh's nodes (docs/outputs.md); the others are per triangle."""


@dataclass
class ResultSeries:
    """The mesh and the time series of one run directory.

    Attributes:
        directory: the run directory.
        points: reference node coordinates, (N, 2).
        triangles: node indices of each cell, (M, 3).
        times: the output times of ``u`` (sorted).
        datasets: ``{function name: {time: (HDF5 file, dataset path)}}`` from fields.xdmf.
        coarse: the coarse grid and its node fields (from coarse.xdmf), or None.
        outlines: the micro cells' outlines (from cells.xdmf), or None.
    """

    directory: Path
    points: np.ndarray
    triangles: np.ndarray
    times: list[float]
    datasets: dict[str, dict[float, tuple[Path, str]]] = field(default_factory=dict)
    coarse: CoarseSeries | None = None
    outlines: OutlineSeries | None = None

    @property
    def names(self) -> list[str]:
        """The functions written in this run (fine and coarse)."""
        return sorted(self.datasets | (self.coarse.datasets if self.coarse else {}))

    def _read(self, name: str, t: float) -> np.ndarray:
        if name not in self.datasets:
            raise KeyError(f"no field {name!r} in {self.directory} (has {self.names})")
        return _read_at(self.datasets[name], name, t)

    def displacement(self, t: float) -> np.ndarray:
        """The displacement u at the nodes at time t, (N, 2)."""
        return self._read("u", t)[:, :2]

    def field(self, name: str, t: float) -> np.ndarray:
        """The field at time t as :meth:`displacement`, :meth:`node_field` or
        :meth:`cell_field` (raw tensors) read it, by where it was written."""
        if name == "u":
            return self.displacement(t)
        return self.node_field(name, t) if name in NODE_FIELDS else self.cell_field(name, t)

    def node_field(self, name: str, t: float) -> np.ndarray:
        """A scalar field of the fine mesh's nodes (:data:`NODE_FIELDS`) at time t, (N,)."""
        return self._read(name, t).reshape(len(self.points))

    def cell_field(self, name: str, t: float, component: str | None = None) -> np.ndarray:
        """A DG0 field at time t, one value (or row) per triangle.

        Args:
            name: the function's name, e.g. "G", "Fg", "sigma_hom", "E1111" (a coarse-node
                field is interpolated to the cells, see :meth:`CoarseSeries.at_points`).
            t: an output time.
            component: for a tensor field, one of :data:`COMPONENTS`; None returns the raw data
                (M, 9) for tensors, (M,) for scalars.
        """
        if self.coarse is not None and name in self.coarse.datasets:
            return self.coarse.at_points(name, t, self.points[self.triangles].mean(axis=1))
        data = self._read(name, t)
        if data.ndim == 2 and data.shape[1] == 1:
            data = data[:, 0]
        if component is None:
            return data
        if data.ndim != 2 or data.shape[1] != 9:
            raise ValueError(f"{name} is not a 2D tensor field; component {component!r} is invalid")
        if component in _INDEX:
            return data[:, _INDEX[component]]
        if component == "tr":
            return data[:, 0] + data[:, 4]
        if component == "det":
            return data[:, 0] * data[:, 4] - data[:, 1] * data[:, 3]
        raise ValueError(f"component {component!r} is not one of {COMPONENTS}")


@dataclass
class CoarseSeries:
    """The coarse grid of a macro run and its node fields (``coarse.xdmf``).

    Attributes:
        points: coarse node coordinates, (n, 2).
        triangles: node indices of each coarse triangle, (m, 3).
        datasets: ``{function name: {time: (HDF5 file, dataset path)}}``.
    """

    points: np.ndarray
    triangles: np.ndarray
    datasets: dict[str, dict[float, tuple[Path, str]]]

    def node_field(self, name: str, t: float) -> np.ndarray:
        """The field's values at the coarse nodes at time t, (n,)."""
        if name not in self.datasets:
            raise KeyError(f"no coarse field {name!r} (has {sorted(self.datasets)})")
        return _read_at(self.datasets[name], name, t).reshape(len(self.points))

    def at_points(self, name: str, t: float, points: np.ndarray) -> np.ndarray:
        """The field's P1 interpolant on the coarse triangles at ``points`` (k, 2), (k,)."""
        from matplotlib.tri import LinearTriInterpolator, Triangulation

        grid = Triangulation(self.points[:, 0], self.points[:, 1], self.triangles)
        values = LinearTriInterpolator(grid, self.node_field(name, t))(points[:, 0], points[:, 1])
        if np.ma.is_masked(values):
            raise ValueError(f"{name}: some points lie outside the coarse grid")
        return np.asarray(values)


@dataclass
class OutlineSeries:
    """The outlines of a micro run's cells (``cells.xdmf``): polygon edges as lines.

    Attributes:
        points: reference vertex coordinates, (n, 2).
        segments: the two vertices of each edge, (m, 2).
        datasets: ``{function name: {time: (HDF5 file, dataset path)}}`` (u, cell_id).
    """

    points: np.ndarray
    segments: np.ndarray
    datasets: dict[str, dict[float, tuple[Path, str]]]

    def deformed(self, t: float) -> np.ndarray:
        """Vertex coordinates moved by the displacement at time t, (n, 2)."""
        return self.points + _read_at(self.datasets["u"], "u", t)[:, :2]

    def cell_ids(self, t: float) -> np.ndarray:
        """The cell of each edge, (m,)."""
        return _read_at(self.datasets["cell_id"], "cell_id", t).reshape(-1).astype(np.int64)


def _read_at(series: dict[float, tuple[Path, str]], name: str, t: float) -> np.ndarray:
    """The dataset of ``series`` at time t (to round-off)."""
    key = min(series, key=lambda s: abs(s - t))
    if abs(key - t) > 1e-9 * max(1.0, abs(t)):
        raise KeyError(f"{name} has no output at t = {t!r} (nearest {key!r})")
    return _load(*series[key])


def _load(h5file: Path, dataset: str) -> np.ndarray:
    with h5py.File(h5file, "r") as f:
        return np.asarray(f[dataset][...])


def _reference(xdmf: Path, item: ET.Element | None) -> tuple[Path, str]:
    """(HDF5 file, dataset) of an XDMF ``DataItem`` "file.h5:/path" (file relative to the XDMF)."""
    if item is None or not (item.text or "").strip() or item.get("Format", "HDF") != "HDF":
        raise ValueError(f"{xdmf}: expected an HDF DataItem")
    name, _, dataset = item.text.strip().partition(":")
    return xdmf.parent / name, dataset


def _index(xdmf: Path) -> tuple[np.ndarray, np.ndarray, dict]:
    """Node coordinates (n, 2), triangles (m, 3) and ``{name: {time: reference}}`` of an XDMF
    time series."""
    root = ET.parse(xdmf).getroot()
    geometry = topology = None
    datasets: dict[str, dict[float, tuple[Path, str]]] = {}
    for grid in root.iter("Grid"):
        if grid.get("GridType") != "Uniform":
            continue
        if geometry is None and grid.find("Geometry") is not None:
            geometry = _reference(xdmf, grid.find("Geometry/DataItem"))
            topology = _reference(xdmf, grid.find("Topology/DataItem"))
        time = grid.find("Time")
        if time is None:
            continue
        for attribute in grid.findall("Attribute"):
            name = attribute.get("Name", "")
            reference = _reference(xdmf, attribute.find("DataItem"))
            datasets.setdefault(name, {})[float(time.get("Value"))] = reference
    if geometry is None or topology is None:
        raise ValueError(f"{xdmf} has no mesh")
    return _load(*geometry)[:, :2], _load(*topology).astype(np.int64), datasets


def read_series(directory: str | os.PathLike) -> ResultSeries:
    """Open the run directory written by ``plantgrowth run SCENE -o DIR``.

    Raises:
        FileNotFoundError: if ``fields.xdmf`` is missing.
    """
    directory = Path(directory)
    if not (directory / "fields.xdmf").is_file():
        raise FileNotFoundError(f"{directory / 'fields.xdmf'} not found: not a run directory?")
    points, triangles, datasets = _index(directory / "fields.xdmf")
    times = sorted(datasets.get("u", {}) or {t for s in datasets.values() for t in s})
    coarse = outlines = None
    if (directory / "coarse.xdmf").is_file():
        coarse = CoarseSeries(*_index(directory / "coarse.xdmf"))
    if (directory / "cells.xdmf").is_file():
        outlines = OutlineSeries(*_index(directory / "cells.xdmf"))
    return ResultSeries(directory, points, triangles, times, datasets, coarse, outlines)


def boundary_outline(points: np.ndarray, triangles: np.ndarray) -> list[np.ndarray]:
    """The boundary of a triangulation as closed loops of node indices.

    Boundary edges are the edges used by exactly one triangle; they are chained into loops.
    Each loop is an index array (first node not repeated), oriented counter-clockwise in
    ``points``; loops are sorted by enclosed area, largest (the outer boundary) first. Apply the
    indices to ``points + u`` to get the deformed outline.

    Args:
        points: node coordinates, (N, 2).
        triangles: node indices, (M, 3).
    """
    tri = np.asarray(triangles, dtype=np.int64)
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    boundary = unique[counts == 1]
    neighbours: dict[int, list[int]] = {}
    for a, b in boundary.tolist():
        neighbours.setdefault(a, []).append(b)
        neighbours.setdefault(b, []).append(a)
    unused = {tuple(e) for e in boundary.tolist()}
    loops = []
    while unused:
        start, nxt = unused.pop()
        loop = [start]
        previous, current = start, nxt
        while current != start:
            loop.append(current)
            # take any unused edge at this node (more than one only at pinch nodes)
            for candidate in neighbours[current]:
                edge = (min(current, candidate), max(current, candidate))
                if edge in unused:
                    unused.remove(edge)
                    previous, current = current, candidate
                    break
            else:  # open chain: cannot happen for a triangulation, stop rather than loop
                break
        del previous
        loops.append(np.array(loop, dtype=np.int64))
    pts = np.asarray(points)[:, :2]
    oriented = [loop if polygon_area(pts[loop]) >= 0 else loop[::-1] for loop in loops]
    return sorted(oriented, key=lambda loop: -abs(polygon_area(pts[loop])))
