"""Command line: ``plantgrowth run | validate | cell | compare | sweep | render``.

``main(argv) -> int`` logs on rank 0 only: progress to stdout, warnings to stderr, both to the
run's ``run.log``. Exit codes: 0 done, 2 bad input (one line naming the field and its valid
range), 3 a run that failed numerically (step, time, place, cause; ``sweep``: some run failed,
see its sweep.csv), 130 interrupted by SIGINT at the end of a step. A closed stdout
(``plantgrowth ... | head``) silences the progress only.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from mpi4py import MPI

from plantgrowth.errors import (
    USER_ERRORS,
    InputError,
    RunError,
    check_growth_tensor,
    check_wall_material,
)

log = logging.getLogger("plantgrowth")

OVERWRITE_HELP = (
    "replace an earlier run in the output directory (only the files plantgrowth wrote are "
    "removed); without it such a directory is refused"
)


class _Parser(argparse.ArgumentParser):
    """argparse that raises InputError instead of exiting, so every rank fails the same way."""

    def error(self, message: str):  # type: ignore[override]
        raise InputError(message)


def _floats(text: str) -> list[float]:
    try:
        return [float(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers a,b,...: {text!r}") from None


def build_parser() -> argparse.ArgumentParser:
    """The CLI's argument parser (sub-commands)."""
    parser = _Parser(prog="plantgrowth", description="Multiscale plant tissue growth.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    cell = sub.add_parser(
        "cell",
        help="solve the unit-cell problems and print the homogenized tensors",
        description="Homogenized properties of one honeycomb cell (MODEL.md sections 2-3). "
        "Defaults: the reference cell of MODEL.md section 9 with Fg = I.",
    )
    cell.add_argument("--l1", type=float, default=1.0, help="vertical wall length (default 1)")
    cell.add_argument("--l2", type=float, default=1.0, help="inclined wall length (default 1)")
    cell.add_argument("--theta", type=float, default=30.0, help="wall angle, degrees (default 30)")
    cell.add_argument("--w", type=float, default=0.05, help="own wall thickness (default 0.05)")
    cell.add_argument("--E", type=float, default=1.0, help="wall Young modulus (default 1)")
    cell.add_argument("--nu", type=float, default=0.3, help="wall Poisson ratio (default 0.3)")
    cell.add_argument(
        "--Fg",
        type=_floats,
        default=[1.0, 0.0, 0.0, 1.0],
        help="growth tensor F11,F12,F21,F22, row-major (default identity)",
    )
    cell.add_argument(
        "--resolution",
        type=int,
        default=None,
        help="P2 elements across a wall (default: about 0.3%% error on moduli)",
    )
    cell.add_argument("--json", action="store_true", help="print one JSON object as the last line")
    cell.set_defaults(handler=_cell_command)

    run = sub.add_parser(
        "run",
        help="run a scene (also under mpirun)",
        description="Run the simulation a scene describes; writes DIR/fields.xdmf (+ .h5; "
        "macro runs also DIR/coarse.xdmf: E_hom at the coarse nodes), DIR/state.h5 (for "
        "--resume), DIR/summary.csv, DIR/scene.toml (the resolved scene) and DIR/run.log.",
    )
    run.add_argument("scene", type=Path, help="scene TOML file")
    run.add_argument(
        "-o",
        "--output",
        type=Path,
        default=None,
        help="output directory (default: results/<scene name>)",
    )
    run.add_argument(
        "--resume", type=Path, default=None, metavar="DIR",
        help="continue the run in DIR from its last completed step (a finished run is extended "
        "if the scene's only change is a larger time.t_max)",
    )  # fmt: skip
    run.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    run.set_defaults(handler=_run_command)

    compare = sub.add_parser(
        "compare",
        help="compare the micro and macro models for several Nx",
        description="Runs, for each Nx, the macro model on the region the micro tissue covers "
        "and the micro model; writes DIR/compare.csv (nx, delta, the relative errors err_u1, "
        "err_u2, err_G at the first step, mean growth rates at t = 0 and t_max, run times) and "
        "DIR/nx<N>/{macro,micro}.",
    )
    compare.add_argument("scene", type=Path, help="scene TOML file")
    compare.add_argument("--nx", type=int, nargs="+", required=True, help="even cell counts")
    compare.add_argument(
        "-o",
        "--output",
        type=Path,
        default=None,
        help="output directory (default: results/compare_<scene name>)",
    )
    compare.add_argument(
        "--resolution",
        type=int,
        default=None,
        help="micro: P2 elements across a wall (default: micro.resolution)",
    )
    compare.add_argument(
        "--first-step-only",
        action="store_true",
        help="stop both models after the first step (errors only; no t_max columns)",
    )
    compare.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    compare.set_defaults(handler=_compare_command)

    validate = sub.add_parser(
        "validate",
        help="check a scene without running it",
        description="Load and check a scene file (keys, types, ranges, geometry, loads) and "
        "print a one-line summary; warnings about implausible parameters go to stderr.",
    )
    validate.add_argument("scene", type=Path, help="scene TOML file")
    validate.set_defaults(handler=_validate_command)
    _add_sweep_parser(sub)
    _add_render_parser(sub)
    return parser


