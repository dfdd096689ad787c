"""The growth time loop shared by the macro and micro models (paper Algorithm 1's outer loop).

A model owns its mesh, its growth units (fine cells for macro, biological cells for micro) and
its output functions; the loop owns time: per step it asks the model for the growth rate G at
the current Fg, checks the step, writes it, and advances ``dFg/dt = G Fg``.
"""

from __future__ import annotations

import logging
import signal
import time
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from mpi4py import MPI

from plantgrowth.base.errors import Interrupted, RunError
from plantgrowth.models import growth
from plantgrowth.models.micro.water import water_columns
from plantgrowth.models.regions import region_columns
from plantgrowth.models.step import GrowthModel
from plantgrowth.runner.output import (
    FieldSeries,
    Schedule,
    StateFile,
    SummaryWriter,
    last_summary_step,
)
from plantgrowth.runner.step_warnings import MAX_LOAD_IMBALANCE, StepWarnings
from plantgrowth.scene import Scene

log = logging.getLogger("plantgrowth")

SUMMARY_COLUMNS = [
    "step", "t", "area", "growth_rate_11", "growth_rate_22", "growth_rate_area",
    "u1_max", "u2_max", "det_Fg_min", "n_cell_solves", "residual",
    "substeps", "seconds", "seconds_cells", "seconds_solve", "seconds_growth", "seconds_io",
    "nonelliptic_area_fraction", "singular_points", "elastic_strain_max",
    "elastic_strain_max_x1", "elastic_strain_max_x2",
]  # fmt: skip
NEWTON_COLUMNS = ["newton_iterations", "newton_residual"]
"""Appended to SUMMARY_COLUMNS for ``kinematics = "finite"`` (linear runs keep those above)."""


LOAD_COLUMNS = ["load_imbalance"]
"""Appended for a scene with loads that only the pinned point holds along x1 (no held edge holds
u1: Scene.pinned): the net x1 force of the applied loads over the largest edge force, in the
configuration the forms apply them (plantgrowth.models.macro.edge_loads)."""


HELD_COLUMNS = ["held_force_1", "held_force_2"]
"""Appended for a scene with held edges (``[supports]``): the total force they exert on the tissue
(plantgrowth.models.macro.supports)."""


FIBRE_COLUMNS = ["fibre_order", "fibre_angle_mean"]
"""Appended for a scene with a fibre director (fibred walls or ``[feedback]``): the director
field's order and mean angle (plantgrowth.models.fibres.fibre_statistics)."""


def summary_columns(scene: Scene) -> list[str]:
    """The columns of a scene's summary.csv."""
    newton = NEWTON_COLUMNS if scene.kinematics == "finite" else []
    loads = LOAD_COLUMNS if scene.loads and scene.pinned else []
    held = HELD_COLUMNS if scene.supports else []
    fibres = FIBRE_COLUMNS if scene.has_director else []
    water = water_columns(scene.hydraulics)
    regions = region_columns(scene.regions, scene.hydraulics is not None)
    return SUMMARY_COLUMNS + newton + loads + held + fibres + regions + water


@contextmanager
def interrupt_at_step_end():
    """While active, SIGINT only sets a flag that the loop reads at the end of a step."""
    flag = {"set": False}

    def handler(signum, frame):
        flag["set"] = True

    try:
        previous = signal.signal(signal.SIGINT, handler)
    except ValueError:  # not the main thread: leave SIGINT alone
        previous = None
    try:
        yield flag
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


MIN_SUBSTEP = 2.0**-12
"""Smallest sub-step of the adaptive integrator, as a fraction of dt."""


