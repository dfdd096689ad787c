"""Logging handlers on the process's standard streams, looked up when a record is written.

A handler made with ``logging.StreamHandler(sys.stderr)`` keeps the stream object of that moment.
When a caller swaps ``sys.stdout``/``sys.stderr`` for a while and closes its own (pytest's
capture does, per test), every later record raises ``ValueError: I/O operation on closed file``
inside logging. :class:`StdStreamHandler` writes to whatever ``sys.<name>`` is at each record, as
logging's own last-resort handler does.
"""

from __future__ import annotations

import logging
import sys
from typing import Literal, TextIO


class StdStreamHandler(logging.StreamHandler):
    """A StreamHandler on ``sys.stdout`` or ``sys.stderr`` as they are when a record is written."""

    def __init__(self, name: Literal["stdout", "stderr"], level: int = logging.NOTSET) -> None:
        if name not in ("stdout", "stderr"):
            raise ValueError(f"name must be 'stdout' or 'stderr', got {name!r}")
        logging.Handler.__init__(self, level)  # not StreamHandler's: it would bind a stream
        self.stream_name = name

    @property
    def stream(self) -> TextIO:  # type: ignore[override]
        return getattr(sys, self.stream_name)