def _add_render_parser(sub) -> None:
    render = sub.add_parser(
        "render",
        help="draw a field of a run into a PNG (headless, matplotlib)",
        description="Draw one written field of a run (finished or still running) on the "
        "deformed tissue x + u(t), with the initial outline dashed and, for micro runs, the "
        "cells' outlines: scalars and tensor components as colours, vectors as arrows "
        "(directions as bars). Reads DIR, never writes into it; under mpirun only rank 0 draws.",
    )
    render.add_argument("directory", type=Path, metavar="DIR", help="a run's output directory")
    render.add_argument(
        "--field", required=True, metavar="NAME",
        help="a written field: u, Fg, G, sigma_hom, eps_hom, E1111 ..., trG, growth_anisotropy, "
        "growth_direction, stress_direction, cell_id (an unknown name lists the run's fields)",
    )  # fmt: skip
    render.add_argument(
        "--time", type=float, default=None, metavar="T",
        help="draw the written time nearest T (default: the last written time)",
    )  # fmt: skip
    render.add_argument(
        "--component", default=None, metavar="K",
        help="tensors (required): 11, 12, 21, 22, tr or det; vectors: 1, 2 or norm as colours "
        "(default: arrows); scalars: none",
    )  # fmt: skip
    render.add_argument("-o", "--output", type=Path, required=True, metavar="FILE.png",
                        help="the picture to write (outside DIR)")  # fmt: skip
    render.add_argument("--force", action="store_true",
                        help="replace FILE.png if it exists (without it an existing file is "
                        "refused)")  # fmt: skip
    render.add_argument("--dpi", type=int, default=150, help="resolution (default 150)")
    render.set_defaults(handler=_render_command)


