"""The XDMF 3 indexes of a run's time series (``fields.xdmf``, ``coarse.xdmf``, ``cells.xdmf``):
the mesh in ``fields.h5``, one grid per written step pointing into its step file
``fields/step_NNNNNN.h5`` (:mod:`plantgrowth.runner.output` writes both)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STEP_DIR = "fields"

ATTRIBUTE_TYPES = {1: ("Scalar", 1), 2: ("Vector", 3), 4: ("Tensor", 9)}
"""Block size -> XDMF attribute type and its padded width (2D vectors/tensors padded to 3D)."""


def pad(values: np.ndarray, dtype: np.dtype | str) -> np.ndarray:
    """Values (n, block size) as ``dtype`` and padded to 3D (:data:`ATTRIBUTE_TYPES`): a 2D
    vector gets a zero third component, a 2 x 2 tensor (row-major) zero third row and column."""
    n, bs = values.shape
    if bs not in (2, 4):
        return np.ascontiguousarray(values, dtype=dtype)
    out = np.zeros((n, ATTRIBUTE_TYPES[bs][1]), dtype=dtype)
    if bs == 2:
        out[:, :2] = values
    else:
        out[:, 0:2], out[:, 3:5] = values[:, 0:2], values[:, 2:4]
    return out


@dataclass(frozen=True)
class Attribute:
    """One field of a time series: its XDMF attribute and its dataset in each step file."""

    name: str
    dataset: str
    kind: str  # Scalar | Vector | Tensor
    center: str  # Node | Cell
    shape: tuple[int, int]
    precision: int  # bytes per value

    def xml(self, step: int) -> str:
        dims = " ".join(map(str, self.shape))
        return (
            f'        <Attribute Name="{self.name}" AttributeType="{self.kind}" '
            f'Center="{self.center}">\n'
            f'          <DataItem Dimensions="{dims}" NumberType="Float" '
            f'Precision="{self.precision}" '
            f'Format="HDF">{STEP_DIR}/step_{step:06d}.h5:/{self.dataset}</DataItem>\n'
            f"        </Attribute>\n"
        )


@dataclass(frozen=True)
class IndexMesh:
    """A mesh in fields.h5: ``/<group>/geometry`` and ``/<group>/topology`` (triangles, or
    2-node lines)."""

    group: str
    n_nodes: int
    n_cells: int
    nodes_per_cell: int = 3


def grid_xml(attributes: list[Attribute], step: int, t: float) -> str:
    """One step's grid of the temporal collection: the mesh's topology and geometry included,
    the time, the step file's attributes."""
    include = (
        "<xi:include xpointer=\"xpointer(/Xdmf/Domain/Grid[@GridType='Uniform'][1]/"
        '*[self::Topology or self::Geometry])" />'
    )
    return (
        f'      <Grid Name="step_{step}" GridType="Uniform">\n'
        f"        {include}\n"
        f'        <Time Value="{t!r}" />\n' + "".join(a.xml(step) for a in attributes)
        + "      </Grid>\n"
    )  # fmt: skip


def series_xml(mesh: IndexMesh, grids: list[str]) -> str:
    """XDMF 3: the mesh grid, then a temporal collection of the steps' grids
    (:func:`grid_xml`)."""
    group, n_nodes, n_cells, k = mesh.group, mesh.n_nodes, mesh.n_cells, mesh.nodes_per_cell
    kind = {3: "Triangle", 2: "Polyline"}[k]
    grid = (
        f'    <Grid Name="{group}" GridType="Uniform">\n'
        f'      <Topology TopologyType="{kind}" NumberOfElements="{n_cells}" '
        f'NodesPerElement="{k}">\n'
        f'        <DataItem Dimensions="{n_cells} {k}" NumberType="Int" Precision="8" '
        f'Format="HDF">fields.h5:/{group}/topology</DataItem>\n'
        f"      </Topology>\n"
        f'      <Geometry GeometryType="XY">\n'
        f'        <DataItem Dimensions="{n_nodes} 2" NumberType="Float" Precision="8" '
        f'Format="HDF">fields.h5:/{group}/geometry</DataItem>\n'
        f"      </Geometry>\n"
        f"    </Grid>\n"
    )
    return (
        '<?xml version="1.0"?>\n'
        '<Xdmf Version="3.0" xmlns:xi="http://www.w3.org/2001/XInclude">\n'
        "  <Domain>\n" + grid
        + '    <Grid Name="fields" GridType="Collection" CollectionType="Temporal">\n'
        + "".join(grids)
        + "    </Grid>\n  </Domain>\n</Xdmf>\n"
    )  # fmt: skip
