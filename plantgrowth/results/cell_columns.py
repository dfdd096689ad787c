"""``plantgrowth render DIR --cells COLUMN``: a column of a micro run's ``cells.csv`` (turgor P,
area, trG, neighbours, ...; docs/outputs.md) drawn as one colour per biological cell on the
cells' deformed polygons, through the field path of :mod:`plantgrowth.results.render`: the
column at the written time t, value ``c[k]`` of cell k, is handed to it as the per-triangle
field ``c[cell_id]`` (every wall triangle of cell k gets cell k's value).
"""

from __future__ import annotations

import csv

import numpy as np

from plantgrowth.base.errors import InputError
from plantgrowth.results.reader import ResultSeries

PREFIX = "cells.csv:"
"""A render name ``cells.csv:<column>`` is the column ``<column>`` of cells.csv."""
NOT_DRAWN = ("step", "t", "cell")  # the row's keys, not a cell's property
TIME_TOLERANCE = 1e-9  # relative: cells.csv's t and the written time agree to round-off


class CellColumnError(InputError):
    """A ``--cells`` request that cannot be met; the message starts with ``--cells``."""


def is_column(name: str) -> bool:
    """Whether the render name ``name`` is a cells.csv column (:data:`PREFIX`)."""
    return name.startswith(PREFIX)


def _header(series: ResultSeries) -> list[str]:
    path = series.directory / "cells.csv"
    if series.outlines is None or not path.is_file():
        raise CellColumnError(
            f"--cells: {series.directory} has no cells.csv (a micro run writes it; a macro run "
            "has no cells: use --field)"
        )
    with path.open(newline="", encoding="utf-8") as f:
        return next(csv.reader(f), [])


def check_column(series: ResultSeries, name: str) -> None:
    """CellColumnError unless ``name`` (``cells.csv:<column>``) names a drawable column of the
    run's cells.csv; the message lists the valid ones."""
    column = name[len(PREFIX) :]
    valid = [c for c in _header(series) if c not in NOT_DRAWN]
    if column not in valid:
        raise CellColumnError(
            f"--cells {column!r}: {series.directory}/cells.csv has no such column; valid: "
            f"{', '.join(valid)}"
        )


def column_values(series: ResultSeries, name: str, t: float) -> np.ndarray:
    """The column ``name`` at the written time t per wall triangle (``c[cell_id]``)."""
    check_column(series, name)
    column = name[len(PREFIX) :]
    with (series.directory / "cells.csv").open(newline="", encoding="utf-8") as f:
        rows = [(int(r["cell"]), float(r[column])) for r in csv.DictReader(f)
                if abs(float(r["t"]) - t) <= TIME_TOLERANCE * max(1.0, abs(t))]  # fmt: skip
    n = len(np.unique(series.outlines.cell_ids(t)))
    if sorted(k for k, _ in rows) != list(range(n)):
        raise CellColumnError(
            f"--cells {column}: {series.directory}/cells.csv has {len(rows)} rows at t = {t:g}, "
            f"not one for each of the {n} cells (a step still being written? try an earlier "
            "--time)"
        )
    per_cell = np.empty(n)
    for k, value in rows:
        per_cell[k] = value
    return per_cell[series.cell_field("cell_id", t).astype(np.int64)]
