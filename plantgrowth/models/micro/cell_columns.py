"""The cells' columns of a membrane form: for a form ``L(indicator)`` linear in a per-cell
DG0 indicator and integrated over the lumen membranes, the n vectors

    b_c = L(chi_c)    (chi_c: 1 on biological cell c, 0 elsewhere)

as one sparse (owned dofs x n) matrix, from ONE assembly per call: L(1) = sum_c b_c, split by
the columns' supports, which are disjoint (a dof lies on one lumen's membrane) and found once by
n assemblies of a structural form (positive on every dof of a cell's membrane facets).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from dolfinx import fem
from petsc4py import PETSc
from scipy import sparse


def _assemble(vector: PETSc.Vec, form: fem.Form, bcs: list) -> np.ndarray:
    """This rank's owned entries of ``form``, zero on the Dirichlet dofs (collective)."""
    with vector.localForm() as local:
        local.set(0.0)
    fem.petsc.assemble_vector(vector, form)
    # membrane facets next to a ghost cell: their share goes to the owner
    vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    fem.petsc.set_bc(vector, bcs)
    return vector.array


class CellColumns:
    """The columns ``b_c`` of membrane forms over the same membranes.

    Args:
        support: a structural form (e.g. ``chi . (1, 1) . psi`` over the membranes: nonzero on
            every dof of the membrane facets where chi = 1) in the indicator.
        indicator: the DG0 indicator the forms read; set_cells: sets it from values per
            biological cell; n: the number of cells; bcs: the Dirichlet conditions.
    """

    def __init__(
        self, support: fem.Form, indicator: fem.Function,
        set_cells: Callable[[fem.Function, np.ndarray], None], n: int, bcs: list,
    ) -> None:  # fmt: skip
        self.indicator, self.set_cells, self.n, self.bcs = indicator, set_cells, n, bcs
        self.vector = fem.petsc.create_vector(support)
        rows, cols = [], []
        for c in range(n):
            set_cells(indicator, np.eye(1, n, c)[0])
            nonzero = np.flatnonzero(_assemble(self.vector, support, bcs))
            rows.append(nonzero)
            cols.append(np.full(len(nonzero), c))
        self.rows, self.cols = np.concatenate(rows), np.concatenate(cols)
        if len(np.unique(self.rows)) != len(self.rows):
            raise ValueError("two cells' membranes share a dof: their columns cannot be split")

    def __call__(self, form: fem.Form) -> sparse.csc_matrix:
        """(owned dofs, n): this rank's rows of ``b_c = form(chi_c)``, zero on the Dirichlet
        dofs (collective)."""
        self.set_cells(self.indicator, np.ones(self.n))
        values = _assemble(self.vector, form, self.bcs)[self.rows]
        return sparse.csc_matrix((values, (self.rows, self.cols)), (len(self.vector.array), self.n))
