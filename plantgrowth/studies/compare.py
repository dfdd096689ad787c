"""Micro-macro comparison in delta = 1/Nx (docs/model.md sections 7-8, paper Fig. 2 d-j).

For each Nx the macro model runs on the region the micro tissue covers (the union of its cells'
mid-line hexagons, cut at x2 = 0) and the micro model on the walls. At the first time step the
macro displacement is evaluated on the micro walls and compared with [error]:
``e = sqrt( int (a - A)^2 / int A^2 )`` for u1 and u2. With water fluxes (``[hydraulics]``,
either kinematics) the macro model's cells are the micro tissue's (``cell_scale = 4 / Nx``:
:func:`plantgrowth.models.macro.domain.macro_domain`) and each cell's turgor is compared with
the macro field P at its centre (:func:`turgor_error`).
"""

from __future__ import annotations

import csv
import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import ufl
from dolfinx import fem
from matplotlib.tri import TrapezoidMapTriFinder, Triangulation
from mpi4py import MPI
from scipy.spatial import cKDTree

from plantgrowth.base.gather import MeshGather
from plantgrowth.meshes.cell_tissue import CellTissue
from plantgrowth.models import fibres
from plantgrowth.models.macro.domain import MacroDomain, macro_domain
from plantgrowth.models.macro.model import model_on
from plantgrowth.models.micro.model import MicroModel
from plantgrowth.runner.output import prepare_directory
from plantgrowth.runner.timeloop import run_model
from plantgrowth.scene import Scene

log = logging.getLogger("plantgrowth")

COLUMNS = [
    "nx", "delta", "err_u1", "err_u2", "err_ubar", "err_G", "err_u1_pinned",
    "rate_macro_t0", "rate_micro_t0", "rate_macro_tmax", "rate_micro_tmax",
    "seconds_macro", "seconds_micro", "dofs_macro", "dofs_micro",
    "err_u1_tmax", "err_u2_tmax", "err_ubar_tmax", "err_G_tmax",
    "err_fibre_angle_tmax", "fibre_order_macro_tmax", "fibre_order_micro_tmax",
    "err_P", "err_P_tmax",
]  # fmt: skip
"""The ``_tmax`` errors are the first-step ones at the last step (empty if only the first step
ran): both models are Lagrangian on their reference meshes, so u at t_max compares as at t = 0.
The fibre columns are empty without a director (a scene without fibres), the turgor columns
without water fluxes (a scene without ``[hydraulics]``)."""


@dataclass(frozen=True)
class P1Snapshot:
    """A P1 vector field gathered on every rank: node coordinates, triangles, nodal values."""

    points: np.ndarray  # (n, 2)
    triangles: np.ndarray  # (m, 3)
    values: np.ndarray  # (n, k): k = 2 for u, 1 for P

    @classmethod
    def gather(cls, u: fem.Function) -> P1Snapshot:
        """Collect a (distributed) P1 function, vector or scalar, on all ranks."""
        everywhere = MeshGather(u.function_space, root=None)
        return cls(everywhere.points(), everywhere.triangles(), everywhere.function(u))

    def evaluate(self, x: np.ndarray) -> np.ndarray:
        """Values at points x (k, 2); points outside (round-off at the boundary) extrapolate
        linearly from a triangle at their nearest node."""
        tri = Triangulation(self.points[:, 0], self.points[:, 1], self.triangles)
        found = TrapezoidMapTriFinder(tri)(x[:, 0], x[:, 1])
        missing = found < 0
        if np.any(missing):
            nearest = cKDTree(self.points).query(x[missing])[1]
            first_triangle = np.full(len(self.points), -1)
            first_triangle[self.triangles[::-1].ravel()] = np.repeat(
                np.arange(len(self.triangles))[::-1], 3
            )
            found[missing] = first_triangle[nearest]
        corners = self.points[self.triangles[found]]  # (k, 3, 2)
        T = np.stack([corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]], axis=2)
        lam = np.linalg.solve(T, (x - corners[:, 0])[..., None])[..., 0]
        weights = np.column_stack([1.0 - lam.sum(axis=1), lam])
        return np.einsum("kj,kjd->kd", weights, self.values[self.triangles[found]])


def macro_on_walls(u_micro: fem.Function, macro: P1Snapshot) -> fem.Function:
    """The macro displacement interpolated on the micro walls' P2 nodes."""
    V = u_micro.function_space
    A = fem.Function(V)
    A.x.array[:] = macro.evaluate(V.tabulate_dof_coordinates()[:, :2]).ravel()
    return A


