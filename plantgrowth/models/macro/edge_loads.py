"""The macro model's edge loads (docs/model.md section 4) in the configuration the forms apply
them: tractions per grown length ``Jg |Fg^-T N|`` (linear kinematics) or per current length
``|cof(F) N|`` (finite), and total forces ``{force = [F1, F2]}`` spread uniformly over that length.

A traction's resultant follows its edge's length as the tissue grows, so tractions balanced on
the reference edges drift apart under non-uniform growth, and the pinned vertex carries the
difference as a point force. :meth:`EdgeLoads.balance` measures that drift every step (the
summary's ``load_imbalance``); a total force keeps its resultant by construction: its traction
``F / L`` is updated to the edge's length ``L`` before each solve (finite kinematics: until
``L`` of the solution agrees with the ``L`` it was solved with to ``FORCE_LENGTH_RTOL``).
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem, mesh
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.forms.expressions import UFL_OPS
from plantgrowth.models.step import LoadBalance
from plantgrowth.scene.loads import ALONG, EdgeForce, Load

FORCE_LENGTH_RTOL = 1e-13
"""Largest relative change of a loaded edge's length between the solve and its solution that
leaves a total force's traction as it is: below the 1e-10 balance the tests ask for, above
round-off of the length integrals (~1e-15 relative)."""


class EdgeLoads:
    """The traction of each loaded edge as a UFL vector, the length and x1-resultant forms, and
    the total forces' tractions kept equal to ``F / L``.

    Args:
        loads: edge name -> load (scene.loads).
        msh: the fine mesh.
        facets: its boundary facet tags; ``tags``: edge name -> tag.
        length_factor: ``(n) -> the length of a unit reference boundary element`` in the
            configuration the forms use (``grown_length`` or ``current_length``), named
            ``length_name`` ("grown" or "current") in messages.
    """

    def __init__(self, loads: dict[str, Load], msh: mesh.Mesh, facets, tags: dict[str, int],
                 length_factor, length_name: str) -> None:  # fmt: skip
        self.comm = msh.comm
        self.length_name = length_name
        self.ds = ufl.Measure("ds", domain=msh, subdomain_data=facets)
        self.n = ufl.FacetNormal(msh)
        self.names = sorted(loads)
        self.tags = {name: tags[name] for name in self.names}
        self.forces: dict[str, tuple[fem.Constant, np.ndarray]] = {}
        self.tractions = {name: self._traction(msh, name, loads[name]) for name in self.names}
        factor = length_factor(self.n)
        self._length = {n: fem.form(factor * self.ds(self.tags[n])) for n in self.names}
        self._x1 = {
            n: fem.form(self.tractions[n][0] * factor * self.ds(self.tags[n])) for n in self.names
        }

    def _traction(self, msh: mesh.Mesh, edge: str, load: Load) -> ufl.core.expr.Expr:
        """A Constant (numbers; a total force's ``F / L``), or a UFL vector of the expressions
        of s, the coordinate along the edge (plantgrowth/scene/loads.py)."""
        if isinstance(load, EdgeForce):
            traction = fem.Constant(msh, np.zeros(2, dtype=PETSc.ScalarType))
            self.forces[edge] = (traction, np.asarray(load.force, dtype=float))
            return traction
        if all(isinstance(c, float) for c in load):
            return fem.Constant(msh, np.asarray(load, dtype=PETSc.ScalarType))
        s = ufl.SpatialCoordinate(msh)[ALONG[edge]]
        return ufl.as_vector(
            [c if isinstance(c, float) else c.evaluate(UFL_OPS, s=s) for c in load]
        )

    def terms(self, term) -> ufl.Form | int:
        """``term(f, n, ds)`` summed over the loaded edges (0 without loads)."""
        out = 0
        for name in self.names:
            out += term(self.tractions[name], self.n, self.ds(self.tags[name]))
        return out

    def _integral(self, form: fem.Form) -> float:
        return self.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM)

    def lengths(self) -> dict[str, float]:
        """Each loaded edge's length in the forms' configuration (collective)."""
        return {name: self._integral(self._length[name]) for name in self.names}

    def update_forces(self) -> float:
        """Set each total force's traction to ``F / L`` at the current state (collective);
        returns the largest relative change of a traction (0 without total forces)."""
        change = 0.0
        lengths = self.lengths() if self.forces else {}
        for name, (traction, force) in self.forces.items():
            new = force / lengths[name]
            old = np.array(traction.value)
            scale = np.abs(new).max()
            change = max(change, np.abs(new - old).max() / scale if scale > 0.0 else 0.0)
            traction.value = new
        return change

    def balance(self) -> LoadBalance:
        """The x1 resultant of each edge's load at the current state (collective)."""
        return LoadBalance(
            {name: self._integral(self._x1[name]) for name in self.names},
            self.lengths(),
            self.length_name,
        )
