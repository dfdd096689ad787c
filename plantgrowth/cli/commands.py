"""The handlers of the ``plantgrowth`` commands: each takes the parsed arguments and the
communicator, calls the Python API (:mod:`plantgrowth.api`) or the study it names, and returns
the exit code (bad input raises :class:`InputError`: exit 2)."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from plantgrowth.base.errors import USER_ERRORS, InputError, RunError
from plantgrowth.cli.console import solver_signals

if TYPE_CHECKING:
    from mpi4py import MPI

log = logging.getLogger("plantgrowth")


def cell_command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    from plantgrowth.unitcell.properties import cell_properties

    if len(args.Fg) != 4:
        raise InputError(f"--Fg needs 4 numbers F11,F12,F21,F22, got {len(args.Fg)}")
    Fg = [args.Fg[:2], args.Fg[2:]]
    result = cell_properties(args.l1, args.l2, args.theta, args.w, args.E, args.nu, Fg,
                             args.resolution, comm, "--resolution", args.fibre_stiffness,
                             args.fibre_angle, ("--fibre-stiffness", "--fibre-angle"))  # fmt: skip
    if comm.rank == 0:
        if args.json:
            print(json.dumps(result))
        else:  # the scalars; the strain averages, b and kappa in --json only
            scalars = {k: v for k, v in result.items() if not isinstance(v, (dict, list))}
            width = max(len(k) for k in scalars)
            for key, value in scalars.items():
                shown = value if key == "ndofs" else f"{value:.6g}"
                print(f"{key:<{width}}  {shown}")
    return 0


def render_command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    """Rank 0 draws (:func:`_on_rank0`)."""

    def draw() -> str:
        from plantgrowth.results.cell_columns import PREFIX as CELLS_PREFIX
        from plantgrowth.results.picture import render

        if args.dpi is not None and not 10 <= args.dpi <= 1200:
            raise InputError(f"--dpi = {args.dpi} is out of range: an integer in [10, 1200]")
        name = args.field if args.cells is None else CELLS_PREFIX + args.cells
        written = render(args.directory, name, args.output, args.time, args.component,
                         args.force, dpi=args.dpi, vmin=args.vmin, vmax=args.vmax,
                         regions=args.regions, fibres=args.fibres)  # fmt: skip
        return f"wrote {written}"

    return _on_rank0(draw, "render", comm)


def export_command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    """Rank 0 writes the table (:func:`_on_rank0`)."""

    def write() -> str:
        from plantgrowth.results.export import export

        written = export(args.directory, args.field, args.output, args.time, args.overwrite)
        return f"wrote {written}"

    return _on_rank0(write, "export", comm)


def _on_rank0(work: Callable[[], str], command: str, comm: MPI.Comm) -> int:
    """``work()`` on rank 0 alone (a command that reads a run and writes one file); the other
    ranks wait for its outcome and fail the same way. Logs the line ``work`` returns."""
    outcome = None
    if comm.rank == 0:
        try:
            outcome = ("done", work())
        except USER_ERRORS as err:
            outcome = ("error", str(err))
        except BaseException:
            comm.bcast(("failed", f"{command} failed on rank 0"), root=0)
            raise
    kind, text = comm.bcast(outcome, root=0)
    if kind == "error":
        raise InputError(text)
    if kind == "failed":
        raise RuntimeError(text)
    log.info("%s", text)
    return 0


def validate_command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    from plantgrowth.scene import load_scene
    from plantgrowth.scene.places import check_micro_tissue, needs_place_checks
    from plantgrowth.scene.plausibility import warn_about

    scene = load_scene(args.scene)
    if needs_place_checks(scene):  # only then a mesh, dolfinx and PETSc
        from plantgrowth.runner.scene_run import check_used_values

        solver_signals()
        check_used_values(scene, comm)
    elif scene.model in ("micro", "both"):
        check_micro_tissue(scene)  # given cells: their voids and walls mesh (pure numpy)
    warn_about(scene)
    if comm.rank == 0:
        print(
            f"{args.scene}: valid {scene.model} scene, growth law {scene.growth.law}, "
            f"{scene.time.n_steps} steps of dt = {scene.time.dt:g}"
        )
    return 0


def compare_command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    from plantgrowth.meshes.tissue import TissueLayout, check_nx, wall_mesh_size
    from plantgrowth.models.micro.model import scene_cell
    from plantgrowth.runner.scene_run import checked_domain, run_directory
    from plantgrowth.scene import load_scene
    from plantgrowth.scene.places import check_micro_tissue
    from plantgrowth.scene.plausibility import warn_about
    from plantgrowth.scene.tissue_cells import cells_at_nx
    from plantgrowth.studies.compare import run_compare

    scene = load_scene(args.scene)
    scene.check_micro()
    for nx in args.nx:  # the cheap checks of every Nx first
        layout = TissueLayout(scene_cell(scene), check_nx("--nx", nx))
        if args.resolution is not None:
            wall_mesh_size(layout, args.resolution, "--resolution")
        check_micro_tissue(cells_at_nx(scene, nx))  # generated cells: regenerated at each Nx
    domains = {nx: checked_domain(scene, comm, nx) for nx in args.nx}  # before anything is written
    scene.check_cellular_extent("plantgrowth compare", args.nx[0])
    outdir = args.output or Path("results") / f"compare_{args.scene.stem}"
    with run_directory(outdir, scene, comm, overwrite=args.overwrite):
        log.info("plantgrowth compare %s -> %s on %d rank(s)", args.scene, outdir, comm.size)
        warn_about(scene)
        try:
            run_compare(
                scene, args.nx, outdir, comm, args.resolution, args.first_step_only, domains
            )
        except RunError as err:
            log.error("run failed: %s", err)
            return _run_failed(err, comm)
        log.info("done: %s", outdir / "compare.csv")
    return 0


def _run_failed(err: RunError, comm: MPI.Comm) -> int:
    """Report a failed run once on stderr (run.log has it already)."""
    if comm.rank == 0:
        print(f"plantgrowth: run failed: {err}", file=sys.stderr)
    return 3


def run_command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    from plantgrowth.api import run_with
    from plantgrowth.base.errors import Interrupted
    from plantgrowth.runner.rundir import CLI_OPTIONS
    from plantgrowth.scene import load_scene

    scene = load_scene(args.scene)
    resume = args.resume is not None
    if resume:
        if args.output is not None and args.output != args.resume:
            raise InputError("give either -o DIR or --resume DIR, not two different directories")
        outdir = args.resume
    else:
        outdir = args.output if args.output is not None else Path("results") / args.scene.stem
    try:
        run_with(
            CLI_OPTIONS,
            scene,
            outdir,
            comm,
            resume=resume,
            overwrite=args.overwrite,
            label=f"plantgrowth run {args.scene}",
        )
    except RunError as err:
        return _run_failed(err, comm)
    except Interrupted as stop:
        if comm.rank == 0:
            print(f"plantgrowth: {stop}; continue with: plantgrowth run {args.scene} "
                  f"--resume {outdir}", file=sys.stderr)  # fmt: skip
        return 130
    return 0


def sweep_command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    from plantgrowth.runner.scene_run import run_scene
    from plantgrowth.studies.sweep import run_sweep
    from plantgrowth.studies.sweep_file import load_sweep
    from plantgrowth.studies.sweep_share import Share, dry_run

    share = Share.check(comm.size, args.ranks_per_run, args.array_index, args.array_count)
    sweep = load_sweep(args.sweep)
    if args.dry_run:
        return dry_run(sweep, share, comm)
    if args.overwrite and share.elements > 1:
        raise InputError(
            "--overwrite cannot be given to a job-array element (the elements share DIR): "
            "remove the earlier sweep before submitting the array, or choose another -o"
        )
    outdir = (
        args.output if args.output is not None else Path("results") / f"sweep_{args.sweep.stem}"
    )
    code = run_sweep(sweep, outdir, comm, share, run_scene, args.overwrite)
    if comm.rank == 0 and code == 130:
        print(f"plantgrowth: sweep interrupted; continue with: plantgrowth sweep {args.sweep} "
              f"-o {outdir}", file=sys.stderr)  # fmt: skip
    elif comm.rank == 0 and code == 3:
        print(f"plantgrowth: not every run finished (failed, or held by another process): see "
              f"{outdir / 'sweep.csv'}", file=sys.stderr)  # fmt: skip
    return code