def cell_mean_error(micro: MicroModel, A: fem.Function) -> float:
    """Relative error of the cell-mean displacement, [error] over cells instead of points:
    ``sqrt( sum_c Y_c |ubar_c - Abar_c|^2 / sum_c Y_c |Abar_c|^2 )`` with ubar_c, Abar_c the
    means of the micro and macro displacements over cell c's own walls and Y_c its hexagon's
    area; u1 in the zero-mean gauge (see :func:`relative_errors`). Averaging over a cell
    removes most of the periodic corrector delta (w^ij eps_el + v P1), which dominates the
    pointwise errors at small Nx, so this error sees the macro displacement itself: the
    stiffness E_hom and the turgor response K_hom."""
    weights = micro.hexagon_area / micro.hexagon_area.sum()
    ubar, Abar = micro.cell_means(micro.u), micro.cell_means(A)
    for mean in (ubar, Abar):
        mean[:, 0] -= weights @ mean[:, 0]
    return float(
        np.sqrt(weights @ np.sum((ubar - Abar) ** 2, axis=1) / (weights @ np.sum(Abar**2, axis=1)))
    )


def relative_errors(u_micro: fem.Function, A: fem.Function) -> dict[str, float]:
    """[error] for u1 and u2 on the micro walls (the macro field interpolated on their P2 nodes).

    u2 has no gauge freedom (u2 = 0 on the symmetry plane). u1 is defined up to a rigid shift
    along x1, which both models fix by u1 = 0 at the origin (docs/model.md section 4). In the micro
    tissue the origin lies in the middle of an outer wall, which turgor bows outwards by
    O(delta): that bulge shifts the whole micro u1 field. ``err_u1`` therefore compares both
    fields in the other gauge docs/model.md section 4 allows, zero mean of u1 over the walls (the
    rigid shift removed from each); ``err_u1_pinned`` is the same measure in the pinned gauge.
    """
    V = u_micro.function_space
    comm = V.mesh.comm

    def integral(expr) -> float:
        return comm.allreduce(fem.assemble_scalar(fem.form(expr * ufl.dx)), op=MPI.SUM)

    def error(a, b) -> float:
        return float(np.sqrt(integral((a - b) ** 2) / integral(b**2)))

    area = integral(fem.Constant(V.mesh, 1.0))
    shift_micro, shift_macro = integral(u_micro[0]) / area, integral(A[0]) / area
    return {
        "err_u1": error(u_micro[0] - shift_micro, A[0] - shift_macro),
        "err_u2": error(u_micro[1], A[1]),
        "err_u1_pinned": error(u_micro[0], A[0]),
    }


TIE = 1e-9
"""Relative distance within which fine cells count as equally near a point."""


def turgor_error(micro_P: np.ndarray, weights: np.ndarray, centres: np.ndarray,
                 macro_P: P1Snapshot) -> float:  # fmt: skip
    """Relative difference of the turgor, cell by cell, as [error] over cells:
    ``sqrt( sum_c Y_c (P_c - P(x_c))^2 / sum_c Y_c P(x_c)^2 )`` with P_c the micro model's
    turgor of cell c (one value per cell), P(x) the macro turgor field (P1, interpolated at the
    cell centre x_c) and Y_c the cell's hexagon area."""
    P = macro_P.evaluate(centres)[:, 0]
    return float(np.sqrt(np.sum(weights * (micro_P - P) ** 2) / np.sum(weights * P**2)))