def _add_sweep_parser(sub) -> None:
    sweep = sub.add_parser(
        "sweep",
        help="run a scene for many parameter values (also under mpirun and as a job array)",
        description='Run every combination (mode = "grid") or every value of each key alone '
        '(mode = "one-at-a-time") of the [vary] table of a sweep file on its base scene: '
        "DIR/run_NNNN/ holds each run (as plantgrowth run writes it), DIR/sweep.csv one row per "
        "run, DIR/sweep.toml the resolved sweep. Everything is checked before anything runs. "
        "Started again, a sweep skips its finished runs, resumes interrupted ones and retries "
        "failed ones.",
    )
    sweep.add_argument(
        "sweep", type=Path,
        help='sweep TOML file: base = "SCENE.toml", mode, [vary] "dotted.key" = [values]',
    )  # fmt: skip
    sweep.add_argument(
        "-o", "--output", type=Path, default=None,
        help="output directory (default: results/sweep_<sweep name>)",
    )  # fmt: skip
    sweep.add_argument(
        "--ranks-per-run", type=int, default=1, metavar="K",
        help="under mpirun -n N: N/K runs at a time, each on K ranks (N a multiple of K; "
        "default 1)",
    )  # fmt: skip
    sweep.add_argument(
        "--array-index", type=int, default=None, metavar="I",
        help="as element I (0 <= I < N) of a job array, take runs I, I+N, I+2N, ... "
        "(Slurm: $SLURM_ARRAY_TASK_ID, with --array=0-<N-1>)",
    )  # fmt: skip
    sweep.add_argument(
        "--array-count", type=int, default=None, metavar="N",
        help="number N of job-array elements (Slurm: $SLURM_ARRAY_TASK_COUNT)",
    )  # fmt: skip
    sweep.add_argument(
        "--dry-run", action="store_true",
        help="check the sweep and list its runs (this element's share); write nothing",
    )  # fmt: skip
    sweep.add_argument(
        "--overwrite", action="store_true",
        help="replace an earlier sweep in DIR (only plantgrowth's files are removed); without "
        "it another sweep there is refused and the same one continued",
    )  # fmt: skip
    sweep.set_defaults(handler=_sweep_command)


def _cell_command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    import numpy as np

    from plantgrowth.cell_solver import DEFAULT_RESOLUTION, CellSolver
    from plantgrowth.meshes.honeycomb import HoneycombCell
    from plantgrowth.meshes.unit_cell import mesh_size

    E, nu = check_wall_material(args.E, args.nu)
    if len(args.Fg) != 4:
        raise InputError(f"--Fg needs 4 numbers F11,F12,F21,F22, got {len(args.Fg)}")
    Fg = np.array(check_growth_tensor("Fg", [args.Fg[:2], args.Fg[2:]]))
    resolution = DEFAULT_RESOLUTION if args.resolution is None else args.resolution
    cell = HoneycombCell(args.l1, args.l2, args.theta, args.w)
    mesh_size(cell, resolution, "--resolution")
    result = CellSolver(cell, resolution, comm).solve(Fg, E, nu).summary()
    if comm.rank == 0:
        if args.json:
            print(json.dumps(result))
        else:
            width = max(len(k) for k in result)
            for key, value in result.items():
                shown = value if key == "ndofs" else f"{value:.6g}"
                print(f"{key:<{width}}  {shown}")
    return 0


def _render_command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    """Rank 0 draws; the others wait for its outcome and fail the same way."""
    outcome = None
    if comm.rank == 0:
        from plantgrowth.render import render

        try:
            if not 10 <= args.dpi <= 1200:
                raise InputError(f"--dpi = {args.dpi} is out of range: an integer in [10, 1200]")
            written = render(args.directory, args.field, args.output, args.time,
                             args.component, args.force, dpi=args.dpi)  # fmt: skip
            outcome = ("done", f"wrote {written}")
        except USER_ERRORS as err:
            outcome = ("error", str(err))
        except BaseException:
            comm.bcast(("failed", "render failed on rank 0"), root=0)
            raise
    kind, text = comm.bcast(outcome, root=0)
    if kind == "error":
        raise InputError(text)
    if kind == "failed":
        raise RuntimeError(text)
    log.info("%s", text)
    return 0


def _validate_command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    from plantgrowth.field_checks import check_used_values
    from plantgrowth.scene import load_scene

    scene = load_scene(args.scene)
    check_used_values(scene, comm)
    _warn_about(scene)
    if comm.rank == 0:
        print(
            f"{args.scene}: valid {scene.model} scene, growth law {scene.growth.law}, "
            f"{scene.time.n_steps} steps of dt = {scene.time.dt:g}"
        )
    return 0


