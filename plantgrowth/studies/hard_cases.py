"""Hard-case stability criteria of the coupled macro model (docs/model.md sections 4-5).

:func:`evaluate` runs one scene through :func:`plantgrowth.runner.timeloop.run_model` with a
per-step callback and returns the criterion values, a pass/fail per criterion and the wall time. The
callback reads only public attributes of :class:`~plantgrowth.models.macro.model.MacroModel`
(E_hom: the fine cells' values the step's solve used). Scenes are plain TOML dictionaries here,
so that the cheap (CI) and refined variants are derived from one file: :func:`cheap`,
:func:`refined`, :func:`with_overrides`.

Criteria (all collective over the mesh's communicator):

- ``finite``: no NaN/Inf in u, Fg, G, sigma_hom, E_hom or the summary rows;
- ``det_Fg``: ``min det Fg / det Fg0 >= 1 - 1e-12`` over cells and steps (G >= 0 is growth);
- ``E_hom_spd``: the 3x3 Voigt matrix of E_hom is symmetric with a positive smallest
  eigenvalue at every coarse node and step;
- ``solver``: PETSc's converged reason > 0 and the true relative residual
  <= :data:`plantgrowth.models.diagnostics.RESIDUAL_BOUND` (1e-8) at every step;
- ``no_inversion``: ``det(I + grad u) > 0`` in every cell at every step;
- ``G_in_clamp``: every component of G in [-M, M];
- ``growth_bound``: ``ln sigma_max(Fg Fg0^-1) / t <= 2 M`` (the largest eigenvalue of a 2x2
  symmetric matrix with components in [-M, M] is at most 2 M). The sharper per-cell bound
  ``ln sigma_max(Fg Fg0^-1) <= sum_k dt lambda_max(G_k)`` holds for ``euler``/``exp``, whose G
  is constant over a step; it is reported (``growth_excess``), not judged, since ``adaptive``
  re-evaluates G inside the step.

Reported, not judged: ``max_elastic_strain``, the largest principal magnitude of the elastic
strain (eps_el, or Ee with finite kinematics) over the cells and completed steps; after a stop
by loss of ellipticity, ``unstable_state`` (:func:`unstable_state`).
"""

from __future__ import annotations

import copy
import csv
import math
import re
import time
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI

from plantgrowth.base.errors import RunError
from plantgrowth.models import growth, stability
from plantgrowth.models.diagnostics import RESIDUAL_BOUND
from plantgrowth.models.macro.model import MacroModel
from plantgrowth.models.macro.problem import rectangle_mesh
from plantgrowth.runner.output import prepare_directory
from plantgrowth.runner.timeloop import run_model
from plantgrowth.scene import Scene, parse_scene

DET_TOLERANCE = 1e-12
"""Round-off allowed below det Fg / det Fg0 = 1 (a product of ~1e3 exp factors, ~1e-13)."""
REFINEMENT_TOLERANCE = 0.02
"""Accepted relative change of final area and mean growth rate under one refinement.

One refinement halves tissue.h (P1 macro error O(h^2) in u, O(h) in grad u per cell) and adds one
P2 element across the cell walls (E_hom changes by the cell-problem discretisation error: ~0.5%
for E1 from resolution 2 to 3 on the reference cell). Both enter the growth rate linearly, so a
change of a few 0.1% is the expected size; 2% leaves a margin of ~4x for thin walls and
gradients, and is still well below the effects the hard cases look at (Euler's 5% at dt = 30).
"""
GROWTH_BOUND_SLACK = 1e-12
"""Round-off allowed above the growth bounds (logarithms of O(1) numbers)."""

CRITERIA = (
    "finite", "det_Fg", "E_hom_spd", "solver", "no_inversion", "G_in_clamp", "growth_bound",
)  # fmt: skip
DT_STUDY = {"reference_dt": 0.25, "reference_integrator": "adaptive", "dts": (1.0, 10.0, 30.0)}
"""Large-step study: final area versus a dt = 0.25 'adaptive' run, for each dt and integrator."""


# --- scene dictionaries ---------------------------------------------------------------------------


def read_scene_data(path: str | Path) -> dict[str, Any]:
    """The raw TOML tables of a scene file (validated later by :func:`to_scene`)."""
    with open(path, "rb") as f:
        return tomllib.load(f)


