"""The logging rule of tests/conftest.py (not a test module): a test leaves the ``plantgrowth``
and root loggers with the handlers it found, and none of them on a closed stream.

A handler left behind on a stream that its owner closes (pytest's capture of a test's
stdout/stderr) makes every later record print ``--- Logging error --- ValueError: I/O operation
on closed file``; a file handler left behind keeps writing into an old run's run.log. pytest's
own handlers (added and removed around each test phase) are not the tests' concern.
"""

from __future__ import annotations

import logging

WATCHED = ("plantgrowth", "")
"""The loggers watched, by name ("" is the root)."""


def handlers() -> dict[str, list[logging.Handler]]:
    """The watched loggers' handlers, pytest's own left out."""
    return {
        name: [h for h in logging.getLogger(name or None).handlers
               if not type(h).__module__.startswith("_pytest")]
        for name in WATCHED
    }  # fmt: skip


def leaks(before: dict[str, list[logging.Handler]]) -> list[str]:
    """What breaks the rule now, against the handlers ``before`` the test: one line per
    handler added and not removed, or writing to a closed stream."""
    problems = []
    for name, now in handlers().items():
        where = f"logger {name or 'root'!r}"
        for handler in now:
            if handler not in before[name]:
                problems.append(f"{where}: {handler!r} was added and not removed")
            if getattr(getattr(handler, "stream", None), "closed", False):
                problems.append(f"{where}: {handler!r} writes to a closed stream")
    return problems


def remove_added(before: dict[str, list[logging.Handler]]) -> None:
    """Remove (and close) the handlers added since ``before``, so that one leak fails one test."""
    for name, now in handlers().items():
        logger = logging.getLogger(name or None)
        for handler in now:
            if handler not in before[name]:
                logger.removeHandler(handler)
                handler.close()