def _compare_command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    from plantgrowth.compare import run_compare
    from plantgrowth.field_checks import check_used_values
    from plantgrowth.meshes.tissue import TissueLayout, check_nx, wall_mesh_size
    from plantgrowth.micro import scene_cell
    from plantgrowth.scene import load_scene

    scene = load_scene(args.scene)
    scene.check_micro()
    for nx in args.nx:  # everything is checked before anything runs
        layout = TissueLayout(scene_cell(scene), check_nx("--nx", nx))
        if args.resolution is not None:
            wall_mesh_size(layout, args.resolution, "--resolution")
        check_used_values(scene, comm, nx)
    outdir = args.output or Path("results") / f"compare_{args.scene.stem}"
    with _run_directory(outdir, scene, comm, overwrite=args.overwrite):
        log.info("plantgrowth compare %s -> %s on %d rank(s)", args.scene, outdir, comm.size)
        _warn_about(scene)
        try:
            run_compare(scene, args.nx, outdir, comm, args.resolution, args.first_step_only)
        except RunError as err:
            log.error("run failed: %s", err)
            return _run_failed(err, comm)
        log.info("done: %s", outdir / "compare.csv")
    return 0


@contextmanager
def _run_directory(
    outdir: Path, scene, comm: MPI.Comm, resume: bool = False, overwrite: bool = False
) -> Iterator[None]:
    """Hold the output directory for the run (see :mod:`plantgrowth.rundir`), write the resolved
    scene and log into run.log (appended to on resume) until the block ends."""
    from plantgrowth.output import atomic_write_text
    from plantgrowth.rundir import claim

    lock = claim(outdir, comm, resume=resume, overwrite=overwrite)
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


def _warn_about(scene) -> None:
    """Log the scene's implausible parameters as warnings (stderr and run.log, rank 0)."""
    from plantgrowth.plausibility import scene_warnings

    for text in scene_warnings(scene):
        log.warning("warning: %s", text)


def _run_failed(err: RunError, comm: MPI.Comm) -> int:
    """Report a failed run once on stderr (run.log has it already)."""
    if comm.rank == 0:
        print(f"plantgrowth: run failed: {err}", file=sys.stderr)
    return 3


def run_scene(
    scene, outdir: Path, comm: MPI.Comm, what: str, resume: bool = False, overwrite: bool = False
) -> None:
    """Run a scene into ``outdir`` on ``comm`` as ``plantgrowth run`` does: hold the directory,
    write scene.toml and run.log (its first line names the run as ``what``), warn, run.

    Raises:
        InputError: a field is out of range where the run uses it (SceneError), the directory
            is busy, holds an earlier run, or cannot be resumed.
        RunError: a step failed (logged in run.log).
        Interrupted: SIGINT stopped the run after a completed step (logged in run.log).
    """
    from plantgrowth.coupled import run_macro
    from plantgrowth.field_checks import check_used_values
    from plantgrowth.micro import run_micro
    from plantgrowth.output import prepare_directory
    from plantgrowth.rundir import check_resumable
    from plantgrowth.timeloop import Interrupted

    check_used_values(scene, comm)  # before anything is written
    extends = resume and check_resumable(outdir, scene)
    with _run_directory(outdir, scene, comm, resume, overwrite):
        log.info("%s -> %s on %d rank(s)", what, outdir, comm.size)
        if extends:
            log.info("extending the run to time.t_max = %g", scene.time.t_max)
        _warn_about(scene)
        runs = {"macro": [(run_macro, outdir)], "micro": [(run_micro, outdir)],
                "both": [(run_macro, outdir / "macro"), (run_micro, outdir / "micro")]}  # fmt: skip
        try:
            for run, directory in runs[scene.model]:
                if directory != outdir:
                    prepare_directory(directory, comm, keep=resume)
                run(scene, directory, comm, resume=resume)
        except RunError as err:
            log.error("run failed: %s", err)
            raise
        except Interrupted as stop:
            log.info("%s", stop)
            raise
        log.info("done: %s", outdir)


