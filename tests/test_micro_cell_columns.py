"""The cells' columns of the micro water step (plantgrowth/models/micro/cell_columns.py): one
assembly split by the membranes' supports equals the n assemblies with one cell's indicator (up
to round-off entries off the membranes, where the exact columns are 0)."""

from __future__ import annotations

import numpy as np
import pytest
from mpi4py import MPI

from plantgrowth.models.micro.cell_columns import _assemble
from plantgrowth.models.micro.model import MicroModel
from plantgrowth.scene import parse_scene

SPLIT_ROUND_OFF = 1e-14
"""On the supports, relative to the largest entry: the one assembly adds, at a cell's membrane
dofs, only the other cells' facets' basis values there (0, or of order eps; measured 0)."""
OFF_SUPPORT_ROUND_OFF = 1e-12
"""Off the supports, relative to the largest entry: the enclosed area depends only on its
membrane's dofs, so its derivative's other entries (the membrane elements' other dofs, through
grad psi) are exactly 0, assembled as cancelling element terms of up to ~100 times the largest
entry (x ~ 10 against wall elements of size ~0.1): round-off of ~100 eps (measured 7e-14)."""


@pytest.mark.mpi
def test_one_assembly_split_by_supports_equals_each_cells_assembly():
    """Finite kinematics at a deformed state (u = (0.01 x2^2, 0.02 x1 x2): every component of
    the follower load and of the area's derivative nonzero), load and area columns."""
    supply = [{"edge": e, "conductance": 1.0, "potential": 0.0} for e in ("left", "right")]
    scene = parse_scene({
        "model": "micro", "kinematics": "finite", "growth": {"law": "stress"},
        "time": {"t_max": 1.0, "dt": 1.0}, "micro": {"nx": 4, "resolution": 1},
        "hydraulics": {"osmotic": 0.001, "conductivity": 1.0, "supply": supply},
    })  # fmt: skip
    turgor = MicroModel(scene, MPI.COMM_WORLD).turgor
    parts, columns, n = turgor.parts, turgor.columns, turgor.water.n
    parts.u.interpolate(lambda x: np.stack([0.01 * x[1] ** 2, 0.02 * x[0] * x[1]]))
    parts.u.x.scatter_forward()
    for form in (turgor.load_column, turgor.area_column):
        split = columns(form).toarray()
        each = np.empty_like(split)
        for c in range(n):
            parts.set_cells(turgor.indicator, np.eye(1, n, c)[0])
            each[:, c] = _assemble(columns.vector, form, parts.bcs)
        scale = MPI.COMM_WORLD.allreduce(np.abs(each).max(), op=MPI.MAX)
        on = np.zeros_like(each, dtype=bool)
        on[columns.rows, columns.cols] = True
        local = np.array([np.abs(split - each)[on].max(initial=0.0),
                          np.abs(each[~on]).max(initial=0.0), np.abs(split[~on]).max(initial=0.0)])
        worst = np.empty(3)
        MPI.COMM_WORLD.Allreduce(local, worst, op=MPI.MAX)
        on_error, off_each, off_split = worst
        assert scale > 0.0 and on_error <= SPLIT_ROUND_OFF * scale
        assert off_each <= OFF_SUPPORT_ROUND_OFF * scale and off_split == 0.0