def advance_adaptive(
    model: GrowthModel, Fg: np.ndarray, G: np.ndarray, dt: float, tol: float, comm: MPI.Comm
) -> tuple[np.ndarray, int, int]:
    """``dFg/dt = G(Fg) Fg`` over dt by exponential steps with step-doubling error control.

    Each sub-step h is taken once whole (``expm(h G0) Fg``) and as two halves (the second with
    G re-evaluated at the midpoint state: a new solve); the halves are kept when the two results
    differ by at most ``tol`` relative (max over growth units), else h is halved. Re-evaluating
    G inside the step is what keeps the coupled growth-elasticity loop stable for large dt,
    where the explicit schemes (``euler``, ``exp``) oscillate. The model's own state (the water)
    follows the kept halves: the midpoint's solve advances it by h/2 from the last kept state
    and the one at the sub-step's end by h/2 more (the step's last: the loop's next solve); a
    rejected sub-step's midpoint is undone (:meth:`GrowthModel.keep`). Returns (Fg, sub-steps,
    cell solves).
    """
    done, h, substeps, solves = 0.0, dt, 0, 0
    while done < dt * (1.0 - 1e-12):
        h = min(h, dt - done)
        whole = growth.advance(Fg, G, h, "exp")
        half = growth.advance(Fg, G, 0.5 * h, "exp")
        model.check_growth(half)
        model.substep(0.5 * h, dt - done - 0.5 * h)
        middle = model.step(half)
        two_halves = growth.advance(half, middle.G, 0.5 * h, "exp")
        solves += middle.n_cell_solves
        scale = np.maximum(np.linalg.norm(two_halves, axis=(1, 2)), 1e-300)
        local = np.linalg.norm(two_halves - whole, axis=(1, 2)) / scale
        error = comm.allreduce(float(local.max(initial=0.0)), op=MPI.MAX)
        model.keep(error <= tol)
        if error <= tol:
            Fg, done, substeps = two_halves, done + h, substeps + 1
            if done < dt * (1.0 - 1e-12):
                model.substep(0.5 * h, dt - done)
                model.check_growth(Fg)
                result = model.step(Fg)
                model.keep(True)
                G, solves = result.G, solves + result.n_cell_solves
            else:  # the loop's next solve ends the step
                model.substep(0.5 * h, 0.0)
            if error <= 0.25 * tol:
                h *= 2.0
        elif h > MIN_SUBSTEP * dt:
            h *= 0.5
        else:
            raise RunError(
                f"the adaptive integrator needs sub-steps below dt/{1 / MIN_SUBSTEP:g} "
                f"(local error {error:.3g} > tolerance {tol:g}); likely cause: the growth rate "
                "changes faster than the model can follow (check pressure, eta and clamp M)"
            )
    return Fg, substeps, solves


