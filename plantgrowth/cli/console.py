"""The command line's console: progress on rank 0 to stdout, warnings to stderr, quiet when the
reader of stdout has gone (``plantgrowth ... | head``)."""

from __future__ import annotations

import logging
import os
import signal
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from mpi4py import MPI

log = logging.getLogger("plantgrowth")


class _Below(logging.Filter):
    """Passes records below a level."""

    def __init__(self, level: int) -> None:
        super().__init__()
        self.level = level

    def filter(self, record: logging.LogRecord) -> bool:
        return record.levelno < self.level


class _Quiet(logging.Filter):
    """With ``on`` (``--quiet``), drops the progress records but the final result line (logged
    with ``extra={"result": True}``)."""

    on = False

    def filter(self, record: logging.LogRecord) -> bool:
        return not self.on or getattr(record, "result", False)


QUIET = _Quiet()


class _Console(logging.StreamHandler):
    """A console handler that goes quiet when its reader is gone (``plantgrowth ... | head``)."""

    def handleError(self, record: logging.LogRecord) -> None:  # noqa: N802 (logging's name)
        if isinstance(sys.exc_info()[1], BrokenPipeError):
            discard_stdout()
        else:
            super().handleError(record)


def discard_stdout() -> None:
    """Send the rest of stdout to /dev/null: its reader has closed the pipe."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # not a real file (e.g. captured by pytest)
        pass


def configure_logging(comm: MPI.Comm) -> None:
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
    QUIET.on = False
    console.addFilter(QUIET)
    warnings = _Console(sys.stderr)
    warnings.setFormatter(logging.Formatter("plantgrowth: %(message)s"))
    warnings.setLevel(logging.WARNING)
    warnings.addFilter(_Below(logging.ERROR))
    log.addHandler(console)
    log.addHandler(warnings)
    log.propagate = False
    log.setLevel(logging.INFO if comm.rank == 0 else logging.ERROR)


def solver_signals() -> None:
    """The signals of a command that solves. A closed stdout raises BrokenPipeError (handled)
    instead of PETSc's SIGPIPE handler aborting MPI (exit 59): initialise PETSc, then restore
    Python's ignored SIGPIPE. Ctrl-C outside the time loop (which stops at the end of a step)
    stops at once and silently: SIGINT's default action, which importing gmsh used to set at
    start-up before gmsh was imported only to build a mesh."""
    from petsc4py import PETSc  # noqa: F401  (PetscInitialize installs the signal handlers)

    try:
        signal.signal(signal.SIGPIPE, signal.SIG_IGN)
        signal.signal(signal.SIGINT, signal.SIG_DFL)
    except ValueError:  # not the main thread (main() called from a thread): leave them
        pass
