"""One scene, run as ``plantgrowth run`` runs it: its fields checked where the run uses them, its
directory held, its model(s) built on the checked domain and driven by the time loop.

The checks (:mod:`plantgrowth.scene.places`) run once, on the domain the run then solves on, and
before anything is written: a bad scene leaves no file behind.
"""

from __future__ import annotations

import csv
import logging
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from mpi4py import MPI

from plantgrowth.base.errors import InputError, Interrupted, RunError
from plantgrowth.models.macro.domain import MacroDomain, macro_domain
from plantgrowth.models.macro.model import model_on
from plantgrowth.models.micro.model import MicroModel
from plantgrowth.runner.output import atomic_write_text, prepare_directory
from plantgrowth.runner.rundir import CLI_OPTIONS, Options, check_resumable, claim
from plantgrowth.runner.timeloop import run_model
from plantgrowth.scene import Scene
from plantgrowth.scene.places import (
    check_macro_places,
    check_micro_places,
    check_micro_tissue,
    needs_place_checks,
)
from plantgrowth.scene.plausibility import warn_about

log = logging.getLogger("plantgrowth")


def checked_domain(scene: Scene, comm: MPI.Comm, nx: int | None = None) -> MacroDomain | None:
    """Collective: the macro domain a run of ``scene`` solves on (None without a macro side),
    with the scene's fields checked at its places and at the micro tissue's cell centres.
    ``nx``: a micro-macro comparison at ``nx`` cells per row; else the scene's own model(s).

    Raises:
        SceneError: a field out of its range where the run uses it (the first place in
            (key, x1, x2) order, the same on every rank).
    """
    if nx is None and scene.model in ("micro", "both"):
        check_micro_tissue(scene)
    macro = nx is not None or scene.model in ("macro", "both")
    domain = macro_domain(scene, comm, nx) if macro else None
    if needs_place_checks(scene):
        if domain is not None:
            check_macro_places(domain.scene, *domain.places(), comm)
        if nx is not None or scene.model in ("micro", "both"):
            check_micro_places(scene, nx)
    return domain


def check_used_values(scene: Scene, comm: MPI.Comm) -> None:
    """Collective: the checks of :func:`checked_domain`, building a mesh only when a field must
    be checked at its places (``plantgrowth validate``)."""
    if needs_place_checks(scene):
        checked_domain(scene, comm)


@contextmanager
def run_directory(
    outdir: Path, scene: Scene, comm: MPI.Comm, resume: bool = False, overwrite: bool = False,
    options: Options = CLI_OPTIONS,
) -> Iterator[None]:  # fmt: skip
    """Hold the output directory for the run (see :mod:`plantgrowth.runner.rundir`; its
    messages name the options as ``options`` do), write the resolved scene and log into run.log
    (appended to on resume) until the block ends."""
    lock = claim(outdir, comm, resume=resume, overwrite=overwrite, options=options)
    handler = None
    try:
        if comm.rank == 0:
            atomic_write_text(outdir / "scene.toml", scene.to_toml())
            handler = logging.FileHandler(outdir / "run.log")  # appends
            handler.setFormatter(logging.Formatter("%(asctime)s %(message)s"))
            log.addHandler(handler)
        yield
    finally:
        if handler is not None:
            log.removeHandler(handler)
            handler.close()
        if lock is not None:
            lock.release()


def run_macro(
    domain: MacroDomain, outdir: Path, comm: MPI.Comm, resume: bool = False
) -> list[dict[str, float]]:
    """Run the coupled macroscopic model on its domain, writing into ``outdir``: the scene's
    rectangle, or, for ``model = "both"``, the region the micro tissue's cells cover, so that
    the two models see the same tissue (docs/model.md section 7). Returns the summary rows of the
    steps run (all rows are in ``outdir/summary.csv``)."""
    start = time.perf_counter()
    model = model_on(domain, comm)
    log.info("set-up: %.2f s", time.perf_counter() - start)
    return run_model(model, domain.scene, outdir, comm, resume=resume)


def run_micro(
    scene: Scene, outdir: Path, comm: MPI.Comm, resume: bool = False
) -> list[dict[str, float]]:
    """Run the microscopic model of a scene, writing into ``outdir``."""
    start = time.perf_counter()
    model = MicroModel(scene, comm)
    log.info("set-up: %.2f s", time.perf_counter() - start)
    return run_model(model, scene, outdir, comm, resume=resume)


def run_scene(
    scene: Scene, outdir: Path, comm: MPI.Comm, what: str, resume: bool = False,
    overwrite: bool = False, options: Options = CLI_OPTIONS,
) -> None:  # fmt: skip
    """Run a scene into ``outdir`` on ``comm`` as ``plantgrowth run`` does: check it where the
    run uses it, hold the directory, write scene.toml and run.log (its first line names the run
    as ``what``), warn, run. The messages name ``resume`` and ``overwrite`` as ``options`` do.

    Raises:
        InputError: a field is out of range where the run uses it (SceneError), the directory
            is busy, holds an earlier run, or cannot be resumed; ``resume`` with ``overwrite``.
        RunError: a step failed (logged in run.log).
        Interrupted: SIGINT stopped the run after a completed step (logged in run.log).
    """
    if resume and overwrite:
        raise InputError(f"give either {options.overwrite} or {options.resume}, not both")
    domain = checked_domain(scene, comm)  # before anything is written
    extends = resume and check_resumable(outdir, scene, options)
    with run_directory(outdir, scene, comm, resume, overwrite, options):
        log.info("%s -> %s on %d rank(s)", what, outdir, comm.size)
        if extends:
            log.info("extending the run to time.t_max = %g", scene.time.t_max)
        warn_about(scene)
        runs = {"macro": [("macro", outdir)], "micro": [("micro", outdir)],
                "both": [("macro", outdir / "macro"), ("micro", outdir / "micro")]}  # fmt: skip
        try:
            for side, directory in runs[scene.model]:
                if directory != outdir:
                    prepare_directory(directory, comm, keep=resume)
                if side == "macro":
                    run_macro(domain, directory, comm, resume=resume)
                else:
                    run_micro(scene, directory, comm, resume=resume)
        except RunError as err:
            log.error("run failed: %s", err)
            raise
        except Interrupted as stop:
            log.info("%s", stop)
            raise
        log.info("done: %s", outdir)
        for side, directory in runs[scene.model]:
            if comm.rank == 0:
                name = f"{side} " if directory != outdir else ""
                log.info("%sresult: %s", name, result_line(directory), extra={"result": True})


def result_line(directory: Path) -> str:
    """The final line of a run: its last time, area and mean growth rate, and the largest
    non-elliptic area fraction reached and when (summary.csv, resumed steps included)."""
    with open(directory / "summary.csv", newline="") as f:
        rows = [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]
    first, last = rows[0], rows[-1]
    worst = max(rows, key=lambda row: row["nonelliptic_area_fraction"])
    lost = (
        f"; largest non-elliptic area {worst['nonelliptic_area_fraction']:.3g} of the tissue "
        f"at t = {worst['t']:g}"
        if worst["nonelliptic_area_fraction"] > 0.0
        else "; no non-elliptic area larger than a cell"
    )
    singular = sum(row["singular_points"] > 0 for row in rows)
    points = f", singular points at {singular} step(s)" if singular else ""
    return (
        f"t = {last['t']:g}: area {last['area']:.6g} ({last['area'] / first['area']:.4g} times "
        f"its value at t = 0), mean growth rate tr G {last['growth_rate_area']:.6g} per unit "
        f"time{lost}{points} (summary.csv has every step)"
    )
