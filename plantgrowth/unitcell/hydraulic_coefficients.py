"""The unit cell's hydraulic coefficients (docs/model.md, "Water fluxes"): the Biot tensor b, the
storage 1/M and the conductivity kappa per unit wall conductivity L, for a growth tensor Fg.

From the cell problems of docs/model.md section 3 (``K_hom``, ``dbar[v]``, ``phi_w``) and the
lattice of section 2 (``d_k``: b1, b2, b2 - b1; ``t_k``, ``l_k``: the wall family each crosses):
    b = (1 - phi_w) I - K_hom                 1/M = -tr dbar[v]
    kappa / L = (1 / (Jg |Y|)) sum_k |Fg t_k| l_k (Fg d_k) (x) (Fg d_k)
b and 1/M are what the lumens' area change per unit grown cell area is made of:
    (1 / (Jg |Y|)) int_Gamma (e Fg y + w^{ij} e_ij + v P) . Jg Fg^{-T} n_c dgamma = b : e + P / M;
:func:`lumen_area_change` computes its left side on the membrane, the derivation's check.
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.base.errors import check_growth_tensor
from plantgrowth.base.tensors import symmetric_components
from plantgrowth.forms.cell_problems import lumen_area_change_form
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.meshes.unit_cell import FACET_TAGS
from plantgrowth.unitcell.solver import STRAIN_PROBLEMS, CellResult, CellSolver


def biot_tensor(result: CellResult) -> np.ndarray:
    """``b = (1 - phi_w) I - K_hom`` (2, 2): the lumens' area change per unit macro strain, and
    the turgor's share of the stress, ``-b P``."""
    if result.K_hom is None:
        raise ValueError("the Biot tensor needs K_hom: solve the pressure problem (pressure=True)")
    return (1.0 - result.phi_w) * np.eye(2) - result.K_hom


def storage(result: CellResult) -> float:
    """``1/M = -tr dbar[v]``: the lumens' area change per unit turgor and unit grown cell area
    at zero macro strain (> 0; scales as 1/E)."""
    if result.dbar_v is None:
        raise ValueError(
            "the storage 1/M needs dbar[v]: solve with pressure=True and strain_averages=True"
        )
    return -float(np.trace(result.dbar_v))


def conductivity(cell: HoneycombCell, Fg: object) -> np.ndarray:
    """``kappa / L = (1/(Jg |Y|)) sum_k |Fg t_k| l_k (Fg d_k) (x) (Fg d_k)`` (2, 2), grown
    frame: the tissue's water conductivity per unit wall conductivity L. ``d_k`` joins a cell's
    centre to the neighbour across the walls of family k (b1 across the walls of length l1,
    b2 across AB and DE, b2 - b1 across BC and EF). Raises InputError for a bad ``Fg``."""
    Fg = np.array(check_growth_tensor("Fg", Fg))
    vertical, rising, falling = cell.wall_tangents()  # e2; (c, s)/l2 (BC, EF); (-c, s)/l2
    crossings = (
        (cell.b1, vertical, cell.l1),
        (cell.b2, falling, cell.l2),
        (cell.b2 - cell.b1, rising, cell.l2),
    )
    kappa = np.zeros((2, 2))
    for d, t, length in crossings:
        kappa += np.linalg.norm(Fg @ t) * length * np.outer(Fg @ d, Fg @ d)
    return kappa / (np.linalg.det(Fg) * cell.area)


def lumen_area_change(solver: CellSolver, Fg: np.ndarray, e: np.ndarray, P: float) -> float:
    """``(1/(Jg |Y|)) int_Gamma (e Fg y + w^{ij} e_ij + v P) . Jg Fg^{-T} n_c dgamma``: the
    lumen's area change per unit grown cell area under the macro strain e (2x2, symmetric,
    grown frame) and the turgor P, computed on the membrane from the correctors of the
    solver's last solve, which must be at this ``Fg`` and have solved the pressure problem
    (collective on ``solver.comm``)."""
    e = np.asarray(e, dtype=float)
    if e.shape != (2, 2) or not np.array_equal(e, e.T):
        raise ValueError(f"e must be a symmetric 2x2 strain, got {e.tolist()}")
    if solver.shape != "hexagon":
        raise ValueError("the lumen is closed inside the hexagonal cell only (shape='hexagon')")
    *w, v = solver.correctors()
    if len(w) != len(STRAIN_PROBLEMS):
        raise ValueError("the lumen's area change needs v: solve with pressure=True")
    mesh = solver.unit_cell.mesh
    y = ufl.SpatialCoordinate(mesh)
    strain = fem.Constant(mesh, e.astype(PETSc.ScalarType))
    F = fem.Constant(mesh, np.asarray(Fg, dtype=PETSc.ScalarType))
    # sum over all i, j: the off-diagonal corrector w^12 = w^21 counts twice
    pairs = zip(STRAIN_PROBLEMS, w, strict=True)
    z = ufl.dot(strain * F, y) + fem.Constant(mesh, PETSc.ScalarType(P)) * v
    z += sum((1 + (i != j)) * strain[i, j] * w_ij for (i, j), w_ij in pairs)
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=solver.unit_cell.facet_tags)
    form = fem.form(lumen_area_change_form(z, F, ufl.FacetNormal(mesh), ds(FACET_TAGS["membrane"])))
    change = solver.comm.allreduce(fem.assemble_scalar(form), op=MPI.SUM)
    return change / (np.linalg.det(Fg) * solver.area)


def hydraulic_summary(result: CellResult, cell: HoneycombCell, Fg: np.ndarray) -> dict:
    """The CLI's JSON keys: ``b`` and ``kappa`` (per unit L) as [11, 22, 12], ``inv_M``."""
    b, kappa = biot_tensor(result), conductivity(cell, Fg)
    return {
        "b": symmetric_components(b),
        "inv_M": storage(result),
        "kappa": symmetric_components(kappa),
    }
