"""The scene key ``[tissue] cells`` (issue 34, docs/real_tissues.md): where a tissue's cells come
from. ``cells = {voronoi = N, seed = S, regularity = r}`` generates them
(plantgrowth/meshes/voronoi_tissue.py); ``cells = "file"`` imports a label image (.tif, .tiff,
.png; needs ``tissue.pixel_size``) or a polygon table (.json, .csv). Parsing and the named errors
only: plantgrowth/scene/tissue_cells.py builds the cells."""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from plantgrowth.base.errors import SceneError
from plantgrowth.meshes.cell_polygons import CellPolygons
from plantgrowth.meshes.geometry_error import GeometryError
from plantgrowth.meshes.voronoi_tissue import voronoi_nx
from plantgrowth.scene.limits import MAX_LENGTH
from plantgrowth.scene.values import check_keys, in_range, integer, show

IMAGE_SUFFIXES = (".tif", ".tiff", ".png")
TABLE_SUFFIXES = (".json", ".csv")
MAX_SEED = 2**63 - 1
"""Largest ``tissue.cells.seed`` (numpy's generators take any non-negative integer; TOML's is
a signed 64-bit one)."""
ALONE = ("outline", "mesh", "width", "height")
"""Tissue keys that a ``cells`` tissue may not have: its cells set its shape and extent."""


@dataclass(frozen=True)
class GeneratedCells:
    """``cells = {voronoi = N, seed = S, regularity = r}``: N = Nx^2/2 cells, r in [0, 1]."""

    voronoi: int
    seed: int = 0
    regularity: float = 0.0

    @property
    def nx(self) -> int:
        """Cells per row of the honeycomb the tissue starts from (``N = Nx^2 / 2``)."""
        return voronoi_nx(self.voronoi)

    def to_toml(self) -> dict[str, Any]:
        return {"voronoi": self.voronoi, "seed": self.seed, "regularity": self.regularity}


@dataclass(frozen=True)
class ImportedCells:
    """``cells = "file"``: a label image or a polygon table (absolute path), its pixel size
    (required for an image; for a table, a factor on its coordinates, default 1)."""

    path: str
    pixel_size: float | None = None

    @property
    def is_image(self) -> bool:
        return self.path.lower().endswith(IMAGE_SUFFIXES)

    def to_toml(self) -> str:
        return self.path


CellsSpec = GeneratedCells | ImportedCells


def _generated(value: dict) -> GeneratedCells:
    check_keys(value, "tissue.cells.", ("voronoi", "seed", "regularity"))
    if "voronoi" not in value:
        raise SceneError(
            "tissue.cells.voronoi is required in a generated tissue: the number of cells, "
            "Nx^2/2 with Nx even (e.g. 32 for Nx = 8)"
        )
    try:
        voronoi_nx(value["voronoi"])
    except GeometryError as e:
        raise SceneError(str(e)) from None
    seed = integer("tissue.cells.seed", value.get("seed", 0), 0, MAX_SEED)
    r = in_range("tissue.cells.regularity", value.get("regularity", 0.0), 0.0, 1.0,
                 lo_open=False, hi_open=False)  # fmt: skip
    return GeneratedCells(value["voronoi"], seed, r)


def _imported(path: str, pixel_size: object) -> ImportedCells:
    key = f"tissue.cells = {path!r}"
    if not path.lower().endswith(IMAGE_SUFFIXES + TABLE_SUFFIXES):
        raise SceneError(
            f"{key}: not a label image (.tif, .tiff, .png) or a polygon table (.json, .csv)"
        )
    if not os.path.isfile(path):
        raise SceneError(f"{key}: file not found")
    size = None
    if pixel_size is not None:
        size = in_range("tissue.pixel_size", pixel_size, 0.0, MAX_LENGTH)
    elif path.lower().endswith(IMAGE_SUFFIXES):
        raise SceneError(
            f"tissue.pixel_size is required with a label image ({key}): the side of one pixel in "
            "the scene's length unit, a number > 0"
        )
    spec = ImportedCells(path, size)
    imported_cells(spec)  # a bad file is refused when the scene is read
    return spec


def imported_cells(spec: ImportedCells) -> CellPolygons:
    """The checked cells of an imported file, in the scene's length unit (docs/real_tissues.md);
    a SceneError names the file and the fault. Cached on the file's path, size, modification
    time and the pixel size: do not modify the result."""
    try:
        stat = os.stat(spec.path)
        return _imported_cells(spec, stat.st_mtime_ns, stat.st_size)
    except OSError as e:  # removed or unreadable since the scene was read
        raise SceneError(f"tissue.cells = {spec.path!r}: {e.strerror or e}") from None
    except GeometryError as e:
        raise SceneError(str(e)) from None


@lru_cache(maxsize=4)
def _imported_cells(spec: ImportedCells, mtime: int, size: int) -> CellPolygons:
    name = f"tissue.cells = {spec.path!r}"
    if not spec.is_image:
        from plantgrowth.meshes.polygon_table import table_cells

        return table_cells(spec.path, spec.pixel_size, name)
    from plantgrowth.meshes.label_checks import (
        absorb_specks,
        as_labels,
        check_labels,
        read_labels,
    )
    from plantgrowth.meshes.label_tracing import trace_cells

    labels = absorb_specks(as_labels(read_labels(spec.path, name), name))
    check_labels(labels, name)
    try:
        return trace_cells(labels, spec.pixel_size)
    except GeometryError as e:
        raise GeometryError(f"{name}: {e}") from None


def parse_cells(value: object, pixel_size: object = None) -> CellsSpec | None:
    """The parsed ``tissue.cells`` (a relative file path already made absolute), or None."""
    if value is None or isinstance(value, (GeneratedCells, ImportedCells)):
        return value
    if isinstance(value, dict):
        if pixel_size is not None:
            raise SceneError('tissue.pixel_size: only with an imported tissue.cells = "file"')
        return _generated(value)
    if isinstance(value, str):
        return _imported(value, pixel_size)
    raise SceneError(
        "tissue.cells: expected a table {voronoi = N, seed = S, regularity = r} or a file "
        f"name (a label image or a polygon table), got {show(value)}"
    )


def cells_table(tissue: dict, micro: dict, directory: Path) -> dict:
    """The raw ``[tissue]`` table with a ``cells`` file made absolute (a relative one is relative
    to ``directory``); checked with ``[micro]``: a ``cells`` tissue has no outline, mesh, width
    or height, and micro.nx only if it is the generated tissue's Nx."""
    if "cells" not in tissue:
        if "pixel_size" in tissue:
            raise SceneError('tissue.pixel_size: only with an imported tissue.cells = "file"')
        return tissue
    for key in ALONE:
        if key in tissue:
            raise SceneError(
                f"tissue.{key}: not with tissue.cells: the cells set the tissue's shape and extent"
            )
    spec = tissue["cells"]
    if "nx" in micro and not isinstance(spec, dict):
        raise SceneError(
            "micro.nx: not with an imported tissue.cells: the file gives the cells; remove micro.nx"
        )
    if "nx" in micro and micro["nx"] != (nx := parse_cells(spec).nx):
        raise SceneError(
            f"micro.nx = {show(micro['nx'])} is not the generated tissue's: tissue.cells.voronoi "
            f"= {spec['voronoi']} is Nx = {nx} (N = Nx^2/2); remove micro.nx or set it to {nx}"
        )
    if isinstance(spec, str):
        return tissue | {"cells": os.path.abspath(directory / spec)}
    return tissue