def with_overrides(data: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    """A copy of ``data`` with the tables of ``overrides`` merged in (one level deep)."""
    out = copy.deepcopy(data)
    for key, value in overrides.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = {**out[key], **copy.deepcopy(value)}
        else:
            out[key] = copy.deepcopy(value)
    return out


def refined(data: dict[str, Any]) -> dict[str, Any]:
    """One refinement: tissue.h halved and accuracy.cell_resolution + 1."""
    scene = to_scene(data)
    return with_overrides(
        data,
        {
            "tissue": {"h": scene.tissue.h / 2},
            "accuracy": {"cell_resolution": scene.accuracy.cell_resolution + 1},
        },
    )


def cheap(data: dict[str, Any], t_max: float | None = None, dt: float | None = None) -> dict:
    """The CI variant: h = 0.35, H = 1 (2 for a field scene), cell_resolution 1, output u only.

    ``t_max`` (and ``dt``) shorten the run; ``t_max`` must stay a whole number of steps.
    """
    scene = to_scene(data)
    constant = all(f.is_constant for f in scene.parameter_fields().values())
    time_table = {} if t_max is None else {"t_max": t_max}
    if dt is not None:
        time_table["dt"] = dt
    return with_overrides(
        data,
        {
            "tissue": {"h": 0.35, "H": 1.0 if constant else 2.0},
            "accuracy": {"cell_resolution": 1},
            "output": {"fields": ["u"]},
            "time": time_table,
        },
    )


def to_scene(data: dict[str, Any], source: str = "<scene>") -> Scene:
    """Validate a scene dictionary (SceneError on bad input)."""
    return parse_scene(data, source)


# --- the per-step observer ------------------------------------------------------------------------


class _Observer:
    """Accumulates the criterion values over the steps of one run (local, then reduced)."""

    def __init__(self, scene: Scene) -> None:
        self.dt = scene.time.dt
        self.Fg0_inv = np.linalg.inv(np.array(scene.growth.Fg0, dtype=float))
        self.det_Fg0 = float(np.linalg.det(np.array(scene.growth.Fg0, dtype=float)))
        self.clamp = scene.growth.clamp
        self.finite = True
        self.det_ratio_min = math.inf
        self.E_min_eig = math.inf
        self.E_asym_max = 0.0
        self.reason_min = 2**31
        self.det_def_min = math.inf
        self.G_abs_max = 0.0
        self.G_lambda_max = -math.inf
        self.G_lambda_min = math.inf  # < 0: clipping made G indefinite (shrinks a direction)
        self.log_rate_max = -math.inf  # max ln sigma_max(Fg Fg0^-1) / t, t > 0
        self.excess_max = -math.inf  # max ln sigma_max(Fg Fg0^-1) - int lambda_max(G) dt
        self.anisotropy_max = -math.inf  # max sigma_max / sigma_min of Fg
        self.E1_mean_step0 = math.nan
        self.strain_max = -math.inf  # stays so if no step completes
        self.integral = None  # per owned cell: sum_k dt lambda_max(G_k) up to the current step

    def __call__(self, step: int, model: MacroModel) -> None:
        problem, n = model.problem, model.problem.n_owned
        Fg_all = problem.cell_values(problem.Fg).reshape(-1, 2, 2)
        Fg = Fg_all[:n]
        G = problem.cell_values(model.out.G).reshape(-1, 2, 2)[:n]
        sigma = problem.cell_values(model.out.sigma).reshape(-1, 2, 2)[:n]
        grad_u = problem.grad_u()[:n]
        u = problem.u.x.array
        C = problem.cell_values(problem.C).reshape(-1, 3, 3)[:n]  # E_hom of the step's solve
        arrays = (Fg, G, sigma, grad_u, u, C)
        self.finite &= all(bool(np.all(np.isfinite(a))) for a in arrays)
        if not self.finite:
            return  # the model's own checks stop the run at the end of this step
        C_sym = 0.5 * (C + np.swapaxes(C, 1, 2))
        eig = np.linalg.eigvalsh(C_sym)
        self.E_min_eig = min(self.E_min_eig, float(eig[:, 0].min()))
        asym = np.abs(C - np.swapaxes(C, 1, 2)).max() / np.abs(C).max()
        self.E_asym_max = max(self.E_asym_max, float(asym))
        if step == 0:  # area-weighted over the tissue
            E1 = C[:, 0, 0] - C[:, 0, 1] ** 2 / C[:, 1, 1]
            total = model.comm.allreduce(float(np.sum(problem.areas * E1)), op=MPI.SUM)
            self.E1_mean_step0 = total / problem.total_area
        self.reason_min = min(self.reason_min, int(problem.ksp.getConvergedReason()))
        if n == 0:
            return
        self.det_ratio_min = min(self.det_ratio_min, float(np.linalg.det(Fg).min()) / self.det_Fg0)
        self.det_def_min = min(self.det_def_min, float(np.linalg.det(np.eye(2) + grad_u).min()))
        kinematics = growth.green_lagrange_strain if problem.finite else growth.elastic_strain
        eps = kinematics(grad_u, Fg)
        self.strain_max = max(self.strain_max, float(np.abs(np.linalg.eigvalsh(eps)).max()))
        self.G_abs_max = max(self.G_abs_max, float(np.abs(G).max()))
        lam = np.linalg.eigvalsh(0.5 * (G + np.swapaxes(G, 1, 2)))
        lam_G = lam[:, -1]
        self.G_lambda_max = max(self.G_lambda_max, float(lam_G.max()))
        self.G_lambda_min = min(self.G_lambda_min, float(lam[:, 0].min()))
        singular = np.linalg.svd(Fg, compute_uv=False)
        ratio = float((singular[:, 0] / singular[:, 1]).max())
        self.anisotropy_max = max(self.anisotropy_max, ratio)
        stretch = np.log(np.linalg.svd(Fg @ self.Fg0_inv, compute_uv=False)[:, 0])
        if self.integral is None:
            self.integral = np.zeros(n)
        if step > 0:
            self.log_rate_max = max(self.log_rate_max, float(stretch.max()) / (step * self.dt))
        self.excess_max = max(self.excess_max, float((stretch - self.integral).max()))
        self.integral = self.integral + self.dt * lam_G  # the bound for the next step's Fg

    def reduce(self, comm: MPI.Comm) -> dict[str, float]:
        """Criterion values over all ranks (every rank gets the same dictionary)."""
        MIN, MAX = MPI.MIN, MPI.MAX
        return {
            "finite": bool(comm.allreduce(self.finite, op=MPI.LAND)),
            "det_Fg_min_ratio": comm.allreduce(self.det_ratio_min, op=MIN),
            "E_hom_min_eig": comm.allreduce(self.E_min_eig, op=MIN),
            "E_hom_asym_max": comm.allreduce(self.E_asym_max, op=MAX),
            "E1_mean_step0": self.E1_mean_step0,  # the same on every rank
            "solve_reason_min": comm.allreduce(self.reason_min, op=MIN),
            "det_deformation_min": comm.allreduce(self.det_def_min, op=MIN),
            "G_abs_max": comm.allreduce(self.G_abs_max, op=MAX),
            "G_lambda_max": comm.allreduce(self.G_lambda_max, op=MAX),
            "G_lambda_min": comm.allreduce(self.G_lambda_min, op=MIN),
            "growth_log_rate_max": comm.allreduce(self.log_rate_max, op=MAX),
            "growth_excess_max": comm.allreduce(self.excess_max, op=MAX),
            "anisotropy_max": comm.allreduce(self.anisotropy_max, op=MAX),
            "max_elastic_strain": comm.allreduce(self.strain_max, op=MAX),
        }


# --- evaluation -----------------------------------------------------------------------------------


def _judge(values: dict[str, Any], clamp: float) -> dict[str, bool]:
    def finite(x):
        return math.isfinite(x)

    v = values
    return {
        "finite": v["finite"] and v["summary_finite"],
        "det_Fg": finite(v["det_Fg_min_ratio"]) and v["det_Fg_min_ratio"] >= 1.0 - DET_TOLERANCE,
        "E_hom_spd": v["E_hom_min_eig"] > 0.0 and v["E_hom_asym_max"] <= 1e-8,
        "solver": v["solve_reason_min"] > 0 and v["residual_max"] <= RESIDUAL_BOUND,
        "no_inversion": finite(v["det_deformation_min"]) and v["det_deformation_min"] > 0.0,
        "G_in_clamp": v["G_abs_max"] <= clamp,
        "growth_bound": v["growth_log_rate_max"] <= 2.0 * clamp + GROWTH_BOUND_SLACK,
    }


def evaluate(scene: Scene, outdir: Path, comm: MPI.Comm) -> dict[str, Any]:
    """Run a macro scene in ``outdir`` with the stability observer; never raises RunError.

    Returns:
        The criterion values (see the module docstring), ``criteria`` (name -> passed),
        ``passed`` (all criteria and the run completed), ``error`` (the RunError message or
        None), ``steps``/``t_reached`` (last completed step), ``area_final``,
        ``growth_rate_final`` (reference-area mean of tr G at the last step), ``seconds``.
        Identical on every rank.
    """
    outdir = Path(outdir)
    prepare_directory(outdir, comm)
    start = time.perf_counter()
    model = MacroModel(scene, rectangle_mesh(scene, comm), comm)
    observer = _Observer(scene)
    error = None
    try:
        summary = run_model(model, scene, outdir, comm, on_step=observer)
    except RunError as err:  # raised on every rank (diagnostics.stop_if is collective)
        error, summary = str(err), None
    unstable = None
    if error is not None and "loss of ellipticity" in error:
        unstable = unstable_state(model)
    seconds = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    if summary is None:  # the rows of completed steps are in summary.csv; re-read them
        summary = _read_summary(outdir / "summary.csv", comm)
    values = observer.reduce(comm)
    last = summary[-1] if summary else {}
    values.update(
        summary_finite=all(math.isfinite(float(x)) for row in summary for x in row.values()),
        residual_max=max((float(r["residual"]) for r in summary), default=math.nan),
        steps=int(last.get("step", -1)),
        n_steps=scene.time.n_steps,
        t_reached=float(last.get("t", math.nan)),
        area_initial=float(summary[0]["area"]) if summary else math.nan,
        area_final=float(last.get("area", math.nan)),
        growth_rate_final=float(last.get("growth_rate_area", math.nan)),
        clamp=scene.growth.clamp,
        growth_rate_bound=2.0 * scene.growth.clamp,
        residual_bound=RESIDUAL_BOUND,
        error=error,
        unstable_state=unstable,
        seconds=seconds,
    )
    criteria = _judge(values, scene.growth.clamp)
    values["criteria"] = criteria
    values["passed"] = error is None and all(criteria.values())
    return values


def unstable_state(model: MacroModel) -> dict[str, Any]:
    """Collective: the state where the law is least elliptic (the current step): its place, the
    normalised acoustic eigenvalue, the principal elastic strains (eps_el or Ee) and the
    principal values of the walls' stress ``S_w = E_hom Ee + K_hom P1`` (the stability
    criterion's, docs/model.md section 10) over the mean shear modulus, the direction of its
    smaller principal value (degrees from x1, in [0, 180)), and the bounding box of the
    non-elliptic cells (reference coordinates)."""
    p, n = model.problem, model.problem.n_owned
    values = p.stability_values(screened=False)[:n]
    Fg = p.cell_values(p.Fg).reshape(-1, 2, 2)[:n]
    kinematics = growth.green_lagrange_strain if p.finite else growth.elastic_strain
    eps = kinematics(p.grad_u()[:n], Fg)
    _, walls, C = (x[:n] for x in p.walls_state())
    mu = stability.mean_shear_modulus(C)
    mine = None
    if n:
        i = int(np.argmin(values))
        mine = (float(values[i]), {
            "x": [float(v) for v in p.midpoints[i, :2]], "stability": float(values[i]),
            "strain": np.linalg.eigvalsh(eps[i]).tolist(),
            "wall_stress_over_mu": (np.linalg.eigvalsh(walls[i]) / mu[i]).tolist(),
            "compression_angle": _angle(np.linalg.eigh(walls[i])[1][:, 0]),
        })  # fmt: skip
    worst = min((m for m in model.comm.allgather(mine) if m is not None), key=lambda m: m[0])[1]
    bad = np.concatenate(model.comm.allgather(p.midpoints[:n, :2][values < 0.0]))
    lo, hi = (bad.min(axis=0), bad.max(axis=0)) if len(bad) else ([math.nan] * 2, [math.nan] * 2)
    return dict(worst, region=[float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])])


