"""The cell-resolved microscopic model (docs/model.md section 7, paper [var_inequal],
[growth_micro_1]).

P2 displacement on the walls of all cells; Fg, E, nu and the turgor pressure are constant per
cell (pressure P1 at the cell's centre). Growth is driven by the stress or elastic strain
averaged over each cell's own walls, with the macro model's law, clamp and integrators:
``G~ = eta [ mean_cell(X) - tau I ]_+`` (no 1/phi_w: the mean is over walls already).
"""

from __future__ import annotations

import logging
import time
from functools import cached_property

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from plantgrowth.base.blocks import Block, root_blocks
from plantgrowth.base.errors import RunError
from plantgrowth.base.gather import dof_state, restore_dofs
from plantgrowth.base.mesh_samples import MeshSamples, det_degree
from plantgrowth.forms import cell_measures
from plantgrowth.forms import finite as finite_forms
from plantgrowth.forms import micro as micro_forms
from plantgrowth.forms.elasticity import wall_bilinear_form
from plantgrowth.meshes.cell_tissue import CellTissue
from plantgrowth.meshes.honeycomb import HoneycombCell, polygon_area
from plantgrowth.meshes.tissue import FACET_TAGS, build_walls_mesh
from plantgrowth.models import diagnostics, fibres, growth
from plantgrowth.models.elastic_strain import StrainFields, principal_magnitude, strain_peak
from plantgrowth.models.growth_fields import GrowthFields
from plantgrowth.models.linear import SolveReport, assemble_and_solve, assemble_system, lu_solver
from plantgrowth.models.micro.around import WallsAround
from plantgrowth.models.micro.director import MicroDirector
from plantgrowth.models.micro.hydraulic import turgor_solve, water_measures
from plantgrowth.models.micro.outlines import CellOutlines
from plantgrowth.models.micro.supports import supports
from plantgrowth.models.micro.turgor_solve import ElasticParts
from plantgrowth.models.micro.wall_stability import WallStability
from plantgrowth.models.newton import NEWTON_ATOL, NewtonSolver, log_report
from plantgrowth.models.refinement import ExtendedRefinement
from plantgrowth.models.regions import RegionStatistics
from plantgrowth.models.step import StepResult, clamped_fraction, max_abs_components
from plantgrowth.models.turgor_ramp import solve_ramped
from plantgrowth.scene import Scene
from plantgrowth.scene.micro_tissue import micro_tissue

log = logging.getLogger("plantgrowth")


def scene_cell(scene: Scene) -> HoneycombCell:
    """The (constant) unit cell of a micro scene."""
    return scene.cell.at(0.0, 0.0)


