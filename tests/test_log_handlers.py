"""No logging handler outlives its owner: the rule of tests/conftest.py (tests/handler_leaks.py)
fires on a leaked handler, and the CLI called in process leaves the loggers as it found them."""

from __future__ import annotations

import io
import logging
import sys
from pathlib import Path

import handler_leaks
import pytest

from plantgrowth.base.std_streams import StdStreamHandler
from plantgrowth.cli import main

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "reference_stress.toml"


def test_the_rule_fires_on_a_handler_left_on_a_closed_stream():
    """A handler added on a stream that is then closed (as pytest closes a test's captured
    stdout) is reported twice: added and not removed, and on a closed stream; remove_added
    takes it away."""
    before = handler_leaks.handlers()
    stream = io.StringIO()
    leaked = logging.StreamHandler(stream)
    logging.getLogger("plantgrowth").addHandler(leaked)
    stream.close()
    problems = handler_leaks.leaks(before)
    handler_leaks.remove_added(before)
    assert len(problems) == 2, problems
    assert "'plantgrowth'" in problems[0] and "was added and not removed" in problems[0]
    assert "writes to a closed stream" in problems[1]
    assert leaked not in logging.getLogger("plantgrowth").handlers
    assert handler_leaks.leaks(before) == []


def test_the_rule_fires_on_a_file_handler_left_on_the_root(tmp_path):
    """A file handler left on the root logger (as a run's run.log handler would be) is reported."""
    before = handler_leaks.handlers()
    logging.getLogger().addHandler(logging.FileHandler(tmp_path / f"run{id(before)}.log"))
    problems = handler_leaks.leaks(before)
    handler_leaks.remove_added(before)
    assert len(problems) == 1 and problems[0].startswith("logger 'root': <FileHandler"), problems
    assert handler_leaks.leaks(before) == []


def test_the_cli_in_process_leaves_the_loggers_as_it_found_them(capsys):
    """``main`` adds its console handlers for the command only: afterwards the ``plantgrowth``
    logger has the caller's handler, level and propagation back, and the root no new handler."""
    logger = logging.getLogger("plantgrowth")
    callers = logging.NullHandler()
    logger.addHandler(callers)
    before = handler_leaks.handlers()
    try:
        assert main(["validate", str(SCENE)]) == 0
        assert "reference" in capsys.readouterr().out.lower()
        assert handler_leaks.handlers() == before
        assert logger.level == logging.NOTSET and logger.propagate
    finally:
        logger.removeHandler(callers)


@pytest.mark.parametrize("name", ["stdout", "stderr"])
def test_std_stream_handler_writes_to_the_current_stream(monkeypatch, name):
    """StdStreamHandler looks sys.stdout/sys.stderr up at each record: a stream swapped in after
    it was made receives the record, and one swapped out (and closed) is never written to."""
    handler = StdStreamHandler(name)
    handler.setFormatter(logging.Formatter("%(message)s"))
    first, second = io.StringIO(), io.StringIO()
    monkeypatch.setattr(sys, name, first)
    handler.handle(logging.makeLogRecord({"msg": "one", "levelno": logging.WARNING}))
    assert first.getvalue() == "one\n"
    first.close()
    monkeypatch.setattr(sys, name, second)
    handler.handle(logging.makeLogRecord({"msg": "two", "levelno": logging.WARNING}))
    assert second.getvalue() == "two\n"
    with pytest.raises(ValueError, match="'stdout' or 'stderr'"):
        StdStreamHandler("stdin")  # type: ignore[arg-type]
