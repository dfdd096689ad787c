"""The coupled macroscopic growth loop (paper Algorithm 1, MODEL.md section 5).

Per step: project Fg to the coarse nodes -> cell problems there (distinct inputs only) ->
interpolate E_hom, K_hom, phi_w, dbar, P2vec to the fine cells -> macro solve -> sigma_hom or
eps_hom -> growth rate G -> write the step -> Fg <- integrator(Fg, G, dt).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from plantgrowth import growth
from plantgrowth.coarse import CoarseGrid, project_to_nodes
from plantgrowth.errors import RunError
from plantgrowth.homogenization import Homogenizer
from plantgrowth.macro_problem import MacroProblem
from plantgrowth.output import FieldWriter, SummaryWriter
from plantgrowth.scene import Scene
from plantgrowth.tensors import VOIGT_NAMES, VOIGT_POSITIONS

log = logging.getLogger("plantgrowth")

SUMMARY_COLUMNS = [
    "step", "t", "area", "growth_rate_11", "growth_rate_22", "growth_rate_area",
    "u1_max", "u2_max", "det_Fg_min", "n_cell_solves", "residual",
    "seconds", "seconds_cells", "seconds_solve", "seconds_growth", "seconds_io",
]  # fmt: skip

RESIDUAL_BOUND = 1e-8
"""Largest accepted relative residual of the macro LU solve (round-off is ~1e-14)."""


class _Outputs:
    """The DG0/P1 functions written to fields.xdmf, only those the scene asks for."""

    def __init__(self, problem: MacroProblem, fields: tuple[str, ...]) -> None:
        self.fields = fields
        T0, Q0 = problem.T0, problem.Q0
        self.G = fem.Function(T0, name="G")
        self.sigma = fem.Function(T0, name="sigma_hom")
        self.eps = fem.Function(T0, name="eps_hom")
        self.E = [fem.Function(Q0, name=name) for name in VOIGT_NAMES]
        chosen = {"u": [problem.u], "Fg": [problem.Fg], "G": [self.G], "sigma_hom": [self.sigma],
                  "E_hom": self.E, "eps_hom": [self.eps]}  # fmt: skip
        self.functions = [f for name in fields for f in chosen[name]]


def _pruning_report(problem: MacroProblem, scene: Scene, strain_averages: bool) -> list[str]:
    skipped = []
    if problem.K is None:
        skipped.append("pressure: P1 = 0, no K_hom cell problem and no pressure term")
    if problem.P2vec is None:
        skipped.append("P1 has no gradient: no grad(P1) or P2 terms")
    if not scene.loads:
        skipped.append("no loads: no traction term")
    if not strain_averages:
        skipped.append("stress law: no strain averages dbar[w], dbar[v]")
    if scene.growth.law == "none":
        skipped.append("growth law 'none': no growth update, a single static solve")
    return skipped


def _check_step(step: int, t: float, report, fields: dict[str, np.ndarray], comm) -> None:
    """Stop with a RunError naming step, time and cause if a solve or field went bad."""
    problems = []
    for name, values in fields.items():
        if not np.all(np.isfinite(values)):
            problems.append(f"{name} has NaN or Inf")
    if report.reason <= 0 or not report.residual <= RESIDUAL_BOUND:
        problems.append(
            f"macro solve failed (PETSc reason {report.reason}, relative residual "
            f"{report.residual:.3g} > {RESIDUAL_BOUND:g})"
        )
    problems = sorted(set(p for part in comm.allgather(problems) for p in part))
    if problems:
        raise RunError(f"step {step}, t = {t:g}: " + "; ".join(problems))


def run_macro(scene: Scene, outdir: Path, comm: MPI.Comm) -> list[dict[str, float]]:
    """Run the coupled macroscopic model of a scene, writing into ``outdir``.

    Returns the summary rows (also written to ``outdir/summary.csv``).
    """
    setup_start = time.perf_counter()
    problem = MacroProblem(scene, comm)
    grid = CoarseGrid.with_edge(scene.tissue.width, scene.tissue.height, scene.tissue.H)
    nodes = grid.nodes
    W = grid.interpolation_matrix(problem.midpoints[:, :2])
    W_owned = W[: problem.n_owned]
    x1_nodes, x1 = nodes[:, 0], problem.midpoints[:, 0]
    cell = scene.cell
    geometry = np.column_stack([f(x1_nodes) for f in (cell.l1, cell.l2, cell.theta, cell.w)])
    E_nodes, nu_nodes = scene.material.E(x1_nodes), scene.material.nu(x1_nodes)
    P1, eta, tau = scene.P1(x1), scene.growth.eta(x1), scene.growth.tau(x1)
    grad_P1 = np.array([scene.P1.gradient, 0.0])
    law = scene.growth.law
    strain_averages = law == "strain" or "eps_hom" in scene.output.fields
    homogenizer = Homogenizer(
        scene.accuracy.cell_resolution, scene.accuracy.key_tolerance,
        problem.K is not None, strain_averages, comm,
    )  # fmt: skip
    log.info(
        "macro: %d fine dofs, %d coarse nodes, terms: %s",
        problem.ndofs, len(nodes), ", ".join(problem.active_terms),
    )  # fmt: skip
    for line in _pruning_report(problem, scene, strain_averages):
        log.info("skipped: %s", line)

    out = _Outputs(problem, scene.output.fields)
    writer = FieldWriter(outdir / "fields.xdmf", problem.mesh, out.functions)
    summary = SummaryWriter(outdir / "summary.csv", SUMMARY_COLUMNS, comm)
    log.info("set-up: %.2f s", time.perf_counter() - setup_start)

    n_cells, n_owned = problem.n_cells, problem.n_owned
    Fg = np.tile(np.array(scene.growth.Fg0, dtype=float), (n_cells, 1, 1))
    n_steps = 0 if law == "none" else scene.time.n_steps
    dt = scene.time.dt
    rows = []
    run_start = time.perf_counter()
    for step in range(n_steps + 1):
        t = step * dt
        t0 = time.perf_counter()
        Fg_nodes = project_to_nodes(W_owned, problem.areas, Fg[:n_owned].reshape(-1, 4), comm)
        nt = homogenizer.homogenize(geometry, E_nodes, nu_nodes, Fg_nodes.reshape(-1, 2, 2))
        n_nodes = len(nodes)
        C = (W @ nt.C.reshape(n_nodes, 9)).reshape(-1, 3, 3)
        phi_w = W @ nt.phi_w
        K = None if nt.K is None else (W @ nt.K.reshape(n_nodes, 4)).reshape(-1, 2, 2)
        problem.set_cell_values(problem.Fg, Fg)
        problem.set_cell_values(problem.C, C)
        problem.set_cell_values(problem.phi_w, phi_w)
        if K is not None:
            problem.set_cell_values(problem.K, K)
        if problem.P2vec is not None:
            problem.set_cell_values(problem.P2vec, W @ (nt.P2_matrix @ grad_P1))
        t1 = time.perf_counter()
        report = problem.solve()
        t2 = time.perf_counter()

        grad_u = problem.grad_u()
        eps_el = growth.elastic_strain(grad_u, Fg)
        sigma = growth.homogenized_stress(C, eps_el, K, P1)
        eps_hom = None
        if strain_averages:
            dbar_w = (W @ nt.dbar_w.reshape(n_nodes, 16)).reshape(-1, 2, 2, 2, 2)
            dbar_v = None if nt.dbar_v is None else (W @ nt.dbar_v.reshape(n_nodes, 4))
            dbar_v = None if dbar_v is None else dbar_v.reshape(-1, 2, 2)
            eps_hom = growth.homogenized_strain(eps_el, phi_w, dbar_w, dbar_v, P1)
        if law == "none":
            G = np.zeros_like(Fg)
        else:
            driving = sigma if law == "stress" else eps_hom
            G = growth.growth_rate(driving, phi_w, eta, tau, scene.growth.clamp)
        _check_step(step, t, report, {"u": problem.u.x.array, "G": G, "Fg": Fg}, comm)
        t3 = time.perf_counter()

        problem.set_cell_values(out.G, G)
        problem.set_cell_values(out.sigma, sigma)
        if eps_hom is not None:
            problem.set_cell_values(out.eps, eps_hom)
        for function, (i, j) in zip(out.E, VOIGT_POSITIONS, strict=True):
            problem.set_cell_values(function, C[:, i, j])
        writer.write(t)
        t4 = time.perf_counter()

        row = _summary_row(problem, Fg, G, comm)
        row.update(step=step, t=t, n_cell_solves=homogenizer.solves_last_call,
                   residual=report.residual, seconds=t4 - t0, seconds_cells=t1 - t0,
                   seconds_solve=t2 - t1, seconds_growth=t3 - t2, seconds_io=t4 - t3)  # fmt: skip
        row = {k: comm.allreduce(v, op=MPI.MAX) if k.startswith("seconds") else v
               for k, v in row.items()}  # fmt: skip
        summary.write(row)
        rows.append(row)
        elapsed = time.perf_counter() - run_start
        left = elapsed / (step + 1) * (n_steps - step)
        log.info(
            "step %d/%d  t = %g  mean growth rate tr G = %.6g  cell solves %d  (%.1f s left)",
            step, n_steps, t, row["growth_rate_area"], row["n_cell_solves"], left,
        )  # fmt: skip
        if step < n_steps:
            Fg = growth.advance(Fg, G, dt, scene.time.integrator)
    return rows


def _summary_row(problem: MacroProblem, Fg: np.ndarray, G: np.ndarray, comm) -> dict:
    """Tissue measures: current area, reference-area means of G11, G22, tr G, max |u_i|."""
    n = problem.n_owned
    areas = problem.areas
    grad_u = problem.grad_u()[:n]
    deformation = np.eye(2) + grad_u
    area = np.sum(areas * np.linalg.det(deformation))
    means = np.array([np.sum(areas * G[:n, 0, 0]), np.sum(areas * G[:n, 1, 1])])
    u = problem.u.x.array.reshape(-1, 2)[: problem.V.dofmap.index_map.size_local]
    u_max = np.abs(u).max(axis=0) if len(u) else np.zeros(2)
    area = comm.allreduce(area, op=MPI.SUM)
    means = comm.allreduce(means, op=MPI.SUM) / problem.total_area
    u_max = [comm.allreduce(float(v), op=MPI.MAX) for v in u_max]
    det_min = comm.allreduce(float(np.linalg.det(Fg[:n]).min()) if n else np.inf, op=MPI.MIN)
    return {
        "area": area,
        "growth_rate_11": means[0],
        "growth_rate_22": means[1],
        "growth_rate_area": means[0] + means[1],
        "u1_max": u_max[0],
        "u2_max": u_max[1],
        "det_Fg_min": det_min,
    }