def _angle(v: np.ndarray) -> float:
    """Whole degrees from x1 in [0, 180)."""
    return float(round(float(np.degrees(np.arctan2(v[1], v[0])))) % 180)


def _read_summary(path: Path, comm: MPI.Comm) -> list[dict[str, float]]:
    rows = None
    if comm.rank == 0:
        with open(path, newline="") as f:
            rows = [{k: float(v) for k, v in row.items() if v != ""} for row in csv.DictReader(f)]
    return comm.bcast(rows, root=0)


def relative_change(a: float, b: float) -> float:
    """``|b - a| / |a|`` (NaN if either is not finite)."""
    if not (math.isfinite(a) and math.isfinite(b)) or a == 0.0:
        return math.nan
    return abs(b - a) / abs(a)


def refinement_changes(base: dict[str, Any], fine: dict[str, Any]) -> dict[str, Any]:
    """Relative change of final area and final mean growth rate between two evaluations."""
    area = relative_change(base["area_final"], fine["area_final"])
    rate = relative_change(base["growth_rate_final"], fine["growth_rate_final"])
    E1 = relative_change(base["E1_mean_step0"], fine["E1_mean_step0"])
    ok = math.isfinite(area) and math.isfinite(rate) and max(area, rate) < REFINEMENT_TOLERANCE
    return {"area": area, "growth_rate": rate, "E1_step0": E1, "tolerance": REFINEMENT_TOLERANCE,
            "passed": ok}  # fmt: skip


