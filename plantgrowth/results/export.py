"""``plantgrowth export DIR --field NAME [--time T|all] -o FILE.csv [--overwrite]``: a written
field as a CSV table (:mod:`plantgrowth.results.field_table`), one row per triangle or node and
written time. Reads the run through :class:`~plantgrowth.results.run_results.Results` and writes
only FILE: never into DIR, never over an existing file unless ``overwrite`` (then atomically)."""

from __future__ import annotations

import os
from pathlib import Path

from plantgrowth.base.errors import InputError
from plantgrowth.results.field_table import csv_text
from plantgrowth.results.output_file import check_new_file, written_atomically
from plantgrowth.results.run_results import read_results

SUFFIX = ".csv"


def export(
    directory: str | os.PathLike, name: str, output: str | os.PathLike,
    time: float | str | None = None, overwrite: bool = False,
) -> Path:  # fmt: skip
    """Write ``read_results(directory).field_table(name, time)`` into the CSV file ``output``
    and return its path. InputError on bad input, before anything is written."""
    directory, output = Path(directory), Path(output)
    if output.suffix.lower() != SUFFIX:
        raise InputError(f"-o {output}: the table must be a {SUFFIX} file")
    check_new_file(output, directory, overwrite, "--overwrite")
    table = read_results(directory).field_table(name, time)
    with written_atomically(output) as tmp:
        tmp.write_text(csv_text(table))
    return output
