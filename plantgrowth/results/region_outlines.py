"""The outlines of a run's named regions (``[regions]`` of its scene.toml) for ``plantgrowth
render --regions``: the edges between the growth units inside a region and those outside it (or
the tissue's edge), drawn on the deformed tissue.

Membership is the run's own (plantgrowth/models/regions.py): the region's condition at each
unit's reference midpoint, i.e. each fine triangle's midpoint (macro; from the written mesh, so a
midpoint within round-off of a region's edge may fall on the other side when the mesh is stored
as float32) or each biological cell's centre (micro, from the scene's cell and ``micro.nx``).
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np

from plantgrowth.base.errors import InputError
from plantgrowth.results.reader import ResultSeries
from plantgrowth.scene import parse_scene
from plantgrowth.scene.micro_tissue import micro_tissue
from plantgrowth.scene.parameters import parse_parameters
from plantgrowth.scene.regions import Region, parse_regions


def boundary_edges(polygons: list[np.ndarray], inside: np.ndarray) -> np.ndarray:
    """(k, 2) vertex pairs of the edges of the ``inside`` polygons (vertex index loops) that no
    other inside polygon shares: the outline of their union."""
    loops = [p for p, keep in zip(polygons, inside, strict=True) if keep]
    if not loops:
        return np.empty((0, 2), dtype=np.int64)
    edges = np.sort(np.vstack([np.column_stack([p, np.roll(p, -1)]) for p in loops]), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    return unique[counts == 1]


def _scene_data(directory: Path) -> dict:
    """The run's scene.toml (a side of a ``model = "both"`` run: its parent's)."""
    for path in (directory / "scene.toml", directory.parent / "scene.toml"):
        if path.is_file():
            return tomllib.loads(path.read_text(encoding="utf-8"))
    raise InputError(f"--regions: no scene.toml in {directory} or its parent")


def region_outlines(series: ResultSeries, t: float) -> dict[str, np.ndarray]:
    """Region name -> (k, 2, 2) segments of its outline at time t on the deformed tissue; an
    InputError if the run's scene has no regions."""
    data = _scene_data(series.directory)
    regions: dict[str, Region] = parse_regions(
        data.get("regions", {}), parse_parameters(data.get("parameters", {}))
    )
    if not regions:
        raise InputError(f"--regions: the run's scene ({series.directory}) has no [regions]")
    outline = series.outlines
    if outline is None:  # macro: the fine triangles
        x = series.points + (series.displacement(t) if "u" in series.names else 0.0)
        polygons = list(series.triangles)
        midpoints = series.points[series.triangles].mean(axis=1)
    else:  # micro: the cells' polygons, in cell id order
        x = outline.deformed(t)
        ids = outline.cell_ids(t)
        starts = outline.segments[np.argsort(ids, kind="stable"), 0]
        polygons = np.split(starts, np.cumsum(np.bincount(ids))[:-1])
        scene = parse_scene(data)
        tissue = micro_tissue(scene)
        midpoints = tissue.centres
        if len(midpoints) != len(polygons):
            raise InputError(
                f"--regions: {series.directory} has {len(polygons)} cells, its scene.toml "
                f"{len(midpoints)} ({tissue.name})"
            )
    return {
        name: x[boundary_edges(polygons, region.inside(midpoints))]
        for name, region in regions.items()
    }
