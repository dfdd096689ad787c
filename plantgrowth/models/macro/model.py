"""The coupled macroscopic growth loop (paper Algorithm 1, docs/model.md section 5).

Per step: the homogenized E_hom, K_hom, phi_w, dbar, P2vec at every fine cell -> macro solve ->
sigma_hom or eps_hom -> growth rate G -> write the step -> Fg <- integrator(Fg, G, dt).

The tensors of a fine cell: with the surrogate (``accuracy.cell_tolerance > 0``, the default)
from the cell's own Fg and E, in the lattice tables of the cell geometry and nu of the coarse
nodes (spacing H) around it, combined with their P1 weights at its midpoint (one table when
those are constant). On the exact path (``cell_tolerance = 0``, the validation mode) as in the
paper: Fg projected to the coarse nodes, cell problems there (distinct inputs only), the
tensors P1-interpolated to the fine cells.

Fibred walls (``[walls]``, docs/fibres.md): the director angle is a state variable per fine cell
(:mod:`plantgrowth.models.macro.director`), passed to the cell problems with the nodes' E_f / E.

Water fluxes (``hydraulics``, docs/model.md "Water fluxes"): the step solves u and P together
(:mod:`plantgrowth.models.macro.water`; finite kinematics: :mod:`~.water_finite`, by Newton)
over the time step that ended with the previous step (the first step: the equilibrium at
P = Pi + psi_0), and the growth law reads the solved P; the water held is a state variable like
Fg. The adaptive integrator's sub-steps each advance it by their own dt (:meth:`MacroModel.substep`,
a rejected one leaves it: :meth:`MacroModel.keep`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import numpy as np
from dolfinx import fem
from mpi4py import MPI

from plantgrowth.base.blocks import Block, CanonicalBlocks, root_blocks
from plantgrowth.base.errors import RunError
from plantgrowth.base.gather import dof_state, restore_dofs
from plantgrowth.base.tensors import VOIGT_NAMES, VOIGT_POSITIONS, det2
from plantgrowth.meshes.honeycomb import lattice_area
from plantgrowth.models import diagnostics, growth, stability
from plantgrowth.models.elastic_strain import StrainFields, principal_magnitude, strain_peak
from plantgrowth.models.growth_fields import GrowthFields
from plantgrowth.models.linear import SolveReport
from plantgrowth.models.macro.boundary import Boundary
from plantgrowth.models.macro.coarse import CoarseGrid, NodeProjection, coarse_grid_for
from plantgrowth.models.macro.director import MacroDirector
from plantgrowth.models.macro.domain import MacroDomain, macro_domain
from plantgrowth.models.macro.hydraulics import MacroHydraulics, cell_scale, from_scene
from plantgrowth.models.macro.problem import MacroProblem
from plantgrowth.models.macro.resolution import field_sampling
from plantgrowth.models.macro.water import MacroWater
from plantgrowth.models.macro.water_finite import MacroWaterFinite
from plantgrowth.models.macro.water_outputs import MacroWaterOutputs
from plantgrowth.models.regions import RegionStatistics
from plantgrowth.models.step import (
    SideMesh,
    StepResult,
    clamped_fraction,
    max_abs_components,
)
from plantgrowth.scene import Scene
from plantgrowth.unitcell.homogenization import Homogenizer, NodeTensors

log = logging.getLogger("plantgrowth")


class _Outputs:
    """The DG0/P1 functions written to fields.xdmf, only those the scene asks for (E_hom goes to
    the coarse nodes: see :func:`coarse_output`; the growth outputs: :class:`GrowthFields`)."""

    def __init__(self, problem: MacroProblem, fields: tuple[str, ...]) -> None:
        self.fields = fields
        T0 = problem.T0
        self.G = fem.Function(T0, name="G")
        self.sigma = fem.Function(T0, name="sigma_hom")
        self.eps = fem.Function(T0, name="eps_hom")
        self.stability = fem.Function(problem.Q0, name="stability")
        self.growth = GrowthFields(problem.mesh, fields)
        self.strain = StrainFields(problem.mesh, fields)
        chosen = {"u": problem.u, "Fg": problem.Fg, "G": self.G, "sigma_hom": self.sigma,
                  "eps_hom": self.eps, "stability": self.stability,
                  **self.growth.functions, **self.strain.functions}  # fmt: skip
        self.functions = [chosen[name] for name in fields if name in chosen]


def coarse_output(grid: CoarseGrid, fields: tuple[str, ...]) -> SideMesh:
    """The coarse-node fields the scene asks for (E_hom's six components) on the coarse grid:
    a compact view for plots, the lumped L2 average of the fine cells' E_hom (the run itself
    uses each fine cell's own tensors on the surrogate path)."""
    names = VOIGT_NAMES if "E_hom" in fields else ()
    return SideMesh("coarse.xdmf", "CoarseMesh", "coarse", grid.nodes, grid.triangles,
                    {name: ("Node", 1) for name in names})  # fmt: skip


def _pruning_report(problem: MacroProblem, scene: Scene, strain_averages: bool) -> list[str]:
    skipped = []
    if problem.K is None:
        skipped.append("pressure: P1 = 0, no K_hom cell problem and no pressure term")
    if problem.finite and not scene.P1.is_constant:
        skipped.append(
            "finite kinematics: grad(P1) and P2vec cancel (docs/model.md section 10), not assembled"
        )
    elif problem.P2vec is None:
        skipped.append("P1 has no gradient: no grad(P1) or P2 terms")
    if not scene.loads:
        skipped.append("no loads: no traction term")
    if not strain_averages:
        skipped.append("stress law: no strain averages dbar[w], dbar[v]")
    if scene.growth.law == "none":
        skipped.append("growth law 'none': no growth update, a single static solve")
    return skipped


class MacroModel:
    """The coupled macroscopic model: Algorithm 1's inner steps for one time level.

    Args:
        scene: the scene.
        mesh: the fine mesh m (the scene's rectangle, outline or mesh file, or the outline of a
            micro tissue).
        comm: communicator of the fine mesh; it also shares the cell problems.
        boundary: the fine mesh's boundary (default: the scene's rectangle).
        hydraulics: water fluxes (None: turgor is the scene's P1).
        cell_shape: a tissue given as cells: each point's cell shape Fs (n, 2, 2) of points
            (n, 2); the unit cell of a fine cell at growth Fg is then the hexagon grown by
            ``Fg Fs`` (docs/model.md "The macro model from cells"). None: Fs = I.
    """

    def __init__(
        self, scene: Scene, mesh, comm: MPI.Comm, boundary: Boundary | None = None,
        hydraulics: MacroHydraulics | None = None,
        cell_shape: Callable[[np.ndarray], np.ndarray] | None = None,
    ):  # fmt: skip
        self.scene = scene
        self.comm = comm
        self.problem = problem = MacroProblem(scene, mesh, boundary, water=hydraulics is not None)
        self.water = None
        if hydraulics is not None:
            self.water = (MacroWaterFinite if problem.finite else MacroWater)(problem, hydraulics)
        self.water_out = None  # the water's fields and summary row: a scene's [hydraulics]
        if self.water is not None and scene.hydraulics is not None:
            self.water_out = MacroWaterOutputs(
                self.water, scene.hydraulics, scene.regions, scene.output.fields
            )
        self._water_dt: float | None = None  # the step the next solve advances the water by
        self._time = 0.0  # the time the step of the next solve ends at (the supplies' potentials)
        self._remaining = 0.0  # the next solve ends this long before _time (a sub-step)
        self.mesh = problem.mesh
        self.shape = None if cell_shape is None else cell_shape(problem.midpoints[:, :2])
        width, height = problem.bounding_box
        # the coarse nodes the fine cells see (the others weigh no fine cell)
        self.grid, self.W, self.active = coarse_grid_for(
            width, height, scene.tissue.H, problem.midpoints[:, :2], comm
        )
        # Algorithm 1's projection of the owned fine cells' values onto the coarse nodes
        self.to_nodes = NodeProjection(self.W[: problem.n_owned], problem.areas, comm)
        self.per_cell = scene.accuracy.cell_tolerance > 0.0
        nodes = self.grid.nodes[self.active]
        self._W_active = self.W[:, self.active]
        at_nodes, at_cells = (nodes[:, 0], nodes[:, 1]), problem.midpoints[:, :2].T
        self.geometry = np.column_stack([f(*at_nodes) for f in scene.cell.fields()])
        self.nu_nodes = scene.material.nu(*at_nodes)
        self.E = scene.material.E(*(at_cells if self.per_cell else at_nodes))
        self.P1 = scene.P1(*at_cells)
        self.cell_area = lattice_area(*(f(*at_cells) for f in scene.cell.fields()[:3]))
        self.eta, self.tau = scene.growth.eta(*at_cells), scene.growth.tau(*at_cells)
        # (n_cells, 2): docs/model.md section 6, P2 = -grad P1 . y
        self.grad_P1 = scene.P1.gradient(*at_cells)
        strain_cue = scene.feedback is not None and scene.feedback.cue == "strain"
        self.strain_averages = (  # water: 1/M = -tr dbar[v]
            scene.growth.law == "strain" or "eps_hom" in scene.output.fields or strain_cue
            or self.water is not None
        )  # fmt: skip
        self.homogenizer = Homogenizer(
            scene.accuracy.cell_resolution, scene.accuracy.key_tolerance,
            problem.K is not None or self.water is not None, self.strain_averages, comm,
            scene.accuracy.cell_tolerance, water=self.water is not None,
            interpolant=scene.accuracy.cell_interpolant,
        )  # fmt: skip
        self.cells = None  # each fine cell's unit cell: kappa (water only)
        if self.water is not None:
            self.cells = [scene.cell.at(*p) for p in problem.midpoints[:, :2]]
        self.out = _Outputs(problem, scene.output.fields)
        self.director = None  # fibred walls: the director per fine cell, E_f / E per node
        if scene.has_director:
            self.director = MacroDirector(
                scene.walls, scene.feedback, problem.mesh, problem.midpoints[:, :2], nodes,
                scene.output.fields,
            )  # fmt: skip
        self._cue = None  # the last step's cue tensor per fine cell (feedback only)
        self._fibre_row: dict[str, float] = {}  # the last step's fibre_order, fibre_angle_mean
        self.outputs = self.out.functions + (
            [] if self.director is None else self.director.functions
        ) + ([] if self.water_out is None else self.water_out.functions)  # fmt: skip
        self.side_output = coarse_output(self.grid, scene.output.fields)
        self.cell_table = None  # per-cell rows (cells.csv): micro only
        self.output_space = problem.V
        self._blocks = CanonicalBlocks(problem.V)  # the state's midpoints moved once, below
        self._midpoints = self._blocks.cells(problem.midpoints[: problem.n_owned, :2])
        self._factors_saved: tuple[int, dict[str, Block]] = (0, {})  # see _factor_blocks
        log.info(
            "macro: %d fine dofs, %d coarse nodes (%d in the tissue), terms: %s",
            problem.ndofs, len(self.grid.nodes), len(nodes), ", ".join(problem.active_terms),
        )  # fmt: skip
        for line in _pruning_report(problem, scene, self.strain_averages):
            log.info("skipped: %s", line)
        msh, n = problem.mesh, problem.n_owned
        vertices = msh.geometry.x[msh.geometry.dofmap.array.reshape(-1, 3)[:n], :2]
        self.regions = RegionStatistics(scene.regions, problem.midpoints[:n, :2], problem.areas,
                                        comm)  # fmt: skip
        self.strain_magnitudes, self.jacobians = np.zeros(n), np.ones(n)  # the last step's
        self.sampling = field_sampling(
            scene, vertices, problem.areas, self._W_active[:n], nodes, self.per_cell, comm
        )
        for sampling in self.sampling:
            if sampling.warning:
                log.warning("warning: %s", sampling.warning)

    def initial_growth(self) -> np.ndarray:
        return self.scene.growth.initial(*self.problem.midpoints[:, :2].T)

    def check_growth(self, Fg: np.ndarray) -> None:
        points = self.problem.midpoints[:, :2]
        diagnostics.stop_if(diagnostics.growth_problems(Fg, points), self.comm)

    def state(self, Fg: np.ndarray, G: np.ndarray) -> dict[str, Block]:
        """Fg and G (and the fibre director) of the fine cells with their midpoints, this rank's
        block of them in the written mesh's cell order (finite kinematics: Newton's guess, which
        rank 0 writes)."""
        n = self.problem.n_owned
        parts = {"Fg": Fg[:n].reshape(n, 4), "G": G[:n].reshape(n, 4)}
        if self.director is not None:
            parts["fibre_angle"] = self.director.angle[:n].reshape(n, 1)
        if self.water is not None:  # after end_step: the time the next step reaches
            parts |= self.water.state() | {"water_time": np.full((n, 1), self._time)}
        blocks = {key: self._blocks.cells(p) for key, p in parts.items()}
        newton = dof_state(self.problem.newton.guess_functions) if self.problem.finite else {}
        whole = newton | self.homogenizer.state()  # the surrogate: the same on every rank
        whole = root_blocks(whole if self.comm.rank == 0 else {}, self.comm)
        return {"midpoints": self._midpoints} | blocks | whole | self._factor_blocks()

    def _factor_blocks(self) -> dict[str, Block]:
        """Collective: the kept LU factors' coefficients (``lu_Fg``, ``lu_C``) and floor as state
        blocks, made once per factorization (the canonical blocks' exchange, not every step)."""
        factors = self.problem.factors
        if factors is None or factors.floor is None:
            return {}
        if self._factors_saved[0] != factors.factorizations:
            kept, n = self.problem.factorized_cells(), self.problem.n_owned
            cells = {key: self._blocks.cells(v[:n]) for key, v in kept[0].items()}
            floor = {"lu_floor": np.array([kept[1]])} if self.comm.rank == 0 else {}
            blocks = cells | root_blocks(floor, self.comm)
            self._factors_saved = (factors.factorizations, blocks)
        return self._factors_saved[1]

    def restore(self, state: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """This rank's (Fg, G) per fine cell, matched to the saved cells by midpoint (and the
        fibre director, which the model keeps)."""
        from scipy.spatial import cKDTree  # here: a run that does not resume never loads it

        distance, index = cKDTree(state["midpoints"]).query(self.problem.midpoints[:, :2])
        tolerance = 1e-9 * max(self.problem.bounding_box)
        matches = np.max(distance, initial=0.0) <= tolerance
        if self.problem.finite:  # the resumed Newton starts from the straight run's guess
            matches = (
                restore_dofs(self.problem.newton.guess_functions, state, tolerance) and matches
            )
        if self.director is not None:
            matches = matches and "fibre_angle" in state
        if not matches:
            raise RunError("the saved state does not match this mesh: was the scene changed?")
        if self.director is not None:
            self.director.angle = state["fibre_angle"][index].reshape(-1)
        if self.water is not None:  # the saved step ended with end_step(dt)
            self.water.restore(state)
            if self.water_out is not None:
                self.water_out.restored()
            self._water_dt = self.scene.time.dt
            self._time = float(state["water_time"].reshape(-1)[0])
        self.homogenizer.restore(state)
        self.problem.restore_factors(state, index)  # the straight run's kept LU factors
        return state["Fg"][index].reshape(-1, 2, 2), state["G"][index].reshape(-1, 2, 2)

    def end_step(self, dt: float) -> None:
        """The fibre director's feedback over dt from the step just solved (its cue at the
        step's start, docs/fibres.md); with water, dt is also the step the next solve advances
        the water by; the surrogate's step count (its blends) advances."""
        self._water_dt, self._remaining = dt, 0.0
        self.homogenizer.end_step()
        self._time += dt
        if self.water_out is not None:
            self.water_out.ledger.close()
        if self._cue is not None:
            self.director.turn(self._cue, dt)

    def substep(self, dt: float, remaining: float) -> None:
        """The next solve advances the water (if any) by dt, ``remaining`` before the step's
        end, from the water kept last (the adaptive integrator's sub-steps)."""
        if self.water is not None:
            self._water_dt, self._remaining = dt, remaining
            self.water.mark()

    def keep(self, kept: bool) -> None:
        """Keep the last solve's water (a kept sub-step), or go back to the water before it (a
        rejected one)."""
        if self.water is None:
            return
        if not kept:
            self.water.revert()
        elif self.water_out is not None:
            self.water_out.ledger.keep()

    def cell_tensors(self, Fg: np.ndarray) -> NodeTensors:
        """The homogenized tensors of every fine cell of this rank (ghosts too) at the cells'
        growth tensors Fg (n_cells, 2, 2) (a tissue given as cells: at ``Fg Fs``)."""
        director = self.director
        if self.shape is not None:
            Fg = Fg @ self.shape
        if self.per_cell:
            points = self.problem.midpoints[:, :2]
            fibres = None if director is None else (director.stiffness, director.angle)
            tensors = self.homogenizer.homogenize(
                self.geometry, self.E, self.nu_nodes, Fg, self._W_active, fibres
            )
        else:
            n_owned, problem = self.problem.n_owned, self.problem
            W_owned = self.W[:n_owned]
            Fg_nodes = self.to_nodes(Fg[:n_owned].reshape(-1, 4))[self.active]
            points = self.grid.nodes[self.active]
            fibres = None if director is None else (
                director.stiffness,
                director.angles_at_nodes(W_owned, problem.areas, self.active, self.comm),
            )  # fmt: skip
            tensors = self.homogenizer.homogenize(
                self.geometry, self.E, self.nu_nodes, Fg_nodes.reshape(-1, 2, 2), fibres=fibres
            )
        diagnostics.stop_if(diagnostics.stiffness_problems(tensors.C, points), self.comm)
        return tensors if self.per_cell else self._to_cells(tensors)

    def _to_cells(self, tensors: NodeTensors) -> NodeTensors:
        """P1 interpolation of active-node tensors to the fine cells' midpoints."""
        parts = {}
        for name in ("C", "phi_w", "K", "dbar_w", "dbar_v", "P2_matrix"):
            v = getattr(tensors, name)
            parts[name] = None if v is None else (
                self._W_active @ v.reshape(len(v), -1)
            ).reshape(-1, *v.shape[1:])  # fmt: skip
        return NodeTensors(**parts)

    def _fill_coarse_E_hom(self, C: np.ndarray) -> None:
        """E_hom's components at the coarse nodes: the lumped L2 average of the owned fine
        cells' values (:class:`NodeProjection`; a node outside the tissue gets the mean)."""
        n = self.problem.n_owned
        values = C[:n][:, [i for i, _ in VOIGT_POSITIONS], [j for _, j in VOIGT_POSITIONS]]
        nodes = self.to_nodes(values)
        for k, name in enumerate(VOIGT_NAMES):
            self.side_output.values[name] = nodes[:, k]

    def step(self, Fg: np.ndarray) -> StepResult:
        problem, law = self.problem, self.scene.growth.law
        t0 = time.perf_counter()
        nt = self.cell_tensors(Fg)
        C, phi_w, K = nt.C, nt.phi_w, nt.K
        problem.set_cell_values(problem.Fg, Fg)
        problem.set_cell_values(problem.C, C)
        problem.set_cell_values(problem.phi_w, phi_w)
        if K is not None:
            problem.set_cell_values(problem.K, K)
        if problem.P2vec is not None:
            P2vec = np.einsum("nij,nj->ni", nt.P2_matrix, self.grad_P1)
            problem.set_cell_values(problem.P2vec, P2vec)
        t1 = time.perf_counter()
        report, P = self._solve(Fg, nt)
        t2 = time.perf_counter()
        diagnostics.check_solution(report, problem.u, self.comm)
        grad_u = problem.grad_u()
        strain = growth.green_lagrange_strain if problem.finite else growth.elastic_strain
        eps_el = strain(grad_u, Fg)  # finite kinematics: Ee (docs/model.md section 10)
        sigma = growth.homogenized_stress(C, eps_el, K, P)
        eps_hom = None
        if self.strain_averages:
            eps_hom = growth.homogenized_strain(eps_el, phi_w, nt.dbar_w, nt.dbar_v, P)
        if law == "none":
            G = np.zeros_like(Fg)
        else:
            driving = sigma if law == "stress" else eps_hom
            G = growth.growth_rate(driving, phi_w, self.eta, self.tau, self.scene.growth.clamp)
        midpoints = problem.midpoints[:, :2]
        self.jacobians = det2(np.eye(2) + grad_u)  # det(I + grad u): for measures' area too
        diagnostics.stop_if(
            diagnostics.growth_problems(Fg, midpoints, G)
            + diagnostics.inversion_problems(self.jacobians, midpoints),
            self.comm,
        )
        walls = None if problem.finite else (stability.stretch_of_strain(eps_el), sigma, C)
        ellipticity = self._ellipticity(grad_u, Fg, walls)
        problem.set_cell_values(self.out.G, G)
        if "stability" in self.out.fields:
            exact = problem.stability_values(grad_u, screened=False)
            problem.set_cell_values(self.out.stability, exact)
        problem.set_cell_values(self.out.sigma, sigma)
        if eps_hom is not None:
            problem.set_cell_values(self.out.eps, eps_hom)
        self.out.growth.fill(G, sigma, problem.set_cell_values)
        self.out.strain.fill(eps_el, problem.set_cell_values)
        if self.director is not None:
            if self.scene.feedback is not None:
                self._cue = sigma if self.scene.feedback.cue == "stress" else eps_hom
            self.director.fill(problem.set_cell_values, self._cue)
            self._fibre_row = self.director.measures(problem.areas, self.comm)
        if self.side_output.fields:
            self._fill_coarse_E_hom(C)
        t3 = time.perf_counter()
        n, M = problem.n_owned, self.scene.growth.clamp
        newton = problem.newton_report if problem.finite else None
        self.strain_magnitudes = principal_magnitude(eps_el[:n])  # for measures' regions
        return StepResult(
            G, report.reason, report.residual, self.homogenizer.solves_last_call,
            {"seconds_cells": t1 - t0, "seconds_solve": t2 - t1, "seconds_growth": t3 - t2},
            strain_peak(self.strain_magnitudes, midpoints[:n], self.comm),
            clamped_fraction(G[:n], M, problem.areas, self.comm),
            *((newton.iterations, newton.residual) if newton else (0, 0.0)),
            problem.loads.balance() if self.scene.loads and self.scene.pinned else None,
            ellipticity, problem.held.force() if self.scene.supports else None,
        )  # fmt: skip

    def _solve(self, Fg: np.ndarray, nt: NodeTensors) -> tuple[SolveReport, np.ndarray]:
        """The step's solve and the turgor per fine cell: the scene's P1, or with water P
        solved with u (the first step: the equilibrium at P = Pi + psi_0)."""
        if self.water is None:
            return self.problem.solve(), self.P1
        self.problem.loads.update_forces()
        self.water.set_coefficients(Fg, nt, self.cells, self.shape)
        if self._water_dt is None:
            report = self.water.start()
        else:
            report = self.water.step(self._water_dt, self._time - self._remaining)
        if self.water_out is not None:
            self.water_out.update(self._water_dt, self._time - self._remaining)
        return report, self.problem.P1_cells  # set by the water solve

    def _ellipticity(
        self, grad_u: np.ndarray, Fg: np.ndarray, walls: tuple[np.ndarray, ...] | None
    ) -> stability.Ellipticity:
        """Collective: the step's stability check with the resolution rule: the owned fine
        cells' values with the walls' stress, connected by their vertices, each set against the
        grown area of a cell there, ``Jg |Y|`` (docs/model.md section 10). ``walls``: the
        step's (Fe, S_w, C) if it has them (linear kinematics: the stretch of eps_el,
        sigma_hom, E_hom), else :meth:`MacroProblem.walls_state`."""
        problem, n = self.problem, self.problem.n_owned
        Fe, S, C = problem.walls_state(grad_u) if walls is None else walls
        values = stability.normalised(Fe[:n], S[:n], C[:n], screened=True)
        Jg = det2(Fg[:n])
        return stability.check(
            values, problem.areas, problem.midpoints[:n, :2], self.comm, S[:n],
            problem.cell_vertices, Jg * problem.areas, Jg * self.cell_area[:n],
        )  # fmt: skip

    def measures(self, Fg: np.ndarray, G: np.ndarray) -> dict[str, float]:
        """Current area ``int det(I + grad u)``, reference-area means of G11, G22, tr G,
        max |u_i|, min det Fg, the regions' statistics (plantgrowth/models/regions.py) and, with
        a fibre director, fibre_order and fibre_angle_mean of the director the step used."""
        problem, comm = self.problem, self.comm
        n = problem.n_owned
        areas = problem.areas
        current = areas * self.jacobians[:n]  # the step's u
        area = np.sum(current)
        means = np.array([np.sum(areas * G[:n, 0, 0]), np.sum(areas * G[:n, 1, 1])])
        means = comm.allreduce(means, op=MPI.SUM) / problem.total_area
        u1_max, u2_max = max_abs_components(problem.u, comm)
        det_min = float(det2(Fg[:n]).min()) if n else np.inf
        turgor = None if self.water_out is None else problem.P1_cells[:n]  # the solved P
        return {
            "area": comm.allreduce(area, op=MPI.SUM),
            "growth_rate_11": means[0],
            "growth_rate_22": means[1],
            "growth_rate_area": means[0] + means[1],
            "u1_max": u1_max,
            "u2_max": u2_max,
            "det_Fg_min": comm.allreduce(det_min, op=MPI.MIN),
            **self.regions.measures(current, G[:n], self.strain_magnitudes, turgor),
            **self._fibre_row,
            **({} if self.water_out is None else self.water_out.row),
        }


def macro_model(scene: Scene, comm: MPI.Comm, nx: int | None = None) -> MacroModel:
    """The MacroModel on :func:`plantgrowth.models.macro.domain.macro_domain`."""
    return model_on(macro_domain(scene, comm, nx), comm)


def model_on(domain: MacroDomain, comm: MPI.Comm) -> MacroModel:
    """The MacroModel of a domain (its scene, mesh, boundary and cell shapes; the scene's
    ``[hydraulics]`` with the cells of its micro tissue, :func:`cell_scale`, or those given,
    at their mean size)."""
    scene, shape = domain.scene, domain.cell_shape
    water = None
    if scene.hydraulics is not None:
        scale = cell_scale(scene.micro_nx) if shape is None else shape.shapes.delta
        water = from_scene(scene.hydraulics, scene.regions, scale)
    return MacroModel(scene, domain.mesh, comm, domain.boundary, water, shape)
