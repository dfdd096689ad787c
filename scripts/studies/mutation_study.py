"""Mutation study: do the default CI tests notice realistic physics bugs? (issue 8)

Each mutant is one realistic bug (a sign, a factor, a transposition, a wrong configuration, a
wrong average, a wrong law or integrator, a wrong boundary condition), written as exact text
replacements in one file of the committed tree. The study never touches the working tree:

1. ``git archive HEAD`` of this repository into ``WORKDIR/tree`` (the commit is recorded);
2. a venv ``WORKDIR/venv`` (``/usr/bin/python3 -m venv --system-site-packages``) with the copy
   installed in editable mode, as ``scripts/install.sh`` does, plus meshio (the tests read XDMF
   with it), so that ``Path(sys.executable).parent / "plantgrowth"`` is the copy's CLI;
3. a baseline run of the default serial suite on the unmutated copy, which must pass;
4. per mutant: restore the pristine files, apply the mutant (every replacement must match
   exactly once, else the study stops: a mutant whose code has moved is an error, never a silent
   pass; tests/test_mutant_patterns.py checks the same in CI), run ``python -m pytest -q -m
   "not slow" -x -p no:cacheprovider tests`` and record the first failing test (``-x``: the
   test that killed the mutant) and the wall time.

Results go to ``benchmarks/results/mutants.json`` (``scripts/figures/mutants_table.py`` prints
them as a Markdown table). The exit code is 1 if a mutant survives or the baseline fails.

    python scripts/studies/mutation_study.py                 # everything (~1 h on 2 cores)
    python scripts/studies/mutation_study.py --list          # the mutants, nothing run
    python scripts/studies/mutation_study.py --only cell_pressure_sign --only E_hom_doubled
    python scripts/studies/mutation_study.py --workdir /scratch/mutants --skip-baseline --only ...

An *equivalent* mutant (one that changes no result) is no bug and is replaced, never kept as a
survivor: the first run's ``micro_mean_weighted_by_walls`` (tissue-mean growth rate weighted by
wall instead of hexagon areas) was one, since every cell's own walls, cut cells included, are
phi_w times its hexagon area.

With ``--only`` the named mutants' entries of an existing JSON file are replaced and the others
kept (each entry records the commit it was measured on and, since issue 35, the tests it was run
against: ``killed_by`` is the first failing test of that part of the suite).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
OUTPUT = REPO / "benchmarks" / "results" / "mutants.json"
DEFAULT_WORKDIR = Path("/tmp/plantgrowth-mutation-study")
PYTEST_ARGS = ["-m", "pytest", "-q", "-m", "not slow", "-x", "-p", "no:cacheprovider"]
SUITE = ["tests"]
"""What the mutants are run against: the CI suite; ``--tests`` names a part of it (a mutant
that a part kills, the whole suite kills; one that survives a part is not thereby a survivor)."""
RUN_TIMEOUT = 3600.0  # seconds per suite run; the whole serial suite takes ~3-5 min
CATEGORIES = (
    "sign", "factor", "transposition", "wrong configuration", "wrong average",
    "wrong law or integrator", "wrong boundary condition", "wrong index", "wrong scale",
    "missing check",
)  # fmt: skip


@dataclass(frozen=True)
class Mutant:
    """One bug: ``replacements`` are (old, new) pairs applied to ``file``, each old text
    occurring exactly once in the pristine file."""

    name: str
    file: str
    category: str
    description: str
    replacements: tuple[tuple[str, str], ...]


MUTANTS = (
    # --- forms/ --------------------------------------------------------------------------------
    Mutant(
        "cell_pressure_sign", "plantgrowth/unitcell/solver.py", "sign",
        "pressure cell problem [UCw_weak] with the unit pressure's sign flipped (v -> -v), "
        "issue 8",
        (("list(b) + [np.eye(2)] * pressure", "list(b) + [-np.eye(2)] * pressure"),),
    ),
    Mutant(
        "cell_grad_g_transposed", "plantgrowth/unitcell/solver.py", "transposition",
        "cell problems' growth map vec(X Fg^{-T}) instead of vec(X Fg^{-1}) (matrix, loads, "
        "averages of [UC_weak]/[UCw_weak])",
        (("return np.kron(np.eye(2), np.linalg.inv(Fg).T)",
          "return np.kron(np.eye(2), np.linalg.inv(Fg))"),),
    ),
    Mutant(
        "grad_g_transposed", "forms/elasticity.py", "transposition",
        "growth-weighted gradient grad(z) Fg^{-T} instead of grad(z) Fg^{-1} (macro and micro "
        "problems; the cell solver's own map is cell_grad_g_transposed)",
        (("return ufl.grad(z) * ufl.inv(Fg)", "return ufl.grad(z) * ufl.inv(Fg).T"),),
    ),
    Mutant(
        "micro_elastic_strain_growth_sign", "forms/elasticity.py", "sign",
        "eps_el = sym(grad u Fg^{-1}) - (sym(Fg^{-1}) - I): growth strain with the wrong sign "
        "(micro wall averages)",
        (("return sym_grad_g(u, Fg) + growth_strain(Fg)",
          "return sym_grad_g(u, Fg) - growth_strain(Fg)"),),
    ),
    Mutant(
        "macro_voigt_shear_factor", "forms/macro.py", "factor",
        "macro Voigt strain (e11, e22, e12) instead of (e11, e22, 2 e12)",
        (("ufl.as_vector([e[0, 0], e[1, 1], 2.0 * e[0, 1]])",
          "ufl.as_vector([e[0, 0], e[1, 1], e[0, 1]])"),),
    ),
    Mutant(
        "macro_turgor_sign", "forms/macro.py", "sign",
        "macro turgor stress (K_hom + (1 - phi_w) I) P1 instead of (K_hom + (phi_w - 1) I) P1",
        (("(K + (phi_w - 1.0) * ufl.Identity(2)) * P1",
          "(K + (1.0 - phi_w) * ufl.Identity(2)) * P1"),),
    ),
    Mutant(
        "micro_traction_transposed", "forms/micro.py", "transposition",
        "micro membrane traction along Fg^{-1} N instead of Fg^{-T} N",
        (("ufl.dot(ufl.inv(Fg).T, n)", "ufl.dot(ufl.inv(Fg), n)"),),
    ),
    Mutant(
        "micro_traction_without_Jg", "forms/micro.py", "wrong configuration",
        "micro membrane traction without Jg: the grown membrane's length is taken as the "
        "reference length",
        (("return -ufl.det(Fg) * P * ufl.inner(", "return -P * ufl.inner("),),
    ),
    # --- homogenization, cell solver, tensors ---------------------------------------------------
    Mutant(
        "E_hom_doubled", "plantgrowth/unitcell/homogenization.py", "factor",
        "E_hom doubled on its way from the cell problems to the macro problem, issue 8",
        (("C = packed[:, :9].reshape(n, 3, 3) * E[:, None, None]",
          "C = packed[:, :9].reshape(n, 3, 3) * (2.0 * E[:, None, None])"),),
    ),
    Mutant(
        "dbar_v_E_scaling", "plantgrowth/unitcell/homogenization.py", "factor",
        "dbar[v] of the reduced (E = 1) cell scaled by E instead of 1/E",
        (("reshape(n, 2, 2) / E[:, None, None]", "reshape(n, 2, 2) * E[:, None, None]"),),
    ),
    Mutant(
        "cell_average_over_walls", "plantgrowth/unitcell/solver.py", "wrong average",
        "cell averages divided by |Y_w| instead of |Y|",
        (("grad_g.transpose(0, 1, 3, 2)) / self.area",
          "grad_g.transpose(0, 1, 3, 2)) / self.wall_area"),),
    ),
    Mutant(
        "voigt_vector_shear_factor", "plantgrowth/base/tensors.py", "factor",
        "numpy Voigt strain (e11, e22, e12) instead of (e11, e22, 2 e12) in sigma_hom",
        (("np.stack([e[..., 0, 0], e[..., 1, 1], 2.0 * e[..., 0, 1]], axis=-1)",
          "np.stack([e[..., 0, 0], e[..., 1, 1], e[..., 0, 1]], axis=-1)"),),
    ),
    # --- growth law and integrators ---------------------------------------------------------------
    Mutant(
        "positive_part_abs", "plantgrowth/models/growth.py", "wrong law or integrator",
        "[A]_+ built from |eigenvalues| instead of max(eigenvalues, 0) where both are negative",
        (("weight = np.where(mixed, high / np.where(mixed, high - low, 1.0), 0.0)",
          "weight = np.where(mixed, high / np.where(mixed, high - low, 1.0), -1.0)"),),
    ),
    Mutant(
        "clamp_before_eta", "plantgrowth/models/growth.py", "wrong law or integrator",
        "G = eta clip([X/phi_w - tau]_+, -M, M) instead of clip(eta [.]_+, -M, M)",
        (("np.clip(eta[:, None, None] * positive_part(driving), -clamp, clamp)",
          "eta[:, None, None] * np.clip(positive_part(driving), -clamp, clamp)"),),
    ),
    Mutant(
        "elastic_strain_transposed", "plantgrowth/models/growth.py", "transposition",
        "numpy eps_el from Fg^{-1} grad u instead of grad u Fg^{-1} (sigma_hom, eps_hom)",
        (("A = grad_u @ Finv + Finv", "A = Finv @ grad_u + Finv"),),
    ),
    Mutant(
        "homogenized_strain_dbar_transposed", "plantgrowth/models/growth.py", "transposition",
        "eps_hom with sum_kl eps_el_kl dbar[w^ij]_kl instead of sum_ij eps_el_ij dbar[w^ij]_kl",
        (('np.einsum("nij,nijkl->nkl", eps_el, dbar_w)',
          'np.einsum("nkl,nijkl->nij", eps_el, dbar_w)'),),
    ),
    Mutant(
        "exp_integrator_order", "plantgrowth/models/growth.py", "wrong law or integrator",
        "exp integrator Fg expm(dt G) instead of expm(dt G) Fg",
        (("return exp_symmetric(G, dt) @ Fg", "return Fg @ exp_symmetric(G, dt)"),),
    ),
    # --- coupled loop -----------------------------------------------------------------------------
    Mutant(
        "sigma_without_K", "plantgrowth/models/macro/model.py", "wrong law or integrator",
        "growth driven by the elastic part E_hom eps_el only, without K_hom P1",
        (("growth.homogenized_stress(C, eps_el, K, P)",
          "growth.homogenized_stress(C, eps_el, None, P)"),),
    ),
    Mutant(
        "interpolation_points_swapped", "plantgrowth/models/macro/model.py", "transposition",
        "coarse-node tensors interpolated at (x2, x1) instead of the fine cells' (x1, x2)",
        (("scene.tissue.H, problem.midpoints[:, :2], comm",
          "scene.tissue.H, problem.midpoints[:, 1::-1], comm"),),
    ),
    Mutant(
        "E_factor_wrong_cell", "plantgrowth/models/macro/model.py", "wrong index",
        "each fine cell's E_hom scaled by the E of its neighbour in the cell order (issue 20, "
        "item 4: the per-cell E factor)",
        (("self.E = scene.material.E(*(at_cells if self.per_cell else at_nodes))",
          "self.E = np.roll(scene.material.E(*(at_cells if self.per_cell else at_nodes)), 1)"),),
    ),
    Mutant(
        "cell_growth_wrong_cell", "plantgrowth/unitcell/homogenization.py", "wrong index",
        "the surrogate asked at another cell's stretch (the queries' s reversed)",
        (("s_q, b_q = s[point], b[point]", "s_q, b_q = s[point][::-1], b[point]"),),
    ),
    Mutant(
        "table_weights_dropped", "plantgrowth/unitcell/homogenization.py", "factor",
        "the coarse nodes' tables summed with weight 1 instead of their P1 weights at the cell",
        (("combine = sp.csr_matrix((pairs.data, (point",
          "combine = sp.csr_matrix((np.ones_like(pairs.data), (point"),),
    ),
    Mutant(
        "Fg_projection_transposed", "plantgrowth/models/macro/model.py", "transposition",
        "Fg projected to the coarse nodes as Fg^T (cell problems solved for the transpose)",
        (("Fg[:n_owned].reshape(-1, 4)", "np.swapaxes(Fg[:n_owned], 1, 2).reshape(-1, 4)"),),
    ),
    # --- macro problem ----------------------------------------------------------------------------
    Mutant(
        "macro_bottom_clamped", "plantgrowth/models/macro/supports.py", "wrong boundary condition",
        "macro bottom edge clamped (u = 0) instead of a symmetry plane (u2 = 0)",
        (("self.symmetry = edge_dofs(V, boundary, boundary.symmetry, 1)",
          "self.symmetry = edge_dofs(V, boundary, boundary.symmetry, 1)\n"
          "        self.symmetry_u1 = edge_dofs(V, boundary, boundary.symmetry, 0)"),
         ("return [fem.dirichletbc(zero, self.symmetry, self.V.sub(1))] + [",
          "return [fem.dirichletbc(zero, self.symmetry, self.V.sub(1)), "
          "fem.dirichletbc(zero, self.symmetry_u1, self.V.sub(0))] + ["),),
    ),
    # --- micro model ------------------------------------------------------------------------------
    Mutant(
        "micro_bottom_clamped", "plantgrowth/models/micro/supports.py", "wrong boundary condition",
        "micro bottom walls clamped (u = 0) instead of a symmetry plane (u2 = 0)",
        (("fem.dirichletbc(zero, fem.locate_dofs_topological(V.sub(1), 1, bottom), V.sub(1)),",
          "fem.dirichletbc(np.zeros(2, dtype=PETSc.ScalarType), "
          "fem.locate_dofs_topological(V, 1, bottom), V),"),),
    ),
    Mutant(
        "micro_average_over_hexagon", "plantgrowth/models/micro/model.py", "wrong average",
        "per-cell micro growth driven by the wall integral divided by the cell's hexagon area "
        "instead of its wall area",
        (("return self._mirrored(self._sum_rows(rows) / self.wall_area[:, None])",
          "return self._mirrored(self._sum_rows(rows) / self.hexagon_area[:, None])"),),
    ),
    Mutant(
        "micro_cut_cell_shear_kept", "plantgrowth/models/micro/model.py", "wrong average",
        "cut bottom cells averaged as they are (shear kept) instead of as the mirrored full cell",
        (("means[self.tissue.cut_cells, 1:3] = 0.0", "means[self.tissue.cut_cells, 1:3] *= 1.0"),),
    ),
    # --- time loop --------------------------------------------------------------------------------
    Mutant(
        "adaptive_midpoint_lagged", "plantgrowth/runner/timeloop.py", "wrong law or integrator",
        "adaptive integrator's second half-step with the start-of-step G, not the midpoint G",
        (("growth.advance(half, middle.G, 0.5 * h, \"exp\")",
          "growth.advance(half, G, 0.5 * h, \"exp\")"),),
    ),
    Mutant(
        "scene_integrator_ignored", "plantgrowth/runner/timeloop.py", "wrong law or integrator",
        "explicit steps always use exp, whatever the scene's integrator says",
        (("return growth.advance(Fg, G, t.dt, t.integrator), 1, 0",
          "return growth.advance(Fg, G, t.dt, \"exp\"), 1, 0"),),
    ),
    # --- finite kinematics (docs/model.md section 10, issue 12) -----------------------------------
    Mutant(
        "finite_Fe_order", "forms/finite.py", "transposition",
        "elastic deformation Fe = Fg^{-1} F instead of F Fg^{-1} (macro and micro residuals, the "
        "stretch floor)",
        (("return deformation_gradient(u) * ufl.inv(Fg)",
          "return ufl.inv(Fg) * deformation_gradient(u)"),),
    ),
    Mutant(
        "finite_green_lagrange_left", "forms/finite.py", "wrong configuration",
        "Green-Lagrange strain from the left Cauchy-Green tensor Fe Fe^T instead of Fe^T Fe",
        (("return 0.5 * (Fe.T * Fe - ufl.Identity(2))",
          "return 0.5 * (Fe * Fe.T - ufl.Identity(2))"),),
    ),
    Mutant(
        "finite_green_lagrange_factor", "forms/finite.py", "factor",
        "Green-Lagrange strain Fe^T Fe - I without the factor 1/2",
        (("return 0.5 * (Fe.T * Fe - ufl.Identity(2))", "return Fe.T * Fe - ufl.Identity(2)"),),
    ),
    Mutant(
        "finite_cofactor_transposed", "forms/finite.py", "transposition",
        "cofactor det(F) F^{-1} instead of det(F) F^{-T} (follower turgor and tractions)",
        (("return ufl.det(F) * ufl.inv(F).T", "return ufl.det(F) * ufl.inv(F)"),),
    ),
    Mutant(
        "finite_macro_stress_order", "forms/finite.py", "transposition",
        "macro first Piola stress from S Fe instead of Fe S",
        (("P = Fe * walls_macro_stress(u, Fg, C, K, P1)",
          "P = walls_macro_stress(u, Fg, C, K, P1) * Fe"),),
    ),
    # --- issue 36 ----------------------------------------------------------------------------
    Mutant(
        "finite_lumens_dead", "forms/finite.py", "wrong configuration",
        "the lumens' water as the dead stress -(1 - phi_w) P1 Fe (the earlier law) instead of "
        "the follower -(1 - phi_w) P1 cof(Fe)",
        (("return -(1.0 - phi_w) * P1 * cofactor(Fe)", "return -(1.0 - phi_w) * P1 * Fe"),),
    ),
    Mutant(
        "stability_total_stress", "plantgrowth/models/macro/problem.py", "wrong law or integrator",
        "the acoustic tensor with the total stress S_w - (1 - phi_w) P1 I (walls and lumens)",
        (("K = None if self.K is None else self.cell_values(self.K).reshape(-1, 2, 2)",
          "K = None if self.K is None else self.cell_values(self.K).reshape(-1, 2, 2) - (\n"
          "            1.0 - self.cell_values(self.phi_w)[:, :, None]) * np.eye(2)"),),
    ),
    Mutant(
        "feedback_own_halves_default", "plantgrowth/scene/walls.py", "wrong average",
        "the micro feedback cue over each cell's own halves of its walls by default (the "
        "unstable cue of before issue 36) instead of both halves of the walls around it",
        (('    walls: str = "around"', '    walls: str = "own"'),),
    ),
    Mutant(
        "resolution_by_fine_cells", "plantgrowth/models/nonelliptic_sets.py", "wrong scale",
        "the resolution rule by fine cells (a set of at most four fine cells is a singular "
        "point) instead of its area against a cell's grown area",
        (("cell_area = float(np.dot(grown[mine], cell_areas[mine]) / area) if area > 0.0 else 0.0",
          "cell_area = 2.0 * area if len(mine) <= 4 else 0.0"),),
    ),
    # --- issue 20 ----------------------------------------------------------------------------
    Mutant(
        "load_imbalance_reference_length", "plantgrowth/models/macro/edge_loads.py",
        "wrong configuration",
        "load_imbalance summed with the tractions per reference length (the scene's balance "
        "check once more) instead of per grown or current length",
        (("n: fem.form(self.tractions[n][0] * factor * self.ds(self.tags[n])) for n in self.names",
          "n: fem.form(self.tractions[n][0] * self.ds(self.tags[n])) for n in self.names"),),
    ),
    Mutant(
        "edge_force_reference_length", "plantgrowth/models/macro/edge_loads.py",
        "wrong configuration",
        "a total force's traction F / L0 with the reference length L0 instead of the edge's "
        "grown or current length L",
        (("self._length = {n: fem.form(factor * self.ds(self.tags[n])) for n in self.names}",
          "self._length = {n: fem.form(1.0 * self.ds(self.tags[n])) for n in self.names}"),),
    ),
    Mutant(
        "acoustic_tensor_transposed", "plantgrowth/models/stability.py", "transposition",
        "the acoustic tensor's geometric part Fe^T M(N) Fe instead of Fe M(N) Fe^T (the tangent's "
        "indices contracted in the wrong order: the same for a pure stretch)",
        (("Qx = Fe[:, None] @ M @ np.swapaxes(Fe, 1, 2)[:, None]",
          "Qx = np.swapaxes(Fe, 1, 2)[:, None] @ M @ Fe[:, None]"),),
    ),
    Mutant(
        "newton_tolerance_on_the_residual", "plantgrowth/models/newton.py", "wrong scale",
        "Newton's relative tolerance taken against the whole residual at the initial guess, "
        "growth mismatch included, instead of the external load",
        (("load = 0.0 if self.load is None else self.residual_norm(self.load)",
          "load = self.residual_norm()"),),
    ),
    Mutant(
        "newton_guess_by_residual_only", "plantgrowth/models/newton.py", "missing check",
        "the initial guesses ranked by their residual alone (no ellipticity): the collapsed "
        "state's small residual wins",
        (("return (True, stable >= 0.0, min(stable, 0.0), -r)", "return (True, -r)"),),
    ),
    Mutant(
        "newton_linear_solves_unchecked", "plantgrowth/models/newton.py", "missing check",
        "a failed linear solve of Newton's without a fallback goes on (the natural-monotonicity "
        "solve's convergence was never checked)",
        (("                diagnostics.stop_if(problems, self.comm)\n", ""),),
    ),
    # --- issue 22: fibre-reinforced walls and feedback (docs/model.md, fibre-reinforced walls) ---
    # The fibre weight and the grown tangent are written twice: in numpy for the cell solver's
    # fast path (base/tensors.py, what the macro model's tensors come from) and in UFL for the
    # reference cell forms and the micro model (forms/elasticity.py): one mutant per place.
    Mutant(
        "fibre_weight_unsquared_cell", "plantgrowth/base/tensors.py", "factor",
        "fast-path wall tensor C_iso + E_f (m . t_g) t_g^4 instead of E_f (m . t_g)^2 t_g^4 "
        "(the cell solver's numpy fibre tensor, hence the macro model's tensors)",
        (("q = float(m @ tg) ** 2", "q = float(m @ tg)"),),
    ),
    Mutant(
        "fibre_weight_unsquared_walls", "forms/elasticity.py", "factor",
        "UFL wall stress with the fibre weight (m . t_g) instead of (m . t_g)^2 (the reference "
        "cell forms and the micro model's walls)",
        (("q = ufl.inner(fibres.director, tg) ** 2", "q = ufl.inner(fibres.director, tg)"),),
    ),
    Mutant(
        "fibre_reference_tangent_cell", "plantgrowth/base/tensors.py", "wrong configuration",
        "fast-path fibre tensor along the reference tangent t instead of the grown one "
        "t_g = Fg t / |Fg t| (weight and direction)",
        (("tg = Fg @ t", "tg = 1.0 * t"),),
    ),
    Mutant(
        "fibre_reference_tangent_walls", "forms/elasticity.py", "wrong configuration",
        "UFL fibre stress along the reference tangent t instead of the grown one "
        "t_g = Fg t / |Fg t| (the reference cell forms and the micro model's walls)",
        (("Ft = ufl.dot(Fg, fibres.tangent)", "Ft = fibres.tangent"),),
    ),
    Mutant(
        "feedback_smallest_direction", "plantgrowth/models/fibres.py", "wrong law or integrator",
        "the director turns toward the cue's smallest principal direction (a_Q + 90) instead of "
        "its largest (macro and micro feedback)",
        (("angle = reduce_angle(np.degrees(principal.principal_angle(Q)))",
          "angle = reduce_angle(np.degrees(principal.principal_angle(Q)) + 90.0)"),),
    ),
    Mutant(
        "feedback_step_sign", "plantgrowth/models/fibres.py", "sign",
        "the exact feedback step tan(a_new - a_Q) = tan(a - a_Q) exp(+k A dt) instead of "
        "exp(-k A dt): the director turns away from the cue",
        (("factor = np.exp(-rate * np.asarray(cue_anisotropy, dtype=float) * dt)",
          "factor = np.exp(rate * np.asarray(cue_anisotropy, dtype=float) * dt)"),),
    ),
    # The walk over the levels moved from surrogate.py into lattice.py (issue 33, the stop-square
    # cache): surrogate_level_per_query follows it, the same bug in the walk's two lines.
    Mutant(
        "surrogate_level_per_query", "plantgrowth/unitcell/lattice.py", "wrong average",
        "a lattice level chosen per query again (issue 33): only the hats of the query's own "
        "chain of refined squares are summed (a square's hats count where at least 3 of its "
        "corners are points of that level), the neighbours' finer points on its edges dropped",
        (("used = np.where(built[:, None, :], weights, 0.0).reshape(-1, 4)",
          "used = np.where((built & (built.sum(axis=1, keepdims=True) >= 3))[:, None, :], "
          "weights, 0.0).reshape(-1, 4)"),
         ("has = built.any(axis=1)", "has = built.sum(axis=1) >= 3")),
    ),
    Mutant(
        "director_not_periodic", "plantgrowth/unitcell/director_lattice.py",
        "wrong law or integrator",
        "the director's angle interpolated with the odd-count Dirichlet kernel "
        "sin(N d) / (N sin d) through an even count of nodes: interpolating, but of period 360 "
        "degrees and changing sign over 180 (issue 33, item 2)",
        (("weights = np.sin(count * d) * np.cos(d) / (count * safe)",
          "weights = np.sin(count * d) / (count * safe)"),),
    ),
    Mutant(
        "director_small_weights_skipped", "plantgrowth/unitcell/director_lattice.py", "factor",
        "the fine nodes of small weight (|l_j(b)| <= 1e-3) not asked, as those of weight 0 are, "
        "so their terms take another node's answer: the director's angle dependence near a "
        "node cut off (issue 33's last stop asks every node of nonzero weight)",
        (("used = (weights != 0.0) & ((blend > 0.0)[:, None] | own)",
          "used = (np.abs(weights) > 1e-3) & ((blend > 0.0)[:, None] | own)"),),
    ),
    Mutant(
        "director_near_node_step", "plantgrowth/unitcell/director_lattice.py", "wrong average",
        "the near-node form A_k and the sparse grid's A switched by a step at mid-zone instead of "
        "blended by the C1 step 3 t^2 - 2 t^3: the answer jumps by |A - A_k| where a director "
        "crosses it (issue 33's last stop)",
        (("    return node.astype(np.int64) % count, t * t * (3.0 - 2.0 * t)",
          "    return node.astype(np.int64) % count, (t > 0.5).astype(float)"),),
    ),
    # --- issue 33, this stop: stop squares, the angle's sparse grid, refinement, AMG reuse ------
    Mutant(
        "lattice_place_per_level", "plantgrowth/unitcell/lattice.py", "wrong scale",
        "a query placed per level again: each level's square from s / (H0 / 2^k) rounded to 9 "
        "digits on its own instead of one rounding of s / H0 for every level, so a query a hair "
        "off a lattice line may sit in a level-1 square outside its level-0 one (the squares "
        "do not nest; the draft gradient_nu_stress scene's endless refinement)",
        (("    x = place(s) * 2.0**level  # exact: a power of 2\n    base = np.floor(x)\n"
          "    return base.astype(np.int64) * (STEP >> level), x - base",
          "    x = s / (H0 / 2.0**level)\n    base = np.floor(np.round(x, 9))\n"
          "    return base.astype(np.int64) * (STEP >> level), "
          "np.clip(np.round(x - base, 9), 0.0, 1.0)"),),
    ),
    Mutant(
        "stop_square_drop_built_only", "plantgrowth/unitcell/lattice.py", "wrong index",
        "a refinement drops the cached stop squares that meet the built square only, instead "
        "of its parent widened by one spacing h on every side (the new points' hat supports): "
        "a neighbour's cached corners keep the interpolant of before",
        (("    low = corner // span * span - h\n    return table, low, low + span + 2 * h",
          "    low = corner\n    return table, low, low + h"),),
    ),
    Mutant(
        "refine_pass_touched_scale", "plantgrowth/unitcell/lattice.py", "wrong scale",
        "a refinement pass tests which queries the new hats reach with the queries' places in "
        "coarsest spacings (s / H0) against boxes in finest-lattice integers: most queries "
        "the new points change keep the answers of the lattice before (this stop's pass reuse)",
        (("    x = place(s) * STEP  # exact: a power of 2\n    out = np.zeros(",
          "    x = place(s)\n    out = np.zeros("),),
    ),
    Mutant(
        "learn_walks_per_deepest_square", "plantgrowth/unitcell/lattice.py", "wrong index",
        "learning stop squares walks one query per square of the deepest built level instead "
        "of the level below it: queries in one such square may stop in different children, "
        "and the stop squares of all but one are never learnt (this stop's shared walks)",
        (("depth = min(int(((squares >> 42) & 15).max()) + 1, MAX_LEVEL)",
          "depth = min(int(((squares >> 42) & 15).max()), MAX_LEVEL)"),),
    ),
    Mutant(
        "stop_square_lookup_finer_first", "plantgrowth/unitcell/lattice.py", "wrong index",
        "of two nested stop squares the finer one kept in the lookup's Z-order ranges instead "
        "of the coarser: a query in the coarser square but outside the finer one finds no "
        "entry (issue 33 stop 52's one-search lookup; the walk stops at the coarser square)",
        (("order = np.lexsort((-ends, starts))  # by start, a coarser entry first",
          "order = np.lexsort((ends, starts))  # by start, a coarser entry first"),),
    ),
    Mutant(
        "near_node_zone_fixed", "plantgrowth/unitcell/director_lattice.py", "factor",
        "the near-node zone kept at its 1e-3 width whatever the tolerance: at the fine "
        "preset's 1e-4 the near-node form A_k answers where its error (2e-3 per degree) is the "
        "whole tolerance (this stop's zone scaled with the tolerance)",
        (("scale = min(tolerance / 1e-3, NEAR_NODE_WIDEST * 180.0 / count / NEAR_NODE[1])",
          "scale = min(1.0, NEAR_NODE_WIDEST * 180.0 / count / NEAR_NODE[1])"),),
    ),
    Mutant(
        "angle_surplus_sign", "plantgrowth/unitcell/angle_surplus.py", "sign",
        "the angle surplus (I_2N + I_N) g instead of (I_2N - I_N) g: a doubling's new nodes "
        "taken against the coarser interpolant with the wrong sign (both surplus terms of the "
        "director's sparse grid)",
        (("surplus[:, ::2] -= coarse", "surplus[:, ::2] += coarse"),),
    ),
    Mutant(
        "angle_surplus_levels_swapped", "plantgrowth/unitcell/director_lattice.py",
        "wrong scale",
        "the angle surpluses' stretch grids swapped: (I_2M - I_M) f, the larger surplus, on the "
        "coarse level-0 grid and (I_4M - I_2M) f on the level-1 grid, instead of the other way "
        "round (the larger surplus interpolated with P_0's larger error, 1-2% against 0.4%)",
        (("SURPLUS_TERMS = ((2, 1), (4, 0))", "SURPLUS_TERMS = ((2, 0), (4, 1))"),),
    ),
    Mutant(
        "refinement_residual_in_double", "plantgrowth/models/refinement.py",
        "wrong law or integrator",
        "the refinement step's residual b - A x with products and sums in double instead of "
        "long double: its round-off floor is the LU's own residual, so the step stalls",
        (("EXTENDED = np.longdouble", "EXTENDED = np.float64"),),
    ),
    Mutant(
        "preconditioner_reference_first_solve", "plantgrowth/models/preconditioner_reuse.py",
        "wrong law or integrator",
        "the AMG rebuild rule's reference kept at the first solve after a rebuild (the old rule) "
        "instead of the fewest iterations since: a cold first solve (step 0, a resumed run) "
        "sets a reference the rule never exceeds again",
        (("        elif report.iterations > 0:\n"
          "            self.reference = min(self.reference, report.iterations)\n", ""),),
    ),
    # --- issue 35: water fluxes (docs/model.md, "Water fluxes") ------------------------------
    # The storage, the conductivity's grown lengths and the supplies are coded twice: in the
    # macro model (UFL forms and the unit cell's coefficients) and in the micro model's water
    # network (numpy): one mutant per model. The exact lumen area is the micro model's only.
    Mutant(
        "macro_storage_sign", "plantgrowth/models/macro/water.py", "sign",
        "the macro storage 1/M = +tr dbar[v] instead of -tr dbar[v] (negative: the water held "
        "at a fixed strain falls as turgor rises; in the step's matrix and in m alike)",
        (("pr.set_cell_values(self.inv_M, -np.trace(tensors.dbar_v, axis1=1, axis2=2))",
          "pr.set_cell_values(self.inv_M, np.trace(tensors.dbar_v, axis1=1, axis2=2))"),),
    ),
    Mutant(
        "micro_storage_sign", "plantgrowth/models/micro/turgor_solve.py", "sign",
        "a micro lumen's area V_c(u) = V_c(0) - B_c . u instead of + B_c . u (the water held "
        "falls as turgor pushes the membrane out; in the step's water row and the water held "
        "alike, so the balance still closes)",
        (("self.bordered.solve(-B, -B, -self.dt * H, parts.b, -h, parts.u.vector)",
          "self.bordered.solve(-B, B, -self.dt * H, parts.b, -h, parts.u.vector)"),
         ("self.settle(P, V0 + self._lumen_terms(B), Fg)",
          "self.settle(P, V0 - self._lumen_terms(B), Fg)")),
    ),
    Mutant(
        "kappa_reference_lengths_macro", "plantgrowth/unitcell/hydraulic_coefficients.py",
        "wrong configuration",
        "the unit cell's kappa with the walls' reference lengths l_k instead of the grown "
        "|Fg t_k| l_k (the macro model's conductivity)",
        (("kappa += np.linalg.norm(Fg @ t) * length * np.outer(Fg @ d, Fg @ d)",
          "kappa += length * np.outer(Fg @ d, Fg @ d)"),),
    ),
    Mutant(
        "kappa_reference_lengths_micro", "plantgrowth/models/micro/water.py",
        "wrong configuration",
        "the micro water network's shared walls conducting through their reference lengths l "
        "instead of the grown |Fg t| l",
        (("ell = 0.5 * (grown_lengths(net.shared, Fg[c]) + grown_lengths(net.shared, Fg[d]))",
          "ell = np.linalg.norm(net.shared, axis=1)"),),
    ),
    Mutant(
        "supply_sign_macro", "forms/hydraulics.py", "sign",
        "a supplied edge's inflow L_s |cof(Fg) N| (psi - psi_s) instead of (psi_s - psi) (the "
        "macro model's edge term: in the step's matrix, its right-hand side and the reported "
        "inflow alike)",
        (("return L_s * grown_length(Fg, n) * p * q * ds",
          "return -L_s * grown_length(Fg, n) * p * q * ds"),),
    ),
    Mutant(
        "supply_sign_micro", "plantgrowth/models/micro/water.py", "sign",
        "a supplied edge's inflow into a micro cell L_s ell_cs (psi_c - psi_s) instead of "
        "(psi_s - psi_c) (its weight's sign: in H, the supply term and the reported inflow)",
        (("return supply.conductance * np.bincount(net.outer_cell[on], lengths, self.n)",
          "return -supply.conductance * np.bincount(net.outer_cell[on], lengths, self.n)"),),
    ),
    Mutant(
        "finite_lumen_reference_membrane", "forms/finite.py", "wrong configuration",
        "the micro finite-kinematics lumen constraint V_c with the area the reference membrane "
        "encloses, (1/2) int X . N_l dS, instead of the deformed one's, "
        "(1/2) int x . cof(F) N_l dS",
        (("x = ufl.SpatialCoordinate(u.ufl_function_space().mesh) + u",
          "x = ufl.SpatialCoordinate(u.ufl_function_space().mesh)"),
         ("return -0.5 * weight * ufl.inner(x, ufl.dot(cofactor(deformation_gradient(u)), n)) * ds",
          "return -0.5 * weight * ufl.inner(x, n) * ds")),
    ),
    # --- issue 34: real tissues (docs/real_tissues.md) ----------------------------------------
    # A tissue of cells reaches the models through its walls (the network of shared walls, the
    # traced outlines), its measured shapes (the stretch Fs, applied before growth) and its units
    # (the pixel size). The shape tensor J is symmetric, so is Fs: "Fg0 transposed" is no bug; its
    # meaningful forms are the order Fg Fs and the power of J. The stretch from the raw second
    # moment int (x - c)(x - c)^T instead of J = that / |P| is equivalent (Fg0 is rescaled to the
    # cell's area, and F is homogeneous in J) and is not kept.
    Mutant(
        "shared_wall_one_cell_network", "meshes/cell_walls.py", "wrong index",
        "the wall network gives each shared wall to one of its two cells only, as an outer wall "
        "of that cell (the other loses it): no water crosses between cells, and outer walls "
        "appear inside the tissue",
        (("        if len(found) == 2:\n            pairs.append(",
          "        if len(found) == 3:\n            pairs.append("),),
    ),
    Mutant(
        "shared_wall_one_cell_tracing", "meshes/label_tracing.py", "wrong index",
        "a traced wall between two labels is joined into the outline of the label on its left "
        "only, not also (reversed) into its right neighbour's",
        (("for label, run in ((a, p), (b, p[::-1])):", "for label, run in ((a, p),):"),),
    ),
    Mutant(
        "cell_shape_after_growth", "plantgrowth/models/macro/model.py", "transposition",
        "the unit cell of a tissue given as cells grown by Fs Fg (growth first, then the cell's "
        "measured shape) instead of Fg Fs",
        (("            Fg = Fg @ self.shape", "            Fg = self.shape @ Fg"),),
    ),
    Mutant(
        "cell_stretch_inverse_root", "meshes/cell_shapes.py", "wrong law or integrator",
        "the stretch F = J0^{-1/2} (J0^{1/2} J J0^{1/2})^{-1/2} J0^{-1/2}: the inverse square "
        "root where the square root belongs (a cell's elongation turned across it)",
        (("middle = _spd_power(root @ J @ root, 0.5)",
          "middle = _spd_power(root @ J @ root, -0.5)"),),
    ),
    Mutant(
        "cut_cell_shape_unmirrored", "meshes/cell_shapes.py", "wrong configuration",
        "a cut cell's shape tensor and area from its half above x2 = 0 instead of the cell "
        "united with its mirror image (a half-height cell: Fg0 flattened across the plane)",
        (("moments = [(mirrored_moment if c else second_moment)(cells.polygon(i))",
          "moments = [second_moment(cells.polygon(i))"),),
    ),
    Mutant(
        "mirrored_moment_mixed_kept", "meshes/cell_shapes.py", "wrong average",
        "a cut cell's mixed moment int (x1 - c1) x2 dA kept from its half (doubled) instead of "
        "cancelling between the half and its mirror image",
        (("return 2.0 * area, np.array([centroid[0], 0.0]), 2.0 * np.diag(np.diag(S))",
          "return 2.0 * area, np.array([centroid[0], 0.0]), 2.0 * S"),),
    ),
    Mutant(
        "pixel_size_ignored_image", "plantgrowth/scene/cells_spec.py", "wrong scale",
        "a label image's cells left in pixels: tissue.pixel_size read and checked but not "
        "passed to the tracing",
        (("return trace_cells(labels, spec.pixel_size)", "return trace_cells(labels, 1.0)"),),
    ),
    Mutant(
        "pixel_size_ignored_table", "meshes/polygon_table.py", "wrong scale",
        "a polygon table's vertices left in pixels: its own or the scene's pixel_size ignored",
        (("scale = own if own is not None else (pixel_size if pixel_size is not None else 1.0)",
          "scale = 1.0"),),
    ),
    Mutant(
        "neighbours_count_outer_walls", "meshes/cell_polygons.py", "wrong index",
        "a cell's neighbour count with the outside (its outer walls) counted as one more "
        "neighbour, as the background label of an image would be",
        (("            if len(found) == 2:\n                neighbours[found[0]].add(found[1])",
          "            neighbours[found[0]].add(found[1] if len(found) == 2 else -1)\n"
          "            if len(found) == 2:"),),
    ),
    Mutant(
        "cut_cell_centre_own_centroid", "meshes/cell_tissue.py", "wrong configuration",
        "a cut cell's centre (where the scene's fields are read) at its own half's centroid, "
        "above x2 = 0, instead of the mirrored whole cell's, on x2 = 0",
        (("centres[i] = [polygon_centroid(self.outline(i))[0], 0.0]",
          "centres[i] = self.cells.centroids[i]"),),
    ),
    # --- issue 33, stop 47: the cell phase's bounded estimates, symmetric rotations, SPD test -
    Mutant(
        "estimate_bound_at_refine_threshold", "plantgrowth/unitcell/surrogate.py", "factor",
        "a query's bound of its estimate spares it below the refine threshold (the tolerance) "
        "instead of KEEP times it: a refinement no longer goes on to KEEP times the tolerance "
        "in the squares it built (the gap between the thresholds closed)",
        (("found = self._pass(ids, s, found, squares, KEEP * tol)",
          "found = self._pass(ids, s, found, squares, tol)"),),
    ),
    Mutant(
        "estimate_bound_without_spread", "plantgrowth/unitcell/lattice.py", "wrong average",
        "the stop square's lower bound of |I| taken as its largest corner value's norm, without "
        "the corners' spread: the bound may fall below the estimate it stands in for",
        (("columns += [self._norms(change), (self._norms(values) - spread).max(axis=1)]",
          "columns += [self._norms(change), self._norms(values).max(axis=1)]"),),
    ),
    Mutant(
        "symmetric4_turned_back", "plantgrowth/base/tensors.py", "transposition",
        "dbar[w] turned by T^T D T (the rotation by -R) instead of T D T^T",
        (("turned = (T @ D3 @ np.swapaxes(T, 1, 2)).reshape(n, 9)",
          "turned = (np.swapaxes(T, 1, 2) @ D3 @ T).reshape(n, 9)"),),
    ),
    Mutant(
        "stiffness_check_two_minors", "plantgrowth/models/diagnostics.py", "wrong index",
        "E_hom's SPD test by its first two leading minors only (Sylvester's criterion without "
        "the determinant): an indefinite E_hom with a positive 2 x 2 block passes",
        (("bad = ~((a > 0) & (a * d - b * b > 0) & (det > 0))",
          "bad = ~((a > 0) & (a * d - b * b > 0))"),),
    ),
    Mutant(
        "c1_blend_length_ignores_miss", "plantgrowth/unitcell/smooth_answers.py",
        "missing check",
        "every new point of the c1 path blended in over B steps whatever its miss: a point the "
        "interpolant before it missed by many tolerances keeps part of that miss for B steps",
        (("    length = np.round(BLEND_STEPS / np.maximum(miss, 1.0))\n",
          "    length = np.full(len(miss), float(BLEND_STEPS))\n"),),
    ),
    Mutant(
        "c1_declined_points_taken", "plantgrowth/unitcell/smooth_answers.py", "missing check",
        "the c1 path's declines ignored: every new point enters J, those J already met within "
        "DECLINE tolerances too (each move of J costs the macro CG iterations)",
        (("        keys, point_birth, values = keys[taken], point_birth[taken], exact[taken]\n",
          "        values = exact.copy()\n"),),
    ),
    Mutant(
        "c1_ghosts_never_quadratic", "plantgrowth/unitcell/smooth_lattice.py", "wrong index",
        "the c1 interpolant's level-0 ghosts never take the quadratic extrapolation: a ghost "
        "whose directions all have three built nodes in a row gets none at all",
        (("        quadratic = count[0] > 0\n", "        quadratic = count[0] < 0\n"),),
    ),
    Mutant(
        "spare_goal_not_tightened", "plantgrowth/models/linear.py", "factor",
        "solver.macro_spare_iterations read and ignored: CG stops at macro_rtol whatever the "
        "iterations it has to spare (the organ scene's 1- and 2-rank runs then differ by 1.8e-6)",
        (("        goal = rtol / SPARE_FACTOR if its < self.spare else rtol\n",
          "        goal = rtol\n"),),
    ),
    Mutant(
        "step_chunk_not_shuffled", "plantgrowth/runner/h5_blocks.py", "transposition",
        "a field's chunk deflated in row order instead of after HDF5's byte shuffle, which the "
        "dataset declares: every reader un-shuffles the inflated bytes into other values",
        (("    shuffled = values.view(np.uint8).reshape(-1, values.dtype.itemsize).T\n",
          "    shuffled = values.view(np.uint8).reshape(-1, values.dtype.itemsize)\n"),),
    ),
    Mutant(
        "state_recycled_whatever_its_shapes", "plantgrowth/runner/h5_blocks.py", "missing check",
        "the older state file rewritten in place without comparing its datasets' shapes and "
        "dtypes with the new step's: a step whose arrays grew (the surrogate's squares) is "
        "written into datasets of the old lengths",
        (("                or (held[key].shape, held[key].dtype) != shape_dtype\n",
          "                or False\n"),),
    ),
    Mutant(
        "state_checksums_not_compared", "plantgrowth/runner/h5_blocks.py", "missing check",
        "a state file's CRC-32s read and not compared with its rows' bytes: a file that a "
        "machine crash left holding some of an older step's pages is resumed from",
        (("        zlib.crc32(data[start * row : stop * row]) == crc\n",
          "        zlib.crc32(data[start * row : stop * row]) == crc or True\n"),),
    ),
    Mutant(
        "state_steps_kept_after_a_write", "plantgrowth/runner/output.py", "missing check",
        "the saved steps a resume found kept after the next write: the files' steps and "
        "checksums asked again are those of before the write",
        (("        self._offered = None\n        if self.comm.rank == 0:\n",
          "        if self.comm.rank == 0:\n"),),
    ),
    Mutant(
        "grid_square_keys_collide", "plantgrowth/unitcell/angle_surplus.py", "wrong index",
        "the angle grids' square keys one row too narrow: squares in neighbouring rows of the "
        "stretch grid share a key, so queries are given another square's corners",
        (("    width = int(cells[:, 1].max() - low[1]) + 1\n",
          "    width = int(cells[:, 1].max() - low[1])\n"),),
    ),
)  # fmt: skip


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--list", action="store_true", help="list the mutants and exit")
    parser.add_argument(
        "--only", action="append", metavar="NAME", help="run this mutant (repeatable)"
    )
    parser.add_argument(
        "--workdir", type=Path, default=DEFAULT_WORKDIR,
        help=f"scratch directory for the tree and its venv (default {DEFAULT_WORKDIR})",
    )  # fmt: skip
    parser.add_argument("--output", type=Path, default=OUTPUT, help="the JSON file written")
    parser.add_argument(
        "--skip-baseline", action="store_true", help="do not run the unmutated suite first"
    )
    parser.add_argument("--timeout", type=float, default=RUN_TIMEOUT, help="seconds per run")
    parser.add_argument(
        "--tests", nargs="+", default=SUITE, metavar="PATH",
        help="test files to run the mutants against (default: the whole suite, tests)",
    )  # fmt: skip
    args = parser.parse_args(argv)
    names = [m.name for m in MUTANTS]
    unknown = sorted(set(args.only or ()) - set(names))
    if unknown:
        parser.error(f"unknown mutant(s) {', '.join(unknown)}; --list shows the names")
    return args


def git(*args: str) -> str:
    return subprocess.run(
        ["git", "-C", str(REPO), *args], check=True, capture_output=True, text=True
    ).stdout.strip()


def export_tree(tree: Path) -> str:
    """``git archive HEAD`` into ``tree`` (emptied first); returns the commit hash."""
    commit = git("rev-parse", "HEAD")
    if git("status", "--porcelain", "--untracked-files=no"):
        print("note: the working tree has uncommitted changes; the study tests HEAD " + commit)
    if tree.exists():
        shutil.rmtree(tree)
    tree.mkdir(parents=True)
    archive = subprocess.run(
        ["git", "-C", str(REPO), "archive", "--format=tar", commit],
        check=True, capture_output=True,
    )  # fmt: skip
    subprocess.run(["tar", "-x", "-C", str(tree)], input=archive.stdout, check=True)
    return commit


def make_venv(venv: Path, tree: Path) -> Path:
    """The copy's venv: system site packages, the copy in editable mode, meshio (version from
    the copy's scripts/install.sh) and the Jupyter kernel "plantgrowth" as install.sh makes it.
    Returns its python."""
    python = venv / "bin" / "python"
    if not python.exists():
        subprocess.run(
            ["/usr/bin/python3", "-m", "venv", "--system-site-packages", str(venv)], check=True
        )
    pip = [str(python), "-m", "pip", "install", "--quiet", "--disable-pip-version-check"]
    subprocess.run([*pip, "--no-build-isolation", "--no-deps", "-e", str(tree)], check=True)
    version = re.search(
        r'^MESHIO_VERSION="([^"]+)"', (tree / "scripts/install.sh").read_text(), re.M
    )
    probe = [str(python), "-c", f"import meshio; assert meshio.__version__ == '{version[1]}'"]
    if subprocess.run(probe, capture_output=True).returncode != 0:
        subprocess.run([*pip, f"meshio=={version[1]}"], check=True)
    kernel = venv / "share/jupyter/kernels/plantgrowth/kernel.json"
    if not kernel.exists():  # tests/test_tutorial.py runs the tutorial in it (install.sh, 3c)
        install = ["-m", "ipykernel", "install", "--sys-prefix", "--name", "plantgrowth",
                   "--display-name", "Python (plantgrowth)"]  # fmt: skip
        env = {**os.environ, "PYDEVD_DISABLE_FILE_VALIDATION": "1"}
        subprocess.run([str(python), "-Xfrozen_modules=off", *install, "--env",
                        "PYDEVD_DISABLE_FILE_VALIDATION", "1"], check=True, env=env)  # fmt: skip
    if not (venv / "bin" / "plantgrowth").exists():
        raise SystemExit(f"the venv {venv} has no plantgrowth script after pip install -e")
    return python


def check_patterns(read, mutants: list[Mutant]) -> None:
    """Every replacement of every mutant matches its pristine file (``read(file)``) exactly
    once; stops the study otherwise."""
    problems = []
    for m in mutants:
        text = read(m.file)
        for old, _ in m.replacements:
            count = text.count(old)
            if count != 1:
                problems.append(f"{m.name}: {old!r} occurs {count} times in {m.file}")
    if problems:
        raise SystemExit("mutant patterns out of date:\n  " + "\n  ".join(problems))


def apply(tree: Path, mutant: Mutant) -> None:
    path = tree / mutant.file
    text = path.read_text()
    for old, new in mutant.replacements:
        assert text.count(old) == 1, (mutant.name, old)
        text = text.replace(old, new)
    path.write_text(text)


FAILURE = re.compile(r"^(FAILED|ERROR) (\S+)", re.M)


def run_suite(
    python: Path, tree: Path, basetemp: Path, log: Path, timeout: float, tests: list[str]
) -> dict:
    """The default serial suite (or its ``tests``) with -x in ``tree``; returns outcome, killer,
    seconds."""
    command = [str(python), *PYTEST_ARGS, *tests, "-rfE", f"--basetemp={basetemp}"]
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PATH"] = f"{python.parent}{os.pathsep}{env.get('PATH', '')}"
    start = time.perf_counter()
    with open(log, "w") as out:
        process = subprocess.Popen(
            command, cwd=tree, env=env, stdout=out, stderr=subprocess.STDOUT,
            start_new_session=True,  # its own process group: a timeout ends mpirun children too
        )  # fmt: skip
        try:
            returncode = process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
            returncode = None
    seconds = round(time.perf_counter() - start, 1)
    text = log.read_text()
    failure = FAILURE.search(text)
    last = text.strip().splitlines()[-1] if text.strip() else ""
    if returncode is None:
        return {"outcome": "timeout", "killed_by": None, "seconds": seconds, "summary": last}
    if returncode == 0:
        return {"outcome": "passed", "killed_by": None, "seconds": seconds, "summary": last}
    killer = failure[2] if failure else f"pytest exit code {returncode} (no failing test named)"
    return {"outcome": "failed", "killed_by": killer, "seconds": seconds, "summary": last}


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    chosen = [m for m in MUTANTS if not args.only or m.name in args.only]
    assert all(m.category in CATEGORIES for m in MUTANTS)
    assert len({m.name for m in MUTANTS}) == len(MUTANTS)
    if args.list:
        check_patterns(lambda name: git("show", f"HEAD:{name}") + "\n", MUTANTS)
        width = max(len(m.name) for m in MUTANTS)
        for m in MUTANTS:
            print(f"{m.name:{width}}  {m.file:30}  {m.category:24}  {m.description}")
        print(f"{len(MUTANTS)} mutants; every pattern matches HEAD exactly once")
        return 0
    workdir = args.workdir.resolve()
    tree, logs, basetemp = workdir / "tree", workdir / "logs", workdir / "pytest-tmp"
    start = time.perf_counter()
    commit = export_tree(tree)
    check_patterns(lambda name: (tree / name).read_text(), chosen)
    python = make_venv(workdir / "venv", tree)
    logs.mkdir(parents=True, exist_ok=True)
    command = " ".join(["python", *map(shlex.quote, PYTEST_ARGS + args.tests)])
    print(f"commit {commit}; tree {tree}; logs {logs}\nsuite: {command}", flush=True)

    baseline = None
    if not args.skip_baseline:
        baseline = run_suite(
            python, tree, basetemp, logs / "baseline.log", args.timeout, args.tests
        )
        print(f"baseline: {baseline['outcome']} in {baseline['seconds']} s", flush=True)
        if baseline["outcome"] != "passed":
            print(f"the unmutated suite does not pass: see {logs / 'baseline.log'}")
            return 1

    pristine = {m.file: (tree / m.file).read_text() for m in chosen}
    results = []
    for i, mutant in enumerate(chosen, start=1):
        for name, text in pristine.items():
            (tree / name).write_text(text)
        apply(tree, mutant)
        result = run_suite(
            python, tree, basetemp, logs / f"{mutant.name}.log", args.timeout, args.tests
        )
        killed = result["outcome"] in ("failed", "timeout")
        results.append(
            {
                "name": mutant.name,
                "file": mutant.file,
                "category": mutant.category,
                "description": mutant.description,
                "killed": killed,
                "killed_by": result["killed_by"]
                or ("timeout" if result["outcome"] == "timeout" else None),
                "seconds": result["seconds"],
                "commit": commit,
                "tests": args.tests,
            }
        )
        status = f"killed by {results[-1]['killed_by']}" if killed else "SURVIVED"
        print(f"[{i}/{len(chosen)}] {mutant.name}: {status} ({result['seconds']} s)", flush=True)
    for name, text in pristine.items():
        (tree / name).write_text(text)

    total = round(time.perf_counter() - start, 1)
    write_results(args.output, commit, command, baseline, results, args.only is not None, total)
    survivors = [r["name"] for r in results if not r["killed"]]
    print(f"{len(results) - len(survivors)} of {len(results)} mutants killed in {total} s")
    if survivors:
        print("survivors: " + ", ".join(survivors))
    print(f"written: {args.output}")
    return 1 if survivors else 0


def write_results(
    path: Path,
    commit: str,
    command: str,
    baseline: dict | None,
    results: list[dict],
    merge: bool,
    wall_seconds: float,
) -> None:
    """Write (or, for a subset run, update) the JSON, mutants in the order of MUTANTS.
    ``wall_seconds``: this invocation's wall time (export, venv, baseline and mutant runs)."""
    old = json.loads(path.read_text()) if merge and path.is_file() else {}
    entries = {r["name"]: r for r in old.get("mutants", [])}
    entries.update({r["name"]: r for r in results})
    order = [m.name for m in MUTANTS]
    mutants = [entries[name] for name in order if name in entries]
    data = {
        "description": "physics mutants against the default serial CI suite (issue 8); "
        "killed_by is the first failing test (pytest -x)",
        "command": "python scripts/studies/mutation_study.py",
        "suite": command,
        "commit": commit,
        "baseline": old.get("baseline") if baseline is None else {"commit": commit, **baseline},
        "n_mutants": len(mutants),
        "n_killed": sum(m["killed"] for m in mutants),
        "survivors": [m["name"] for m in mutants if not m["killed"]],
        "mutant_seconds": round(sum(m["seconds"] for m in mutants), 1),
        "wall_seconds_last_invocation": wall_seconds,
        "mutants": mutants,
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2) + "\n")


if __name__ == "__main__":
    sys.exit(main())