def nearest_mean(points: np.ndarray, values: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Values (n, k) of the fine cell whose midpoint (``points``) is nearest to each point x,
    or the mean of those equally near (within :data:`TIE`): a cell centre is often a fine mesh
    vertex, and picking one of its triangles would depend on the order the fine cells were
    gathered in (serial against mpirun)."""
    k = min(8, len(points))
    distance, index = cKDTree(points).query(x, k=k)
    distance, index = distance.reshape(len(x), k), index.reshape(len(x), k)
    tied = distance <= distance[:, :1] * (1.0 + TIE)
    return np.einsum("ij,ijk->ik", tied, values[index]) / tied.sum(axis=1)[:, None]


def growth_rate_error(
    micro_G: np.ndarray, weights: np.ndarray, centres: np.ndarray, macro_G: CellSnapshot
) -> float:
    """Relative difference of the first-step growth rates, cell by cell:
    ``sqrt( sum_c A_c |G_c - G(x_c)|^2 / sum_c A_c |G(x_c)|^2 )`` with A_c the cells' areas and
    G(x) the macro rate in the fine cell nearest to the cell centre x_c (:func:`nearest_mean`)."""
    G = nearest_mean(macro_G.points, macro_G.values, centres).reshape(-1, 2, 2)
    num = np.sum(weights * np.sum((micro_G - G) ** 2, axis=(1, 2)))
    den = np.sum(weights * np.sum(G**2, axis=(1, 2)))
    return float(np.sqrt(num / den)) if den > 0.0 else float(np.sqrt(num))


def director_error(
    micro_angle: np.ndarray, weights: np.ndarray, centres: np.ndarray, macro_angle: CellSnapshot
) -> float:
    """Root-mean-square difference of the fibre directors, cell by cell, in degrees:
    ``sqrt( sum_c A_c d_c^2 / sum_c A_c )`` with ``d_c`` the angle of cell c minus the macro
    angle in the fine cell nearest to its centre (:func:`nearest_mean` of the axial vector
    ``(cos 2a, sin 2a)``, a director being an axis), reduced to (-90, 90]."""
    two_a = np.radians(2.0 * macro_angle.values[:, 0])
    axial = nearest_mean(
        macro_angle.points, np.column_stack([np.cos(two_a), np.sin(two_a)]), centres
    )
    macro = 0.5 * np.degrees(np.arctan2(axial[:, 1], axial[:, 0]))
    d = fibres.reduce_angle(micro_angle - macro)
    return float(np.sqrt(np.sum(weights * d**2) / np.sum(weights)))


@dataclass(frozen=True)
class CellSnapshot:
    """Per-cell values of a DG0 field and the cells' midpoints, gathered on every rank."""

    points: np.ndarray  # (n, 2)
    values: np.ndarray  # (n, k)

    @classmethod
    def gather(cls, points: np.ndarray, values: np.ndarray, comm: MPI.Comm) -> CellSnapshot:
        return cls(np.vstack(comm.allgather(points)), np.vstack(comm.allgather(values)))


def compare_one(
    scene: Scene, domain: MacroDomain, nx: int, outdir: Path, comm: MPI.Comm,
    resolution: int | None, n_steps: int | None, tissue: CellTissue | None = None,
) -> dict[str, float | None]:  # fmt: skip
    """Macro on the outline of the Nx tissue (or of ``tissue``'s cells: ``domain`` is then
    theirs), then micro; errors at the first and the last step (the t_max rates and errors are
    None when only the first step runs)."""
    last = scene.time.n_steps if n_steps is None else n_steps
    measured = (0, last) if last > 0 else (0,)
    snapshot: dict[tuple[str, int], P1Snapshot | CellSnapshot] = {}
    errors: dict[int, dict[str, float]] = {}

    def keep_macro(step: int, model) -> None:
        if step in measured:
            problem = model.problem
            snapshot["u", step] = P1Snapshot.gather(problem.u)
            n = problem.n_owned
            G = problem.cell_values(model.out.G)[:n]
            snapshot["G", step] = CellSnapshot.gather(problem.midpoints[:n, :2], G, comm)
            if model.director is not None:
                a = model.director.angle[:n].reshape(n, 1)
                snapshot["a", step] = CellSnapshot.gather(problem.midpoints[:n, :2], a, comm)
            if model.water is not None:
                snapshot["P", step] = P1Snapshot.gather(model.water.P)

    def measure_micro(step: int, model) -> None:
        if step in measured:
            centres = model.tissue.centres
            A = macro_on_walls(model.u, snapshot["u", step])
            errors[step] = relative_errors(model.u, A) | {
                "err_ubar": cell_mean_error(model, A),
                "err_G": growth_rate_error(
                    model.last_G, model.hexagon_area, centres, snapshot["G", step]
                ),
            }
            if model.director is not None:
                errors[step]["err_fibre_angle"] = director_error(
                    model.director.angle, model.hexagon_area, centres, snapshot["a", step]
                )
            if model.turgor is not None:
                errors[step]["err_P"] = turgor_error(
                    model.turgor.last.P, model.hexagon_area, centres, snapshot["P", step]
                )

    start = time.perf_counter()
    prepare_directory(outdir / "macro", comm)
    macro = model_on(domain, comm)
    macro_rows = run_model(
        macro, scene, outdir / "macro", comm, n_steps, keep_macro, label=f"Nx = {nx}, macro"
    )
    seconds_macro = time.perf_counter() - start
    start = time.perf_counter()
    prepare_directory(outdir / "micro", comm)
    micro = MicroModel(scene, comm, nx, resolution, tissue)
    micro_rows = run_model(
        micro, scene, outdir / "micro", comm, n_steps, measure_micro, label=f"Nx = {nx}, micro"
    )
    seconds_micro = time.perf_counter() - start
    for step, e in errors.items():
        log.info(
            "Nx = %d, step %d, relative errors: err_u1 = %.4g (pinned gauge %.4g), err_u2 = %.4g, "
            "err_ubar = %.4g, err_G = %.4g%s",
            nx, step, e["err_u1"], e["err_u1_pinned"], e["err_u2"], e["err_ubar"], e["err_G"],
            f", err_P = {e['err_P']:.4g}" if "err_P" in e else "",
        )  # fmt: skip
    at_tmax = errors.get(last) if last > 0 else None
    fibred = at_tmax is not None and "err_fibre_angle" in at_tmax
    watered = "err_P" in errors[0]
    return {
        "nx": nx, "delta": 1.0 / nx, **errors[0], "err_P": errors[0].get("err_P"),
        "err_P_tmax": at_tmax["err_P"] if watered and at_tmax is not None else None,
        **{f"{k}_tmax": None if at_tmax is None else at_tmax[k]
           for k in ("err_u1", "err_u2", "err_ubar", "err_G")},
        "rate_macro_t0": macro_rows[0]["growth_rate_area"],
        "rate_micro_t0": micro_rows[0]["growth_rate_area"],
        "rate_macro_tmax": None if n_steps == 0 else macro_rows[-1]["growth_rate_area"],
        "rate_micro_tmax": None if n_steps == 0 else micro_rows[-1]["growth_rate_area"],
        "seconds_macro": seconds_macro, "seconds_micro": seconds_micro,
        "dofs_macro": macro.problem.ndofs, "dofs_micro": micro.ndofs,
        "err_fibre_angle_tmax": at_tmax["err_fibre_angle"] if fibred else None,
        "fibre_order_macro_tmax": macro_rows[-1]["fibre_order"] if fibred else None,
        "fibre_order_micro_tmax": micro_rows[-1]["fibre_order"] if fibred else None,
    }  # fmt: skip


def fitted_rate(nx: list[int], errors: list[float]) -> float:
    """Least-squares slope p of ``log e = log C - p log Nx`` (e ~ delta^p)."""
    return float(-np.polyfit(np.log(nx), np.log(errors), 1)[0])


def run_compare(
    scene: Scene, nxs: list[int], outdir: Path, comm: MPI.Comm,
    resolution: int | None = None, first_step_only: bool = False,
    domains: dict[int, MacroDomain] | None = None,
) -> list[dict[str, float | None]]:  # fmt: skip
    """Compare macro and micro for each Nx; writes ``outdir/compare.csv`` and per-Nx runs. The
    macro side of each Nx runs on ``domains[nx]`` (the checked domains of
    :func:`plantgrowth.runner.scene_run.checked_domain`), else on a domain built here."""
    n_steps = 0 if first_step_only else None
    rows = []
    for nx in nxs:
        domain = domains[nx] if domains is not None else macro_domain(scene, comm, nx)
        rows.append(compare_one(scene, domain, nx, outdir / f"nx{nx}", comm, resolution, n_steps))
        if comm.rank == 0:
            with open(outdir / "compare.csv", "w", newline="") as f:
                writer = csv.writer(f)
                writer.writerow(COLUMNS)
                writer.writerows([["" if r[c] is None else f"{r[c]:.10g}" for c in COLUMNS]
                                  for r in rows])  # fmt: skip
    if len(rows) > 1:
        for key in ("err_u1", "err_u2", "err_ubar", "err_G", "err_P_tmax"):
            if any(r[key] is None for r in rows):
                continue  # err_P_tmax: a scene without water, or the first step only
            rate = fitted_rate([r["nx"] for r in rows], [r[key] for r in rows])
            log.info("%s ~ delta^%.2f (least-squares fit over Nx = %s)", key, rate, nxs)
    return rows