# --- stops ---------------------------------------------------------------------------------------


def parse_stop(error: str | None) -> dict | None:
    """Where and why a run stopped, from the RunError message (or a step warning): ``"step N,
    t = T: what at x = (x1, x2) (n place(s) on this rank); likely cause: ..."`` or ``"step N,
    t = T: the tissue is compressed ... (loss of ellipticity: ... on F% of the tissue) at x1 =
    a, x2 = b, t = T; ..."`` (``after step N``: while advancing the growth from t = T, i.e. in
    (T, T + dt], inside the sub-steps for 'adaptive'). ``kind``: the cause class."""
    if not error:
        return None
    m = re.match(r"(after )?step (\d+), t = ([^:]+): (.*)", error, re.S)
    if m is None:
        return {"message": error, "cause": error[:80], "kind": "other"}
    rest = m.group(4)
    x = re.search(r" at x = \(([^)]*)\)", rest)
    x = x or re.search(r" at x1 = ([^,]*), x2 = ([^,]*),", rest)
    places = re.search(r"\((\d+) place\(s\)", rest)
    fraction = re.search(r"on ([0-9.e+-]+)% of the tissue", rest)
    likely = rest.split("likely cause: ", 1)[1] if "likely cause: " in rest else None
    kind = "other"
    if "loss of ellipticity" in rest:
        kind = "loss of ellipticity"
    elif "inverted" in rest:
        kind = "element inverted"
    coords = x.group(1).split(",") if x and x.lastindex == 1 else (x.groups() if x else None)
    return {
        "step": int(m.group(2)),
        "t": float(m.group(3)),
        "during_advance": bool(m.group(1)),
        "kind": kind,
        "cause": rest.split(" at x = ")[0].split(";")[0].split(" (loss of")[0],
        "x": [float(v) for v in coords] if coords else None,
        "places": int(places.group(1)) if places else None,
        "nonelliptic_area_fraction": float(fraction.group(1)) / 100 if fraction else None,
        "likely_cause": likely,
    }


def run_status(r: dict | None) -> str:
    """A run's outcome in a few words: ``pass``, or ``FAIL (...)`` with where and why it stopped
    or which criteria failed (docs/stability.md's tables, the ``unexpected`` list)."""
    if r is None:
        return "-"
    if r["passed"]:
        return "pass"
    failed = [k for k, ok in (r.get("criteria") or {}).items() if not ok]
    if r.get("error"):
        stop = r.get("stop") or parse_stop(r["error"])
        if stop and "step" in stop:
            cause = stop["kind"] if stop["kind"] != "other" else stop["cause"][:40]
            return f"FAIL ({stop_at(stop)}: {cause})"
        return f"FAIL ({r['error'][:60]})"
    return f"FAIL ({', '.join(failed)})"


def stop_at(stop: dict | None) -> str:
    """Where a run stopped: ``step 13, t = 13``, or ``after step 10, t = 10`` for a failure
    inside the growth advance from t = 10."""
    if not stop or "step" not in stop:
        return "-"
    if stop["during_advance"]:
        return f"after step {stop['step']}, t = {stop['t']:g}"
    return f"step {stop['step']}, t = {stop['t']:g}"
