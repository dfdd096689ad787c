"""Command line: ``plantgrowth run | validate | cell | compare | sweep | render | export``.

``main(argv) -> int`` logs on rank 0 only: progress to stdout, warnings to stderr, both to the
run's ``run.log``. Exit codes: 0 done, 2 bad input (one line naming the field and its valid
range), 3 a run that failed numerically (step, time, place, cause; ``sweep``: some run failed,
see its sweep.csv), 130 interrupted by SIGINT at the end of a step. A closed stdout
(``plantgrowth ... | head``) silences the progress only.

A thin layer over the Python API (:mod:`plantgrowth.api`) and the studies: the handlers
(:mod:`plantgrowth.cli.commands`) import what a command needs when it runs, so ``--help`` and
bad arguments load neither dolfinx nor gmsh.

May import: everything else in plantgrowth.
"""

from __future__ import annotations

import sys

from plantgrowth.base.errors import USER_ERRORS, InputError, Interrupted
from plantgrowth.cli.console import QUIET, console_logging, discard_stdout, solver_signals
from plantgrowth.cli.mpi_start import world
from plantgrowth.cli.parser import build_parser

__all__ = ["build_parser", "main"]


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``plantgrowth`` command. MPI starts once the command line has parsed
    (``--help`` and ``--version`` print before), PETSc only for the commands that solve."""
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser()
    try:
        if not argv:
            if world().rank == 0:
                parser.print_help()
            raise InputError(
                "no command given: choose one of cell, run, compare, validate, sweep, render, "
                "export"
            )
        args = parser.parse_args(argv)
        comm = world()
        with console_logging(comm):
            QUIET.on = getattr(args, "quiet", False)
            if args.solves:
                solver_signals()
            code = args.handler(args, comm)
            sys.stdout.flush()
        return code
    except USER_ERRORS as err:
        if world().rank == 0:
            print(f"plantgrowth: error: {err}", file=sys.stderr)
        return 2
    except Interrupted as stop:  # Ctrl-C in a command without its own hint (compare)
        if world().rank == 0:
            print(f"plantgrowth: {stop}", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader of stdout is gone: nothing left to tell it
        discard_stdout()
        return 0
