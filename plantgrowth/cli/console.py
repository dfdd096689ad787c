"""The command line's console: progress on rank 0 to stdout, warnings to stderr, quiet when the
reader of stdout has gone (``plantgrowth ... | head``)."""

from __future__ import annotations

import logging
import os
import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

from plantgrowth.base.std_streams import StdStreamHandler

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


class _Console(StdStreamHandler):
    """A console handler on sys.stdout or sys.stderr as they are when a record is written, that
    goes quiet when its reader is gone (``plantgrowth ... | head``)."""

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


@contextmanager
def console_logging(comm: MPI.Comm) -> Iterator[None]:
    """While active: progress of ``plantgrowth`` on rank 0 to stdout, its warnings to stderr (as
    ``plantgrowth: warning: ...``); errors are printed by ``main`` and the handlers, once; other
    libraries' warnings only. Afterwards the ``plantgrowth`` and root loggers are as they were:
    ``main`` called in process (a script, a test) leaves no handler behind.

    The root handler (added only if the root logger has none) drops INFO records: the JIT's
    build tool raises the root level to INFO when it compiles a form, which would otherwise
    flood the output.
    """
    root = logging.getLogger()
    root_handler = None
    if not root.handlers:
        root_handler = StdStreamHandler("stderr", logging.WARNING)
        root_handler.setFormatter(logging.Formatter("%(name)s: %(message)s"))
        root.addHandler(root_handler)
    saved = (list(log.handlers), log.level, log.propagate)
    for handler in saved[0]:  # the caller's, back on exit
        log.removeHandler(handler)
    console = _Console("stdout")
    console.setFormatter(logging.Formatter("%(message)s"))
    console.addFilter(_Below(logging.WARNING))
    QUIET.on = False
    console.addFilter(QUIET)
    warnings = _Console("stderr", logging.WARNING)
    warnings.setFormatter(logging.Formatter("plantgrowth: %(message)s"))
    warnings.addFilter(_Below(logging.ERROR))
    ours = (console, warnings)
    for handler in ours:
        log.addHandler(handler)
    log.propagate = False
    log.setLevel(logging.INFO if comm.rank == 0 else logging.ERROR)
    try:
        yield
    finally:
        for handler in ours:
            log.removeHandler(handler)
            handler.close()
        if root_handler is not None:
            root.removeHandler(root_handler)
            root_handler.close()
        for handler in saved[0]:
            log.addHandler(handler)
        log.setLevel(saved[1])
        log.propagate = saved[2]


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
