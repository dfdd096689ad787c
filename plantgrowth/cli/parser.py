"""The ``plantgrowth`` command line's arguments: one sub-parser per command, each naming the
handler in :mod:`plantgrowth.cli.commands` that runs it."""

from __future__ import annotations

import argparse
from pathlib import Path

from plantgrowth.base.errors import InputError
from plantgrowth.cli import commands

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


def _version() -> str:
    """The installed package's version (pyproject.toml)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("plantgrowth")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "(not installed)"


class _Version(argparse.Action):
    """``--version``: prints the installed version, looked up only when asked (argparse's own
    action takes the text when the parser is built: importlib.metadata's look-up costs every
    command 15-30 ms)."""

    def __init__(self, option_strings: list[str], dest: str = argparse.SUPPRESS, **kwargs):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"plantgrowth {_version()}")
        parser.exit()


_QUIET = _Parser(add_help=False)
_QUIET.add_argument(
    "-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
    help="no progress lines on stdout: only warnings, errors and the final result line "
    "(run.log still has everything)",
)  # fmt: skip
"""-q/--quiet, accepted before and after the command (``default=SUPPRESS``: a sub-command's
absent flag does not reset the one given before it)."""


def build_parser() -> argparse.ArgumentParser:
    """The CLI's argument parser (sub-commands)."""
    parser = _Parser(
        prog="plantgrowth", description="Multiscale plant tissue growth.", parents=[_QUIET]
    )
    parser.add_argument("--version", action=_Version, help="show the version and exit")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    cell = sub.add_parser(
        "cell",
        parents=[_QUIET],
        help="solve the unit-cell problems and print the homogenized tensors",
        description="Homogenized properties of one honeycomb cell (docs/model.md sections 2-3). "
        "Defaults: the reference cell of docs/model.md section 9 with Fg = I.",
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
    fibre_flags = {
        "--fibre-stiffness": "fibre-reinforced walls: fibre modulus E_f / E, finite >= 0 "
        "(default 0: the paper's isotropic walls; docs/fibres.md)",
        "--fibre-angle": "fibre director, degrees anticlockwise from x1 (grown frame; default 0)",
    }
    for flag, text in fibre_flags.items():
        cell.add_argument(flag, type=float, default=0.0, metavar="X", help=text)
    cell.add_argument("--json", action="store_true", help="print one JSON object as the last "
                      "line (with the strain averages dbar_w, dbar_v, the Biot tensor b and "
                      "the conductivity per unit wall conductivity kappa, each [11, 22, 12]; "
                      "inv_M, the storage 1/M, is in the table too)")  # fmt: skip
    cell.set_defaults(handler=commands.cell_command, solves=True)

    run = sub.add_parser(
        "run",
        parents=[_QUIET],
        help="run a scene (also under mpirun)",
        description="Run the simulation a scene describes; writes DIR/fields.xdmf (+ .h5; "
        "macro runs also DIR/coarse.xdmf: E_hom at the coarse nodes), DIR/state.h5 and "
        "DIR/state_previous.h5 (for --resume), DIR/summary.csv, DIR/scene.toml (the resolved "
        "scene) and DIR/run.log.",
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
    run.set_defaults(handler=commands.run_command, solves=True)

    compare = sub.add_parser(
        "compare",
        parents=[_QUIET],
        help="compare the micro and macro models for several Nx",
        description="Runs, for each Nx, the macro model on the region the micro tissue covers "
        "and the micro model; writes DIR/compare.csv (nx, delta, the relative errors err_u1, "
        "err_u2, err_G at the first step, mean growth rates at t = 0 and t_max, run times) and "
        "DIR/nx<N>/{macro,micro}. A scene with generated cells (tissue.cells = {voronoi = N, "
        "seed = S, regularity = r}) is regenerated at each Nx with the same seed and r, both "
        "models on those cells.",
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
    compare.set_defaults(handler=commands.compare_command, solves=True)

    validate = sub.add_parser(
        "validate",
        parents=[_QUIET],
        help="check a scene without running it",
        description="Load and check a scene file (keys, types, ranges, geometry, loads) and "
        "print a one-line summary; warnings about implausible parameters go to stderr.",
    )
    validate.add_argument("scene", type=Path, help="scene TOML file")
    validate.set_defaults(handler=commands.validate_command, solves=False)
    _add_sweep_parser(sub)
    _add_render_parser(sub)
    _add_export_parser(sub)
    return parser


def _time(text: str) -> float | str:
    """--time: a number, or "all" (an animation over the written times)."""
    if text == "all":
        return text
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or all: {text!r}") from None


def _add_render_parser(sub) -> None:
    render = sub.add_parser(
        "render",
        parents=[_QUIET],
        help="draw a field of a run into a PNG, PDF or SVG, or a GIF over time (headless)",
        description="Draw one written field of a run (finished or still running) on the "
        "deformed tissue x + u(t), with the initial outline dashed and, for micro runs, the "
        "cells' outlines: scalars and tensor components as colours, vectors as arrows with a "
        "scale key (directions as bars). Reads DIR, never writes into it; under mpirun only "
        "rank 0 draws.",
    )
    render.add_argument("directory", type=Path, metavar="DIR", help="a run's output directory")
    what = render.add_mutually_exclusive_group(required=True)
    what.add_argument(
        "--cells", default=None, metavar="COLUMN",
        help="micro runs: a column of cells.csv (P, area, trG, neighbours, ...) as one colour "
        "per cell on the deformed cells (an unknown name lists the valid columns)",
    )  # fmt: skip
    what.add_argument(
        "--field", metavar="NAME",
        help="a written field: u, Fg, G, sigma_hom, eps_hom, E1111 ..., trG, growth_anisotropy, "
        "growth_direction, stress_direction, elastic_strain, stability, cue_anisotropy, cell_id "
        "(an unknown name lists the run's fields and the one it may mean)",
    )  # fmt: skip
    render.add_argument(
        "--time", type=_time, default=None, metavar="T",
        help="draw the written time nearest T (default: the last written time); all: every "
        "written time, one frame each, into a .gif animation",
    )  # fmt: skip
    render.add_argument(
        "--component", default=None, metavar="K",
        help="tensors (required): 11, 12, 21, 22, tr or det; vectors: 1, 2 or norm as colours "
        "(default: arrows); scalars: none",
    )  # fmt: skip
    for option, end, extreme in (("--vmin", "low", "smallest"), ("--vmax", "high", "largest")):
        render.add_argument(option, type=float, default=None, metavar="V",
                            help=f"the colour range's {end} end (default: the field's "
                            f"{extreme} value); one range makes runs or times compare")  # fmt: skip
    render.add_argument("-o", "--output", type=Path, required=True, metavar="FILE",
                        help="the picture to write (outside DIR): .png, .pdf or .svg; .gif with "
                        "--time all")  # fmt: skip
    render.add_argument("--force", action="store_true",
                        help="replace FILE if it exists (without it an existing file is "
                        "refused)")  # fmt: skip
    render.add_argument("--dpi", type=int, default=None,
                        help="resolution (default 150; 80 for a .gif)")  # fmt: skip
    render.add_argument("--regions", action="store_true",
                        help="outline the scene's [regions] (the growth units whose reference "
                        "midpoint satisfies each condition)")  # fmt: skip
    render.add_argument("--fibres", action="store_true",
                        help="draw the fibre director on top as headless glyphs (macro: the "
                        "written fibre_direction, on a regular grid of cells; micro: one per "
                        "cell from cells.csv's fibre_angle), turned by the elastic deformation "
                        "F Fg^-1 into the drawn tissue")  # fmt: skip
    render.set_defaults(handler=commands.render_command, solves=False)


def _add_export_parser(sub) -> None:
    export = sub.add_parser(
        "export",
        parents=[_QUIET],
        help="write a field of a run as a CSV table, one row per triangle or node",
        description="Write one written field of a run (finished or still running) as a CSV "
        "table: one row per triangle (cell fields) or node (u) with step, t, the row's index, "
        "its reference x1, x2 and deformed x1_deformed, x2_deformed (+ u), then the field's "
        "components (G_11, G_12, G_21, G_22; u_1, u_2; a scalar under its name), every number "
        "exact (shortest round-trip form). Reads DIR, never writes into it; under mpirun only "
        "rank 0 writes.",
    )
    export.add_argument("directory", type=Path, metavar="DIR", help="a run's output directory")
    export.add_argument("--field", required=True, metavar="NAME",
                        help="a written field (a wrong name lists the run's fields)")  # fmt: skip
    export.add_argument(
        "--time", type=_time, default=None, metavar="T",
        help="a written time (default: the last); all: every written time, one after the "
        "other (a long table)",
    )  # fmt: skip
    export.add_argument("-o", "--output", type=Path, required=True, metavar="FILE",
                        help="the .csv file to write (outside DIR)")  # fmt: skip
    export.add_argument("--overwrite", "--force", action="store_true", dest="overwrite",
                        help="replace FILE if it exists (without it an existing file is "
                        "refused)")  # fmt: skip
    export.set_defaults(handler=commands.export_command, solves=False)


def _add_sweep_parser(sub) -> None:
    sweep = sub.add_parser(
        "sweep",
        parents=[_QUIET],
        help="run a scene for many parameter values (also under mpirun and as a job array)",
        description='Run every combination (mode = "grid"), every value of each key alone '
        '(mode = "one-at-a-time"), or the i-th values of all keys together (mode = "zip") of '
        "the [vary] table of a sweep file on its base scene: "
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
    sweep.set_defaults(handler=commands.sweep_command, solves=True)
