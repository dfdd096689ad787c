"""Validation of field values where they are used (issue 11): expressions can leave their range
anywhere, so they are checked at every place the run evaluates them.

Places (docs/model.md sections 5, 7): the coarse-grid nodes (cell problems: geometry, E, nu) and the
fine-mesh cells' midpoints (P1, eta, tau, Fg0) of the macro domain actually simulated (the scene's
rectangle, or the region a micro tissue covers), and the cell centres of a micro tissue. Every
field is checked at all of its model's places against :data:`plantgrowth.scene.RANGES`, Fg0
(entries and det Fg0 > 0) where it is used (fine cells, cell centres), and the cell geometry at
the coarse nodes is checked to be a feasible, affordable unit cell. The first bad place in
(key, x1, x2) order is reported, so serial and parallel runs give the same SceneError, e.g.
``material.nu = 0.6 at x1 = 3.5, x2 = 0 (coarse node 7) is out of range: ...``.

Scenes without non-constant expressions or a varying Fg0 need none of this: the ends of a linear
field are its extremes, checked when the scene is built (:mod:`plantgrowth.scene`).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from mpi4py import MPI

from plantgrowth.base.errors import SceneError
from plantgrowth.meshes.honeycomb import GeometryError
from plantgrowth.meshes.tissue import wall_mesh_size
from plantgrowth.meshes.unit_cell import mesh_size
from plantgrowth.scene.fields import ExprField, check_value
from plantgrowth.scene.limits import FG0_RANGE, RANGES
from plantgrowth.scene.micro_tissue import micro_tissue
from plantgrowth.scene.schema import Scene

DET_RANGE = (0.0, np.inf, True, True)


def needs_place_checks(scene: Scene) -> bool:
    """True if some field is a non-constant expression, Fg0 varies (det Fg0 is not linear) or
    the scene has regions (which must hold a growth unit)."""
    fields = scene.parameter_fields().values()
    varying_Fg0 = any(not f.is_constant for f in scene.growth.Fg0_fields().values())
    expressions = any(isinstance(f, ExprField) and not f.is_constant for f in fields)
    return varying_Fg0 or expressions or bool(scene.regions)


def _first_bad(values: np.ndarray, points: np.ndarray, interval: tuple) -> int | None:
    """Index of the bad value at the lexicographically smallest point (None if all good)."""
    low, high, lo_open, hi_open = interval
    with np.errstate(invalid="ignore"):
        below = values <= low if lo_open else values < low
        above = values >= high if hi_open else values > high
    bad = np.flatnonzero(~np.isfinite(values) | below | above)
    if bad.size == 0:
        return None
    return int(bad[np.lexsort((points[bad, 1], points[bad, 0]))[0]])


def _place(point: np.ndarray, label: str) -> str:
    return f"at x1 = {point[0]:.6g}, x2 = {point[1]:.6g} ({label})"


def _checks(scene: Scene, points: np.ndarray, growth: bool) -> Iterator[tuple]:
    """(key, values at the points, interval) of every field, and with ``growth`` of every
    entry of Fg0 and of det Fg0 (key "growth.Fg0: det")."""
    x1, x2 = points[:, 0], points[:, 1]
    for key, f in scene.parameter_fields().items():
        yield key, f(x1, x2), RANGES[key]
    if growth:
        for key, f in scene.growth.Fg0_fields().items():
            yield key, f(x1, x2), FG0_RANGE
        yield "growth.Fg0: det", np.linalg.det(scene.growth.initial(x1, x2)), DET_RANGE


def check_ranges(
    scene: Scene, points: np.ndarray, what: str, comm: MPI.Comm, numbered=False, growth=True
) -> None:
    """Collective: SceneError on every rank unless every field (and with ``growth`` Fg0 and
    its determinant) lies in its range at all ``points`` ((n, 2), this rank's share). Places
    are named ``what``, with their index if ``numbered`` (replicated points)."""
    found = None  # (key order, x1, x2, message)
    for order, (key, values, interval) in enumerate(_checks(scene, points, growth)):
        i = _first_bad(np.asarray(values, dtype=float), points, interval)
        if i is None:
            continue
        label = f"{what} {i}" if numbered else what
        try:
            check_value(key, float(values[i]), *interval, place=_place(points[i], label))
        except SceneError as e:
            found = (order, float(points[i, 0]), float(points[i, 1]), str(e))
        break
    candidates = [c for c in comm.allgather(found) if c is not None]
    if candidates:
        raise SceneError(min(candidates)[3])


def check_geometry(scene: Scene, nodes: np.ndarray) -> None:
    """SceneError unless the unit cell at every coarse node is feasible and affordable."""
    for i in np.lexsort((nodes[:, 1], nodes[:, 0])):
        x1, x2 = nodes[i]
        place = f" ({_place(nodes[i], f'coarse node {i}')})"
        cell = scene.cell.check_at(x1, x2, place)
        try:
            mesh_size(cell, scene.accuracy.cell_resolution, "accuracy.cell_resolution")
        except GeometryError as e:
            raise SceneError(f"{e}{place}") from None


def check_macro_places(scene: Scene, nodes: np.ndarray, midpoints: np.ndarray, comm) -> None:
    """Collective: the fields at the coarse nodes ``nodes`` (replicated) and this rank's fine-cell
    ``midpoints`` of a macro domain (``scene`` spanning its extent), as the run evaluates them
    (:meth:`plantgrowth.models.macro.domain.MacroDomain.places`)."""
    check_ranges(scene, nodes, "coarse node", MPI.COMM_SELF, numbered=True, growth=False)
    check_geometry(scene, nodes)
    check_ranges(scene, midpoints, "fine cell midpoint", comm)
    check_regions(scene, midpoints, "fine cell midpoint", comm)


def check_micro_tissue(scene: Scene) -> None:
    """A scene's given cells (``[tissue] cells``) make voids and an affordable walls mesh
    (nothing for the honeycomb: Scene.check_micro checks it)."""
    if scene.tissue.cells is not None:
        try:
            wall_mesh_size(micro_tissue(scene), scene.micro_resolution)
        except GeometryError as e:
            raise SceneError(str(e)) from None


def check_micro_places(scene: Scene, nx: int | None = None) -> None:
    """The fields at the cell centres of the micro tissue: the scene's (its cells, or micro.nx's
    honeycomb), or the honeycomb of ``nx`` cells per row."""
    tissue = micro_tissue(scene, nx)
    tissue_scene = scene.over_extent(*tissue.bounding_box)
    check_ranges(tissue_scene, tissue.centres, "cell", MPI.COMM_SELF, numbered=True)
    check_regions(scene, tissue.centres, "cell centre", MPI.COMM_SELF)


def check_regions(scene: Scene, points: np.ndarray, what: str, comm: MPI.Comm) -> None:
    """Collective: SceneError on every rank unless each region's condition is finite at every
    growth unit's reference midpoint (``points``, this rank's share, named ``what``) and
    non-zero at one at least (plantgrowth/scene/regions.py)."""
    for name, region in scene.regions.items():
        values = region.values(points)
        found = None
        if not np.all(np.isfinite(values)):
            bad = np.flatnonzero(~np.isfinite(values))
            i = bad[np.lexsort((points[bad, 1], points[bad, 0]))[0]]
            found = (float(points[i, 0]), float(points[i, 1]), float(values[i]))
        candidates = [c for c in comm.allgather(found) if c is not None]
        key = f"regions.{name}"
        if candidates:
            x1, x2, value = min(candidates)
            raise SceneError(
                f"{key}.expr = {value:g} {_place(np.array([x1, x2]), what)}: a region's "
                "condition must be finite wherever the run evaluates it"
            )
        count = comm.allreduce(int(np.count_nonzero(values != 0.0)), op=MPI.SUM)
        if count == 0:
            total = comm.allreduce(len(points), op=MPI.SUM)
            raise SceneError(
                f"{key}: the region is empty on the mesh: its condition "
                f"{region.expression.text!r} is 0 at all {total} {what}s of the tissue (a "
                "growth unit belongs to a region when the condition holds at its reference "
                "midpoint); widen it or remove it"
            )
