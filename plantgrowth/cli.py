"""Command line: ``plantgrowth run | validate | cell | compare``.

``main(argv) -> int`` logs on rank 0 only. Exit codes: 0 done, 2 bad input (one line naming
the field and its valid range), 3 a run that failed numerically (step, time, place, cause),
130 interrupted by SIGINT at the end of a step.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
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
        description="Run the simulation a scene describes; writes DIR/fields.xdmf (+ .h5), "
        "DIR/summary.csv, DIR/scene.toml (the resolved scene) and DIR/run.log.",
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
        help="continue the interrupted run in DIR from its last completed step",
    )  # fmt: skip
    run.set_defaults(handler=_run_command)

    compare = sub.add_parser(
        "compare",
        help="compare the micro and macro models for several Nx",
        description="Runs, for each Nx, the macro model on the region the micro tissue covers "
        "and the micro model; writes DIR/compare.csv (nx, delta, err_u1, err_u2 at the first "
        "step, mean growth rates at t = 0 and t_max, run times) and DIR/nx<N>/{macro,micro}.",
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
        help="stop both models after the first step (errors only)",
    )
    compare.set_defaults(handler=_compare_command)

    validate = sub.add_parser("validate", help="check a scene without running it")
    validate.add_argument("scene", type=Path, help="scene TOML file")
    validate.set_defaults(handler=_validate_command)
    return parser


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


def _validate_command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    from plantgrowth.scene import load_scene

    scene = load_scene(args.scene)
    if comm.rank == 0:
        print(
            f"{args.scene}: valid {scene.model} scene, growth law {scene.growth.law}, "
            f"{scene.time.n_steps} steps of dt = {scene.time.dt:g}"
        )
    return 0


def _compare_command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    from plantgrowth.compare import run_compare
    from plantgrowth.meshes.tissue import TissueLayout, check_nx, wall_mesh_size
    from plantgrowth.micro import scene_cell
    from plantgrowth.scene import load_scene

    scene = load_scene(args.scene)
    scene.check_micro()
    for nx in args.nx:  # everything is checked before anything runs
        layout = TissueLayout(scene_cell(scene), check_nx("--nx", nx))
        if args.resolution is not None:
            wall_mesh_size(layout, args.resolution, "--resolution")
    outdir = args.output or Path("results") / f"compare_{args.scene.stem}"
    _start_run(outdir, scene, comm)
    try:
        run_compare(scene, args.nx, outdir, comm, args.resolution, args.first_step_only)
    except RunError as err:
        return _run_failed(err, comm)
    log.info("done: %s", outdir / "compare.csv")
    return 0


def _start_run(outdir: Path, scene, comm: MPI.Comm, resume: bool = False) -> None:
    """Prepare the output directory, write the resolved scene, log into run.log (until
    ``main`` returns)."""
    from plantgrowth.output import prepare_directory

    try:
        prepare_directory(outdir, comm, keep=resume)
    except OSError as err:
        raise InputError(str(err)) from None
    if comm.rank == 0 and not resume:
        (outdir / "scene.toml").write_text(scene.to_toml())
        handler = logging.FileHandler(outdir / "run.log")
        handler.setFormatter(logging.Formatter("%(asctime)s %(message)s"))
        log.addHandler(handler)


def _run_failed(err: RunError, comm: MPI.Comm) -> int:
    log.error("run failed: %s", err)
    if comm.rank == 0:
        print(f"plantgrowth: run failed: {err}", file=sys.stderr)
    return 3


def _run_command(args: argparse.Namespace, comm: MPI.Comm) -> int:
    from plantgrowth.coupled import run_macro
    from plantgrowth.micro import run_micro
    from plantgrowth.output import prepare_directory
    from plantgrowth.scene import load_scene
    from plantgrowth.timeloop import Interrupted

    scene = load_scene(args.scene)
    resume = args.resume is not None
    if resume:
        if args.output is not None and args.output != args.resume:
            raise InputError("give either -o DIR or --resume DIR, not two different directories")
        outdir = args.resume
        _check_resumable(outdir, scene)
    else:
        outdir = args.output if args.output is not None else Path("results") / args.scene.stem
    _start_run(outdir, scene, comm, resume)
    log.info("plantgrowth run %s -> %s on %d rank(s)", args.scene, outdir, comm.size)
    runs = {"macro": [(run_macro, outdir)], "micro": [(run_micro, outdir)],
            "both": [(run_macro, outdir / "macro"), (run_micro, outdir / "micro")]}  # fmt: skip
    try:
        for run, directory in runs[scene.model]:
            if directory != outdir:
                prepare_directory(directory, comm, keep=resume)
            run(scene, directory, comm, resume=resume)
    except RunError as err:
        return _run_failed(err, comm)
    except Interrupted as stop:
        if comm.rank == 0:
            print(f"plantgrowth: {stop}; continue with: plantgrowth run {args.scene} "
                  f"--resume {outdir}", file=sys.stderr)  # fmt: skip
        return 130
    log.info("done: %s", outdir)
    return 0


def _check_resumable(outdir: Path, scene) -> None:
    """A run can be resumed only with the scene it was started with."""
    from plantgrowth.scene import load_scene

    saved = outdir / "scene.toml"
    if not saved.is_file():
        raise InputError(f"--resume {outdir}: no scene.toml there, so no run to resume")
    if load_scene(saved) != scene:
        raise InputError(f"--resume {outdir}: the scene differs from the one the run started with")


def _configure_logging(comm: MPI.Comm) -> None:
    """Progress of ``plantgrowth`` on rank 0 to stdout; other libraries' warnings only.

    The root handler drops INFO records: the JIT's build tool raises the root level to INFO
    when it compiles a form, which would otherwise flood the output.
    """
    root_handler = logging.StreamHandler()
    root_handler.setLevel(logging.WARNING)
    logging.basicConfig(handlers=[root_handler], format="%(name)s: %(message)s")
    for handler in list(log.handlers):
        log.removeHandler(handler)
        handler.close()
    console = logging.StreamHandler(sys.stdout)  # the stdout of this call
    console.setFormatter(logging.Formatter("%(message)s"))
    log.addHandler(console)
    log.propagate = False
    log.setLevel(logging.INFO if comm.rank == 0 else logging.WARNING)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``plantgrowth`` command."""
    comm = MPI.COMM_WORLD
    _configure_logging(comm)
    try:
        args = build_parser().parse_args(argv)
        return args.handler(args, comm)
    except USER_ERRORS as err:
        if comm.rank == 0:
            print(f"plantgrowth: error: {err}", file=sys.stderr)
        return 2
    finally:
        for handler in [h for h in log.handlers if isinstance(h, logging.FileHandler)]:
            log.removeHandler(handler)
            handler.close()


if __name__ == "__main__":
    sys.exit(main())
