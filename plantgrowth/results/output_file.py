"""The one file a reading command writes (``render``'s picture, ``export``'s table): checked
before anything is read, written under a temporary name and renamed into place, so that a
failure or a kill never leaves half a file under the name asked for."""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from plantgrowth.base.errors import InputError


def check_new_file(
    output: Path, directory: Path, replace: bool, replace_flag: str,
    error: type[InputError] = InputError,
) -> None:  # fmt: skip
    """:func:`check_place` and :func:`check_new` together. Raises ``error``."""
    check_place(output, directory, error)
    check_new(output, replace, replace_flag, error)


def check_place(output: Path, directory: Path, error: type[InputError] = InputError) -> None:
    """``-o FILE`` is not a directory, lies in an existing directory and outside the run
    ``directory``: plantgrowth never writes into a run after it. Raises ``error``."""
    if output.is_dir():
        raise error(f"-o {output}: is a directory; give a file name ending in {output.suffix}")
    if not output.parent.resolve().is_dir():
        raise error(f"-o {output}: the directory {output.parent} does not exist")
    run = directory.resolve()
    if run == output.parent.resolve() or run in output.parent.resolve().parents:
        raise error(
            f"-o {output}: inside the run directory {directory}; plantgrowth never writes "
            "into a run after it: choose a path outside it"
        )


def check_new(
    output: Path, replace: bool, replace_flag: str, error: type[InputError] = InputError
) -> None:
    """``-o FILE`` is new unless ``replace`` (the option ``replace_flag`` allows it)."""
    if output.exists() and not replace:
        raise error(f"-o {output}: the file exists; give {replace_flag} to replace it")


@contextmanager
def written_atomically(output: Path) -> Iterator[Path]:
    """The temporary path to write ``output``'s content to (same directory and suffix); renamed
    to ``output`` when the block ends without an error, removed in any case."""
    tmp = output.with_name(f".{output.stem}.tmp{output.suffix}")
    try:
        yield tmp
        os.replace(tmp, output)
    finally:
        tmp.unlink(missing_ok=True)