def run_model(
    model: GrowthModel,
    scene: Scene,
    outdir: Path,
    comm: MPI.Comm,
    n_steps: int | None = None,
    on_step: Callable[[int, GrowthModel], None] | None = None,
    resume: bool = False,
    label: str = "",
) -> list[dict]:
    """Run the growth loop of a scene; write its outputs (:mod:`plantgrowth.runner.output`) into
    ``outdir``: the fields at t = 0, every ``output.every``-th step and the last step, the state
    and a summary row after every step.

    Under growth law ``none`` there is no growth: a single static solve at t = 0. Implausible
    states are logged as warnings (:mod:`plantgrowth.runner.step_warnings`): a large elastic
    strain once per band it enters, an active clamp once per run.
    Args:
        n_steps: stop after this many steps (default: the scene's t_max / dt).
        on_step: called after each step's solve as ``on_step(step, model)``.
        resume: continue after the step of the state saved in ``outdir`` (a finished run is
            extended if ``n_steps`` is larger); later summary rows and fields are redone.
        label: what runs, for the progress lines (e.g. "Nx = 8, macro").
    Raises:
        RunError: a step failed (message names step, time, place, cause).
        Interrupted: SIGINT arrived; the loop stopped after the step it was in.
    """
    if n_steps is None:
        n_steps = scene.time.n_steps
    if scene.growth.law == "none":
        n_steps = 0
    dt = scene.time.dt
    state = StateFile(outdir, comm)
    last = _resume_point(state, outdir, comm) if resume else None
    schedule = Schedule(scene.output.every, n_steps)
    series = FieldSeries(outdir, model.output_space, model.outputs, schedule,
                         scene.output.precision, model.side_output, keep_until=last)  # fmt: skip
    summary = SummaryWriter(outdir / "summary.csv", summary_columns(scene), comm, keep_until=last)
    table = model.cell_table
    cells = None if table is None else SummaryWriter(
        outdir / "cells.csv", table.columns, comm, keep_until=last, schedule=schedule
    )  # fmt: skip
    substeps = [0, 0]  # sub-steps and extra cell solves of the advance that led to this step
    if last is None:
        Fg, first = model.initial_growth(), 0
    elif last >= n_steps:
        log.info("the run has already reached step %d (t = %g): nothing to do", last, last * dt)
        return []
    else:
        Fg, G = model.restore(state.read(last))
        Fg, substeps[0], substeps[1] = _advance(model, Fg, G, scene, comm)
        first = last + 1
        log.info("resuming after step %d (t = %g)", last, last * dt)
    rows = []
    # a resumed run warns only for strain bands its kept steps had not reached
    warnings = StepWarnings(
        scene.kinematics, summary.kept_max("elastic_strain_max"),
        summary.kept_max("nonelliptic_area_fraction"),
    )  # fmt: skip
    prefix = f"{label}: " if label else ""
    start = time.perf_counter()
    with interrupt_at_step_end() as interrupt:
        for step in range(first, n_steps + 1):
            t = step * dt
            t0 = time.perf_counter()
            try:
                result = model.step(Fg)
            except RunError as err:
                raise RunError(f"step {step}, t = {t:g}: {err}") from None
            if on_step is not None:
                on_step(step, model)
            t1 = time.perf_counter()
            if step in schedule:
                series.write(step, t)
                if cells is not None:
                    cells.write_rows(table.rows(step, t))
            model.end_step(dt)  # the state saved holds what the next step starts from
            snapshot = model.state(Fg, result.G)
            t2 = time.perf_counter()
            row = model.measures(Fg, result.G)
            row.update(step=step, t=t, n_cell_solves=result.n_cell_solves + substeps[1],
                       residual=result.residual, seconds=t2 - t0, seconds_io=t2 - t1,
                       substeps=substeps[0], newton_iterations=result.newton_iterations,
                       newton_residual=result.newton_residual, **result.seconds)  # fmt: skip
            if result.load_balance is not None:
                row["load_imbalance"] = result.load_balance.imbalance
            if result.held_force is not None:
                row.update(zip(HELD_COLUMNS, result.held_force, strict=True))
            if result.ellipticity is not None:
                row["nonelliptic_area_fraction"] = result.ellipticity.nonelliptic_area_fraction
                row["singular_points"] = len(result.ellipticity.singular)
            peak = result.elastic_strain
            row.update(elastic_strain_max=peak.value, elastic_strain_max_x1=peak.place[0],
                       elastic_strain_max_x2=peak.place[1])  # fmt: skip
            row = {k: comm.allreduce(v, op=MPI.MAX) if k.startswith("seconds") else v
                   for k, v in row.items()}  # fmt: skip
            # fields (and cell rows), row, state: a kill between them leaves the state one step
            # behind at most, and the resumed run redoes that step (its rows and fields)
            summary.write(row)
            state.write(step, t, snapshot)
            rows.append(row)
            for text in warnings.growth(step, t, row["growth_rate_area"], dt, scene.growth.law):
                log.warning("warning: %s%s", prefix, text)
            left = (time.perf_counter() - start) / (step + 1 - first) * (n_steps - step)
            newton = (
                f"  Newton {result.newton_iterations} it., residual {result.newton_residual:.1e}"
                if scene.kinematics == "finite"
                else ""
            )
            log.info(
                "%sstep %d/%d  t = %g  mean growth rate tr G = %.6g  cell solves %d%s  "
                "(%.1f s left)", prefix, step, n_steps, t, row["growth_rate_area"],
                row["n_cell_solves"], newton, left,
            )  # fmt: skip
            lost = result.ellipticity
            for text in warnings.singular_points(step, t, lost):
                log.warning("%ssingular point: %s", prefix, text)
            stop = scene.numerics.on_instability == "stop"
            if stop and lost is not None and lost.lost:
                raise RunError(
                    f"step {step}, t = {t:g}: {lost.describe(t)} (the run stops; "
                    'numerics.on_instability = "warn" goes on)'
                )
            for text in warnings.check(step, t, result):
                log.warning("warning: %s%s", prefix, text)
            balance = result.load_balance
            if balance is not None and balance.imbalance > MAX_LOAD_IMBALANCE:
                raise RunError(f"step {step}, t = {t:g}: {balance.describe()} (more than "
                               f"{MAX_LOAD_IMBALANCE:.0%}: the run stops)")  # fmt: skip
            if step < n_steps:
                if comm.allreduce(interrupt["set"], op=MPI.LOR):
                    raise Interrupted(step, t)
                try:
                    Fg, substeps[0], substeps[1] = _advance(model, Fg, result.G, scene, comm)
                    model.check_growth(Fg)
                except RunError as err:
                    raise RunError(f"after step {step}, t = {t:g}: {err}") from None
    return rows


def _resume_point(state: StateFile, outdir: Path, comm: MPI.Comm) -> int | None:
    """The last step with a saved state and a summary row (None: start again at t = 0)."""
    rows = comm.bcast(last_summary_step(outdir / "summary.csv"), root=0)
    saved = [s for s in state.steps() if rows is not None and s <= rows]
    if not saved:
        log.info("no saved state to continue from: the run starts again at t = 0")
        return None
    return saved[-1]


def _advance(
    model: GrowthModel, Fg: np.ndarray, G: np.ndarray, scene: Scene, comm: MPI.Comm
) -> tuple[np.ndarray, int, int]:
    """Fg after one step of the scene's integrator; (Fg, sub-steps, extra cell solves)."""
    t = scene.time
    if t.integrator == "adaptive":
        return advance_adaptive(model, Fg, G, t.dt, t.tolerance, comm)
    return growth.advance(Fg, G, t.dt, t.integrator), 1, 0