class MicroModel:
    """The walls problem of a tissue of cells and its per-cell growth.

    Args:
        scene: the scene (cell geometry, material and growth fields, pressure).
        comm: communicator the walls mesh is distributed on.
        nx: cells per row of a honeycomb instead of the scene's tissue (a command's ``--nx``).
        resolution: P2 elements across one cell's wall (default: ``micro.resolution``).
        tissue: the cells (default: the scene's, :func:`plantgrowth.scene.micro_tissue`).
    """

    def __init__(
        self, scene: Scene, comm: MPI.Comm, nx: int | None = None,
        resolution: int | None = None, tissue: CellTissue | None = None,
    ) -> None:  # fmt: skip
        tissue = micro_tissue(scene, nx) if tissue is None else tissue
        self.layout = tissue.honeycomb  # the honeycomb the cells are, if they are one
        self.tissue = tissue
        self.scene = scene = scene.over_extent(*tissue.bounding_box)  # fields span this tissue
        self.comm = comm
        msh, cell_tags, facet_tags = build_walls_mesh(
            tissue, scene.micro_resolution if resolution is None else resolution, comm
        )
        self.mesh = msh
        self.V = fem.VectorFunctionSpace(msh, ("Lagrange", 2))
        Q0 = fem.FunctionSpace(msh, ("DG", 0))
        T0 = fem.TensorFunctionSpace(msh, ("DG", 0))
        n_owned = msh.topology.index_map(2).size_local
        self.n_owned = n_owned
        self.cell_id = np.full(n_owned, -1, dtype=np.int64)
        owned = cell_tags.indices < n_owned
        self.cell_id[cell_tags.indices[owned]] = cell_tags.values[owned] - 1

        centres = tissue.centres[:, 0], tissue.centres[:, 1]  # P1 etc. at the cell centres
        self.eta, self.tau = scene.growth.eta(*centres), scene.growth.tau(*centres)
        self.pressure = scene.P1(*centres)
        self.u = fem.Function(self.V, name="u")
        self.Fg = fem.Function(T0, name="Fg")
        E, nu, P = (fem.Function(Q0) for _ in range(3))
        self._P = P  # the turgor per wall triangle (ramped by turgor_ramp.solve_ramped)
        E_cells = np.broadcast_to(scene.material.E(*centres), tissue.n_cells)
        self._set(E, E_cells)
        self._set(nu, scene.material.nu(*centres))
        self._set(P, self.pressure)
        self.director = None  # fibred walls: the director per cell (docs/fibres.md)
        wall_fibres = None
        if scene.has_director:
            self.director = MicroDirector(
                scene.walls, scene.feedback, tissue, msh, self.cell_id, E_cells, self._set
            )
            wall_fibres = self.director.fibres
        self._fibres = wall_fibres

        dx = ufl.dx(domain=msh)
        ds = ufl.Measure("ds", domain=msh, subdomain_data=facet_tags)
        n = ufl.FacetNormal(msh)
        psi, tau_test = ufl.TestFunction(self.V), ufl.TestFunction(T0)
        membrane = ds(FACET_TAGS["membrane"])
        self.bcs = supports(self.V, facet_tags, tissue)
        self.finite = scene.kinematics == "finite"
        self.stability = WallStability(self.u, self.Fg, E, nu, self.finite, wall_fibres)
        self.forms = finite_forms if self.finite else micro_forms  # the growth-driving averages
        rhs = micro_forms.micro_growth_rhs(psi, self.Fg, E, nu, dx, wall_fibres)
        hydraulic = scene.hydraulics is not None  # turgor solved per cell (water.py), not given
        turgid = hydraulic or np.any(self.pressure != 0.0)
        if turgid and not (hydraulic and not self.finite):  # linear water: its own loads
            rhs += micro_forms.membrane_pressure_rhs(psi, self.Fg, P, n, membrane)
        self.a = fem.form(
            wall_bilinear_form(ufl.TrialFunction(self.V), psi, self.Fg, E, nu, dx, wall_fibres)
        )
        self.L = fem.form(rhs)
        self.A = fem.petsc.create_matrix(self.a)
        self.b = fem.petsc.create_vector(self.L)
        self.ksp = lu_solver(self.A, comm, "plantgrowth_micro_")
        self._refinement = ExtendedRefinement()  # of a linear-kinematics step's solve
        if self.finite:  # the linear solve above is Newton's predictor
            residual = finite_forms.micro_residual(self.u, psi, self.Fg, E, nu, dx, wall_fibres)
            load = None
            if turgid:
                load = finite_forms.follower_pressure(self.u, psi, P, n, membrane)
                residual += load
            self.newton = NewtonSolver(
                residual, self.u, self.bcs, lambda A: lu_solver(A, comm, "plantgrowth_micro_"),
                load, self._newton_floor, self.stability.smallest, predictor=self._linear_solve,
            )  # fmt: skip
        self.hexagon_area = np.array(
            [polygon_area(tissue.polygon(i)) for i in range(tissue.n_cells)]
        )
        self.turgor = None
        if hydraulic:
            parts = ElasticParts(self._assemble, self.A, self.b, self.ksp, self.u, self.Fg,
                                 self.bcs, self._set, comm)  # fmt: skip
            self.turgor = turgor_solve(scene, tissue, self.hexagon_area, parts, psi, n, membrane,
                                       (self.newton, P) if self.finite else None)  # fmt: skip
        driving = (
            self.forms.wall_stress_average_form(self.u, tau_test, self.Fg, E, nu, dx, wall_fibres)
            if scene.growth.law == "stress"
            else self.forms.elastic_strain_average_form(self.u, tau_test, self.Fg, dx)
        )
        self.driving = fem.form(driving)
        self.enclosed_area = fem.form(
            micro_forms.enclosed_area_form(self.u, n, ds(FACET_TAGS["outer"]))
        )
        areas = fem.petsc.assemble_vector(fem.form(ufl.TestFunction(Q0) * dx))
        self.wall_area = self._per_cell(areas.array.reshape(-1, 1), Q0)[:, 0]
        self._around = None  # the feedback's cue over the walls around each cell
        if self.director is not None and self.director.feedback is not None:
            if self.director.feedback.walls == "around":
                self._around = WallsAround(
                    tissue, self.cell_id, self.director.side,
                    self._owned_rows(areas.array.reshape(-1, 1), Q0)[:, 0], comm,
                )  # fmt: skip

        self._vector_dg0 = fem.VectorFunctionSpace(msh, ("DG", 0))
        self.G_out = fem.Function(T0, name="G")
        ids = fem.Function(Q0, name="cell_id")
        self._set(ids, np.arange(tissue.n_cells, dtype=float))
        self.u_out = fem.Function(fem.VectorFunctionSpace(msh, ("Lagrange", 1)), name="u")
        self.growth_fields = GrowthFields(msh, scene.output.fields)
        self.strain_fields = StrainFields(msh, scene.output.fields)
        growth_outputs = list(self.growth_fields.functions.values())
        strain_outputs = list(self.strain_fields.functions.values())
        self.outputs = [self.u_out, self.Fg, self.G_out, ids, *growth_outputs, *strain_outputs]
        self.cue_out = None  # the feedback cue's anisotropy, when asked for
        if scene.feedback is not None and fibres.CUE_FIELD in scene.output.fields:
            self.cue_out = fem.Function(Q0, name=fibres.CUE_FIELD)
            self.outputs.append(self.cue_out)
        self.stability_out = None
        if "stability" in scene.output.fields:
            self.stability_out = fem.Function(Q0, name="stability")
            self.outputs.append(self.stability_out)
        self.outlines = CellOutlines(tissue, self.u)
        membrane = ds(FACET_TAGS["membrane"])
        self._measure_forms = [
            (fem.form(form(self.u, ufl.TestFunction(space), n, dx, membrane)), space)
            for form, space in ((cell_measures.deformed_area_form, Q0),
                                (cell_measures.deformed_moment_form, self._vector_dg0))
        ]  # fmt: skip
        self.regions = RegionStatistics(
            scene.regions, tissue.centres, self.hexagon_area, MPI.COMM_SELF
        )  # every rank holds every cell
        self.strain_magnitudes = np.zeros(len(tissue.centres))  # the last step's, per cell
        self.side_output = self.outlines.side  # the cells' outlines (cells.xdmf)
        self.cell_table = self.outlines  # cells.csv
        self.outlines.fibred = self.director is not None
        self.outlines.watered = self.turgor is not None
        self._E, self._nu = E, nu
        self._deformation_det = MeshSamples(
            ufl.det(ufl.Identity(2) + ufl.grad(self.u)), msh, det_degree(self.u)
        )
        self.output_space = self.u_out.function_space
        self.ndofs = self.V.dofmap.index_map.size_global * self.V.dofmap.index_map_bs
        turgid = "on" if np.any(self.pressure) else "off"
        log.info("micro: %s, %d dofs (P2), pressure %s", tissue.name, self.ndofs, turgid)

    def _newton_floor(self) -> float:
        """Newton's absolute floor: NEWTON_ATOL times the stiffest wall's E times the square
        root of the walls' area."""
        stiffest = float(np.max(self.scene.material.E(*self.tissue.centres.T)))
        return NEWTON_ATOL * stiffest * np.sqrt(self.wall_area.sum())

    def _set(self, function: fem.Function, per_cell: np.ndarray) -> None:
        """DG0 function from values per biological cell (any trailing shape)."""
        dofmap = function.function_space.dofmap
        array = function.x.array.reshape(-1, dofmap.index_map_bs)
        values = np.asarray(per_cell, dtype=float).reshape(self.tissue.n_cells, -1)
        array[dofmap.list.array[: self.n_owned]] = values[self.cell_id]
        function.x.scatter_forward()

    def _owned_rows(self, integrals: np.ndarray, space: fem.FunctionSpace) -> np.ndarray:
        """(n_owned, bs) this rank's per-mesh-cell integrals, (n, bs) at a DG0 space's dofs, in
        the order of the owned mesh cells."""
        return integrals[space.dofmap.list.array[: self.n_owned]]

    def _per_cell(self, integrals: np.ndarray, space: fem.FunctionSpace) -> np.ndarray:
        """Sum per-mesh-cell integrals (owned dofs of a DG0 space) per biological cell."""
        return self._sum_rows(self._owned_rows(integrals, space))

    def _sum_rows(self, rows: np.ndarray) -> np.ndarray:
        """Collective: (n_cells, bs) per-owned-mesh-cell rows summed per biological cell."""
        n = self.tissue.n_cells
        sums = np.stack([np.bincount(self.cell_id, r, n) for r in rows.T], axis=1)
        return self.comm.allreduce(sums, op=MPI.SUM)

    def cell_means(self, u: fem.Function) -> np.ndarray:
        """(n_cells, 2) mean of a vector field over each biological cell's own walls."""
        V0 = self._vector_dg0
        integrals = fem.petsc.assemble_vector(
            fem.form(ufl.inner(u, ufl.TestFunction(V0)) * ufl.dx(domain=self.mesh))
        )
        return self._per_cell(integrals.array.reshape(-1, 2), V0) / self.wall_area[:, None]

    def initial_growth(self) -> np.ndarray:
        return self.scene.growth.initial(*self.tissue.centres.T)

    def step(self, Fg: np.ndarray) -> StepResult:
        t0 = time.perf_counter()
        self._set(self.Fg, Fg)
        newton = None
        if self.finite:
            newton = (
                solve_ramped(self.newton, lambda f: self._set(self._P, f * self.pressure))
                if self.turgor is None else self.turgor.solve(Fg)
            )  # fmt: skip
            log_report("micro", newton)
            report = SolveReport(newton.reason, newton.linear_residual)
        elif self.turgor is not None:
            report = self.turgor.solve(Fg)
        else:  # refined once: plantgrowth/models/refinement.py
            report = self._refinement.refine(self._linear_solve(), self.ksp, self.A, self.b, self.u)
        t1 = time.perf_counter()
        diagnostics.check_solution(report, self.u, self.comm)
        driving = self._tensor_rows(self.driving)
        means = self._own_means(driving)
        ones = np.ones(self.tissue.n_cells)
        if self.scene.growth.law == "none":
            G = np.zeros_like(Fg)
        else:
            G = growth.growth_rate(
                means.reshape(-1, 2, 2), ones, self.eta, self.tau, self.scene.growth.clamp
            )
        det = self._deformation_det
        diagnostics.stop_if(
            diagnostics.growth_problems(Fg, self.tissue.centres, G)
            + diagnostics.inversion_problems(*det.cell_minima()),
            self.comm,
        )
        self.last_G = G
        self._set(self.G_out, G)
        self.outlines.update(G, *self._cell_geometry())
        if self.turgor is not None:
            self.outlines.water = self.turgor.last
        if self.director is not None:
            self.outlines.fibre_angle = self.director.angle  # the director this step used
            if self.director.feedback is not None:
                self._cue = self._cue_means(driving)
                if self.cue_out is not None:
                    self._set(self.cue_out, fibres.cue(self._cue).anisotropy)
        if self.growth_fields.functions:
            stress = None
            if self.growth_fields.needs_stress:
                law = self.scene.growth.law
                stress = (means if law == "stress" else self._stress_means()).reshape(-1, 2, 2)
            self.growth_fields.fill(G, stress, self._set)
        strains = self._cell_mean_strains()
        self.strain_magnitudes = principal_magnitude(strains)  # for measures' regions
        self.strain_fields.fill(strains, self._set)
        ellipticity = self.stability.check()
        if self.stability_out is not None:
            out = self.stability_out
            out.x.array[out.function_space.dofmap.list.array[: self.n_owned]] = (
                self.stability.cell_minima()
            )
            out.x.scatter_forward()
        self.u_out.interpolate(self.u)
        t2 = time.perf_counter()
        return StepResult(
            G, report.reason, report.residual, 0,
            {"seconds_cells": 0.0, "seconds_solve": t1 - t0, "seconds_growth": t2 - t1},
            strain_peak(self.strain_magnitudes, self.outlines.centroid_ref, MPI.COMM_SELF),
            clamped_fraction(
                G, self.scene.growth.clamp, self.hexagon_area, MPI.COMM_SELF
            ),  # per-cell values are the same on every rank
            *((newton.iterations, newton.residual) if newton else (0, 0.0)),
            ellipticity=ellipticity,
        )  # fmt: skip

    def _cell_geometry(self) -> tuple[np.ndarray, np.ndarray]:
        """Deformed area (n_cells,) and centroid (n_cells, 2) of each cell's walls and void
        (forms/cell_measures.py)."""
        sums = []
        for form, space in self._measure_forms:
            vector = fem.petsc.assemble_vector(form)
            # membrane facets next to a ghost cell: their share goes to the owner
            vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
            bs = space.dofmap.index_map_bs
            sums.append(self._per_cell(vector.array.reshape(-1, bs), space))
        area = sums[0][:, 0]
        return area, sums[1] / area[:, None]

    def _cell_means(self, form: fem.Form) -> np.ndarray:
        """(n_cells, 4) means of a tensor over each cell's own walls, ``form`` giving the
        per-mesh-cell integrals (:meth:`_own_means`)."""
        return self._own_means(self._tensor_rows(form))

    def _tensor_rows(self, form: fem.Form) -> np.ndarray:
        """(n_owned, 4) this rank's per-mesh-cell integrals of a tensor, ``form`` giving them."""
        integrals = fem.petsc.assemble_vector(form)
        return self._owned_rows(integrals.array.reshape(-1, 4), self.Fg.function_space)

    def _own_means(self, rows: np.ndarray) -> np.ndarray:
        """Collective: (n_cells, 4) means over each cell's own walls of the per-mesh-cell
        integrals ``rows`` of a tensor (:meth:`_mirrored`)."""
        return self._mirrored(self._sum_rows(rows) / self.wall_area[:, None])

    def _mirrored(self, means: np.ndarray) -> np.ndarray:
        """A cut bottom cell takes the full cell mirrored about x2 = 0: its half-cell mean for
        11 and 22, and no shear, which changes sign under the mirror (docs/model.md section 7)."""
        means[self.tissue.cut_cells, 1:3] = 0.0
        return means

    @cached_property
    def _wall_stress_form(self) -> fem.Form:
        """Per mesh cell ``int sigma dx`` (compiled on first use: stress_direction under the
        strain law)."""
        tau = ufl.TestFunction(self.Fg.function_space)
        dx = ufl.dx(domain=self.mesh)
        stress = micro_forms.wall_stress_average_form
        return fem.form(stress(self.u, tau, self.Fg, self._E, self._nu, dx, self._fibres))

    def _stress_means(self) -> np.ndarray:
        """(n_cells, 4) wall stress averaged over each cell's own walls."""
        return self._cell_means(self._wall_stress_form)

    def _assemble(self) -> None:
        assemble_system(self.A, self.b, self.a, self.L, self.bcs)

    def _linear_solve(self) -> SolveReport:
        """The linear-kinematics solve ([var_inequal]) into u."""
        return assemble_and_solve(self.A, self.b, self.a, self.L, self.bcs, self.ksp, self.u)

    @cached_property
    def _wall_strain_form(self) -> fem.Form:
        """Per mesh cell ``int eps_el dx`` (finite kinematics: Ee; compiled on first use)."""
        tau = ufl.TestFunction(self.Fg.function_space)
        dx = ufl.dx(domain=self.mesh)
        return fem.form(self.forms.elastic_strain_average_form(self.u, tau, self.Fg, dx))

    def _cell_mean_strains(self) -> np.ndarray:
        """(n_cells, 2, 2) elastic strain averaged over each cell's own walls: the strain the
        strain law uses (pointwise values are singular at the walls' re-entrant corners)."""
        sums = self._sum_rows(self._tensor_rows(self._wall_strain_form))
        return (sums / self.wall_area[:, None]).reshape(-1, 2, 2)

    def check_growth(self, Fg: np.ndarray) -> None:
        diagnostics.stop_if(diagnostics.growth_problems(Fg, self.tissue.centres), self.comm)

    def _cue_means(self, driving: np.ndarray) -> np.ndarray:
        """(n_cells, 2, 2) the feedback's cue: the wall stress or elastic strain averaged over
        the walls around each cell, both halves of each shared wall (``feedback.walls =
        "own"``: over the cell's own halves), a cut bottom cell without shear; from the growth
        law's per-mesh-cell integrals ``driving`` where law and cue agree."""
        cue = self.director.feedback.cue
        rows = driving
        if cue != self.scene.growth.law:
            rows = self._tensor_rows(
                self._cue_stress_form if cue == "stress" else self._wall_strain_form
            )
        if self._around is None:
            return self._own_means(rows).reshape(-1, 2, 2)
        return self._mirrored(self._around.means(rows)).reshape(-1, 2, 2)

    @cached_property
    def _cue_stress_form(self) -> fem.Form:
        """Per mesh cell ``int C_w[eps_el] dx`` (finite kinematics: S) for a stress cue under
        another growth law (compiled on first use)."""
        tau = ufl.TestFunction(self.Fg.function_space)
        dx = ufl.dx(domain=self.mesh)
        stress = self.forms.wall_stress_average_form
        return fem.form(stress(self.u, tau, self.Fg, self._E, self._nu, dx, self._fibres))

    def end_step(self, dt: float) -> None:
        """The fibre director's feedback over dt from the step just solved (its cue at the
        step's start, docs/fibres.md); nothing without feedback."""
        if self.director is not None and self.director.feedback is not None:
            self.director.turn(self._cue, dt)
        if self.turgor is not None:
            self.turgor.commit(dt)

    def substep(self, dt: float, remaining: float) -> None:
        """The next solve advances the water (if any) by dt, ``remaining`` before the step's
        end, from the water kept last (the adaptive integrator's sub-steps)."""
        if self.turgor is not None:
            self.turgor.substep(dt, remaining)

    def keep(self, kept: bool) -> None:
        """Keep the last solve's water (a kept sub-step), or not (a rejected one)."""
        if self.turgor is not None and kept:
            self.turgor.keep()

    def state(self, Fg: np.ndarray, G: np.ndarray) -> dict[str, Block]:
        """Fg and G per biological cell (replicated on all ranks; rank 0 saves them); with
        finite kinematics also what Newton's next initial guess is made of (u, its offset)."""
        director = {} if self.director is None else {"fibre_angle": self.director.angle}
        cells = {k: Block.whole(v, self.comm) for k, v in ({"Fg": Fg, "G": G} | director).items()}
        if (turgor := self.turgor) is not None:  # the water held and the time of the next step
            water = {"water": turgor.held, "water_time": np.array([turgor.t]), "turgor": turgor.P}
            cells |= {k: Block.whole(v, self.comm) for k, v in water.items()}
        newton = dof_state(self.newton.guess_functions) if self.finite else {}
        return cells | (root_blocks(newton, self.comm) if self.finite else {})

    def restore(self, state: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        matches = state["Fg"].shape == (self.tissue.n_cells, 2, 2)
        if self.finite:
            tolerance = 1e-9 * max(self.tissue.bounding_box)
            matches = restore_dofs(self.newton.guess_functions, state, tolerance) and matches
        if self.director is not None:
            angle = state.get("fibre_angle")
            matches = matches and angle is not None and angle.size == self.tissue.n_cells
        if self.turgor is not None:
            water = state.get("water")
            matches = matches and water is not None and water.size == self.tissue.n_cells
        if not matches:
            raise RunError("the saved state does not match this tissue: was the scene changed?")
        if self.turgor is not None:
            self.turgor.restore(state["water"], float(state["water_time"][0]), state["turgor"])
        if self.director is not None:
            self.director.restore(state["fibre_angle"])
        return state["Fg"], state["G"]

    def measures(self, Fg: np.ndarray, G: np.ndarray) -> dict[str, float]:
        """Area enclosed by the deformed outer boundary; means of G weighted by the cells'
        reference (hexagon) areas; max |u_i|; min det Fg; the regions' statistics (their areas:
        cells.csv's deformed cell areas); with a director, fibre_order and fibre_angle_mean of
        the director the step used (weights: the hexagon areas)."""
        weights = self.hexagon_area / self.hexagon_area.sum()
        g11, g22 = float(weights @ G[:, 0, 0]), float(weights @ G[:, 1, 1])
        u1_max, u2_max = max_abs_components(self.u, self.comm)
        fibre_row = {}
        if self.director is not None:  # per-cell values are the same on every rank
            order, mean = fibres.fibre_statistics(
                self.outlines.fibre_angle, self.hexagon_area, MPI.COMM_SELF
            )
            fibre_row = {"fibre_order": order, "fibre_angle_mean": mean}
        area = self.comm.allreduce(fem.assemble_scalar(self.enclosed_area), op=MPI.SUM)
        return {
            "area": area,
            "growth_rate_11": g11,
            "growth_rate_22": g22,
            "growth_rate_area": g11 + g22,
            "u1_max": u1_max,
            "u2_max": u2_max,
            "det_Fg_min": float(np.linalg.det(Fg).min()),
            **self.regions.measures(self.outlines.area, G, self.strain_magnitudes,
                                    None if self.turgor is None else self.turgor.last.P),
            **fibre_row,
            **({} if self.turgor is None else water_measures(self.turgor, weights)),
        }
