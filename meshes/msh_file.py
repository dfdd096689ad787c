"""A tissue mesh read from a gmsh ``.msh`` file (``tissue.mesh``), with its named groups.

The file holds linear triangles in one or more surface physical groups, the curve group
``symmetry`` (on x2 = 0), the point group ``pinned`` (a vertex of the triangles) and any other
named curve groups (loadable edges). :func:`inspect_msh` checks a file and measures it (every
rank may call it: it reads the file into a scratch gmsh model); :func:`read_msh` builds the
distributed mesh with gmsh on ``model_rank`` and ``gmshio.model_to_mesh``, as
``gmshio.read_from_msh`` does, but keeping the group names (and gmsh initialised).
gmsh (and dolfinx's gmshio, which imports it) is imported by the functions that mesh, through
:func:`gmsh_api.gmsh_api`: its 0.35-0.45 s are paid only when a mesh is built.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from .gmsh_api import gmsh_api

SYMMETRY = "symmetry"
PINNED = "pinned"
LINE, TRIANGLE = 1, 2  # gmsh element types of 2-node lines and 3-node triangles


class MshError(ValueError):
    """A file that is no usable tissue mesh; the message does not name the scene key."""


@dataclass(frozen=True)
class MshInfo:
    """What a tissue .msh file holds.

    Attributes:
        curves: curve group name -> (physical tag, total length, lowest x2, highest x2, normal
            axis: 0 if every line is parallel to x2, 1 if parallel to x1, else None; to 1e-12
            of the mesh's size, round-off).
        pinned: coordinates of the ``pinned`` point.
        lower: smallest (x1, x2) of the triangles' nodes.
        upper: largest (x1, x2) of the triangles' nodes.
        n_triangles: number of triangles.
    """

    curves: dict[str, tuple[int, float, float, float, int | None]]
    pinned: tuple[float, float]
    lower: tuple[float, float]
    upper: tuple[float, float]
    n_triangles: int


def _groups(dim: int) -> dict[str, int]:
    """Named physical groups of a dimension: name -> tag."""
    gmsh = gmsh_api()

    model = gmsh.model
    return {model.getPhysicalName(d, t): t for d, t in model.getPhysicalGroups(dim) if d == dim}


def _elements(dim: int, tag: int, kind: int, what: str) -> np.ndarray:
    """(n, nodes per element) node tags of a physical group's elements, all of type ``kind``."""
    gmsh = gmsh_api()

    out = []
    for entity in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
        types, _, nodes = gmsh.model.mesh.getElements(dim, entity)
        if any(t != kind for t in types):
            raise MshError(
                f"{what} has elements other than linear {['', 'lines', 'triangles'][dim]}"
            )
        out += [np.asarray(n, dtype=np.int64).reshape(-1, dim + 1) for n in nodes]
    return np.concatenate(out) if out else np.empty((0, dim + 1), dtype=np.int64)


def _normal_axis(ends: np.ndarray, nodes: np.ndarray) -> int | None:
    """The axis along which the normal of every line ``ends`` (n, 2, 2) points (0: all lines
    parallel to x2, 1: all parallel to x1), to 1e-12 of the nodes' extent; None otherwise."""
    tol = 1e-12 * max(float(np.abs(nodes).max()), 1.0)
    steps = np.abs(ends[:, 1] - ends[:, 0])
    return next((axis for axis in (0, 1) if steps[:, axis].max() <= tol), None)


def _inspect() -> MshInfo:
    """Check and measure the current gmsh model (see :class:`MshInfo`)."""
    gmsh = gmsh_api()

    surfaces = [t for d, t in gmsh.model.getPhysicalGroups(2)]
    if not surfaces:
        raise MshError("no surface physical group (the tissue's triangles)")
    triangles = np.concatenate([_elements(2, t, TRIANGLE, "a surface group") for t in surfaces])
    if len(triangles) == 0:
        raise MshError("the surface groups hold no triangles")
    tags, coords, _ = gmsh.model.mesh.getNodes()
    index = np.zeros(int(tags.max()) + 1, dtype=np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    x = np.asarray(coords).reshape(-1, 3)[:, :2]
    used = x[index[np.unique(triangles)]]
    curves = {}
    owner: dict[int, str] = {}
    for name, tag in _groups(1).items():
        for entity in gmsh.model.getEntitiesForPhysicalGroup(1, tag):
            if entity in owner:
                raise MshError(f"curve {entity} is in both groups {owner[entity]!r} and {name!r}")
            owner[entity] = name
        lines = _elements(1, tag, LINE, f"curve group {name!r}")
        if len(lines) == 0:
            raise MshError(f"the curve group {name!r} has no line elements")
        ends = x[index[lines]]
        length = float(np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1).sum())
        x2 = ends[:, :, 1]
        curves[name] = (tag, length, float(x2.min()), float(x2.max()), _normal_axis(ends, used))
    points = _groups(0)
    if PINNED not in points:
        raise MshError(f"no point group {PINNED!r} (the point where u1 = 0)")
    pinned = gmsh.model.mesh.getNodesForPhysicalGroup(0, points[PINNED])[0]
    if len(pinned) != 1 or pinned[0] not in set(triangles.ravel().tolist()):
        raise MshError(f"the point group {PINNED!r} must be one vertex of the triangles")
    p = x[index[int(pinned[0])]]
    return MshInfo(
        curves, (float(p[0]), float(p[1])), tuple(used.min(axis=0)), tuple(used.max(axis=0)),
        len(triangles),
    )  # fmt: skip


def inspect_msh(path: str | Path) -> MshInfo:
    """Read a .msh file into a scratch gmsh model and check it: MshError if it cannot be read,
    has no triangles, no ``pinned`` point, or mixes element kinds."""
    gmsh = gmsh_api()

    gmsh.model.add("inspect")
    try:
        try:
            gmsh.merge(str(path))
        except Exception as e:  # gmsh raises a bare Exception with its own message
            raise MshError(f"not a readable gmsh mesh ({e})") from None
        return _inspect()
    finally:
        gmsh.model.remove()


def read_msh(path: str | Path, comm: MPI.Comm = MPI.COMM_WORLD, model_rank: int = 0):
    """The distributed mesh of a checked .msh file: ``(mesh, cell_tags, facet_tags, curves)``,
    ``curves`` = curve group name -> facet tag (its physical tag)."""
    gmsh = gmsh_api()
    from dolfinx.io import gmshio

    names = None
    try:
        if comm.rank == model_rank:
            gmsh.model.add("tissue mesh")
            gmsh.merge(str(path))
            names = _groups(1)
        names = comm.bcast(names, root=model_rank)
        return (*gmshio.model_to_mesh(gmsh.model, comm, model_rank, gdim=2), names)
    finally:
        if comm.rank == model_rank:
            gmsh.model.remove()
