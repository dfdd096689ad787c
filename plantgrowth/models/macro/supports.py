"""The edges where the macro problem holds u (docs/model.md section 4): the symmetry plane x2 = 0
(u2 = 0) and the held edges of ``[supports]`` (u_i = 0 on the components each holds), their
Dirichlet conditions, and the force the held edges exert on the tissue.

That force (the supports' reaction) is the weak form's residual ``R(u; psi)``, assembled without
boundary conditions, summed over the dofs the held edges hold: ``R_i = int S : grad(psi_i) -
(applied loads)_i`` is the force the boundary exerts at node i beyond the applied loads, so the
sum over an edge's nodes is the edge's total reaction, exactly for the discrete solution. The u2
dof of a node on x2 = 0 counts for the symmetry plane, not for a held edge through that node
(the mirror's x2 force is no support's).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.models.macro.boundary import Boundary


def edge_dofs(
    V: fem.FunctionSpace, boundary: Boundary, tags: tuple[int, ...], i: int
) -> np.ndarray:
    """The dofs of component i of the P1 vector space V on the facets tagged ``tags`` (indices
    into V's unrolled local vector)."""
    found = np.sort(np.concatenate([boundary.facets.find(tag) for tag in tags]))
    return fem.locate_dofs_topological(V.sub(i), 1, found)


class HeldEdges:
    """The symmetry plane's and the held edges' conditions, and the held edges' force.

    Args:
        V: the displacement space (P1 vector).
        boundary: the fine mesh's tagged boundary.
        held: edge name -> the components of u held at zero there (Scene.held_components).
    """

    def __init__(self, V: fem.FunctionSpace, boundary: Boundary, held: dict[str, tuple[int, ...]]):
        self.V = V
        self.symmetry = edge_dofs(V, boundary, boundary.symmetry, 1)
        self.dofs = {}  # component -> the dofs the held edges hold at zero
        for i in (0, 1):
            tags = tuple(boundary.edges[edge] for edge, held_i in held.items() if i in held_i)
            if tags:
                self.dofs[i] = np.unique(edge_dofs(V, boundary, tags, i))
        self._counted = {
            i: np.setdiff1d(d, self.symmetry) if i else d for i, d in self.dofs.items()
        }
        self._residual: Callable[[], ufl.Form] | None = None
        self._form: fem.FormMetaClass | None = None
        self._vector: PETSc.Vec | None = None

    def conditions(self) -> list[fem.DirichletBCMetaClass]:
        """``u2 = 0`` on x2 = 0 and ``u_i = 0`` on the held dofs of each component."""
        zero = PETSc.ScalarType(0.0)
        return [fem.dirichletbc(zero, self.symmetry, self.V.sub(1))] + [
            fem.dirichletbc(zero, dofs, self.V.sub(i)) for i, dofs in self.dofs.items()
        ]

    def set_residual(self, residual: Callable[[], ufl.Form]) -> None:
        """The weak form's residual ``R(u; psi)``, made and compiled at the first :meth:`force`
        (a scene without supports never pays for ``ufl.action``'s derivative expansion)."""
        self._residual, self._form = residual, None

    def force(self) -> tuple[float, float]:
        """Collective: the total force (F1, F2) the held edges exert on the tissue at the
        current u."""
        if self._form is None:
            self._form = fem.form(self._residual())
            self._vector = fem.petsc.create_vector(self._form)
        b = self._vector
        with b.localForm() as local:
            local.set(0.0)
        fem.petsc.assemble_vector(b, self._form)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        owned = len(b.array)  # the owned entries: held dofs beyond them are other ranks'
        local = [float(b.array[d[d < owned]].sum()) if (d := self._counted.get(i)) is not None
                 else 0.0 for i in (0, 1)]  # fmt: skip
        total = self.V.mesh.comm.allreduce(np.array(local), op=MPI.SUM)
        return float(total[0]), float(total[1])