def _run_command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    from plantgrowth.scene import load_scene
    from plantgrowth.timeloop import Interrupted

    scene = load_scene(args.scene)
    resume = args.resume is not None
    if resume:
        if args.output is not None and args.output != args.resume:
            raise InputError("give either -o DIR or --resume DIR, not two different directories")
        if args.overwrite:
            raise InputError("give either --overwrite or --resume, not both")
        outdir = args.resume
    else:
        outdir = args.output if args.output is not None else Path("results") / args.scene.stem
    try:
        run_scene(scene, outdir, comm, f"plantgrowth run {args.scene}", resume, args.overwrite)
    except RunError as err:
        return _run_failed(err, comm)
    except Interrupted as stop:
        if comm.rank == 0:
            print(f"plantgrowth: {stop}; continue with: plantgrowth run {args.scene} "
                  f"--resume {outdir}", file=sys.stderr)  # fmt: skip
        return 130
    return 0


def _sweep_command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    from plantgrowth.sweep import Share, dry_run, load_sweep, run_sweep

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


class _Below(logging.Filter):
    """Passes records below a level."""

    def __init__(self, level: int) -> None:
        super().__init__()
        self.level = level

    def filter(self, record: logging.LogRecord) -> bool:
        return record.levelno < self.level


class _Console(logging.StreamHandler):
    """A console handler that goes quiet when its reader is gone (``plantgrowth ... | head``)."""

    def handleError(self, record: logging.LogRecord) -> None:  # noqa: N802 (logging's name)
        if isinstance(sys.exc_info()[1], BrokenPipeError):
            _discard_stdout()
        else:
            super().handleError(record)


def _discard_stdout() -> None:
    """Send the rest of stdout to /dev/null: its reader has closed the pipe."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # not a real file (e.g. captured by pytest)
        pass


def _configure_logging(comm: MPI.Comm) -> None:
    """Progress of ``plantgrowth`` on rank 0 to stdout, its warnings to stderr (as
    ``plantgrowth: warning: ...``); errors are printed by ``main`` and the handlers, once; other
    libraries' warnings only.

    The root handler drops INFO records: the JIT's build tool raises the root level to INFO
    when it compiles a form, which would otherwise flood the output.
    """
    root_handler = logging.StreamHandler()
    root_handler.setLevel(logging.WARNING)
    logging.basicConfig(handlers=[root_handler], format="%(name)s: %(message)s")
    for handler in list(log.handlers):
        log.removeHandler(handler)
        handler.close()
    console = _Console(sys.stdout)  # the stdout of this call
    console.setFormatter(logging.Formatter("%(message)s"))
    console.addFilter(_Below(logging.WARNING))
    warnings = _Console(sys.stderr)
    warnings.setFormatter(logging.Formatter("plantgrowth: %(message)s"))
    warnings.setLevel(logging.WARNING)
    warnings.addFilter(_Below(logging.ERROR))
    log.addHandler(console)
    log.addHandler(warnings)
    log.propagate = False
    log.setLevel(logging.INFO if comm.rank == 0 else logging.ERROR)


def _quiet_broken_pipe() -> None:
    """Let a closed stdout raise BrokenPipeError (handled) instead of PETSc's SIGPIPE handler
    aborting MPI (exit 59): initialise PETSc, then restore Python's ignored SIGPIPE."""
    from petsc4py import PETSc  # noqa: F401  (PetscInitialize installs the signal handlers)

    try:
        signal.signal(signal.SIGPIPE, signal.SIG_IGN)
    except ValueError:  # not the main thread (main() called from a thread): leave it
        pass


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``plantgrowth`` command."""
    comm = MPI.COMM_WORLD
    _configure_logging(comm)
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser()
    try:
        if not argv:
            if comm.rank == 0:
                parser.print_help()
            raise InputError(
                "no command given: choose one of cell, run, compare, validate, sweep, render"
            )
        args = parser.parse_args(argv)
        _quiet_broken_pipe()
        code = args.handler(args, comm)
        sys.stdout.flush()
        return code
    except USER_ERRORS as err:
        if comm.rank == 0:
            print(f"plantgrowth: error: {err}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader of stdout is gone: nothing left to tell it
        _discard_stdout()
        return 0


if __name__ == "__main__":
    sys.exit(main())
