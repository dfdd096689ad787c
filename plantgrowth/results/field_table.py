"""A written field as a table (``Results.field_table``, ``plantgrowth export``): one row per
triangle (a cell field, DG0) or node (``u``, P1) and written time, with the row's place on the
reference and on the deformed tissue, and a CSV file of it whose numbers read back exactly.

Columns, in order: ``step``, ``t``; ``triangle`` or ``node`` (the row's index into
``Results.triangles`` or ``Results.points``); ``x1``, ``x2``, the reference (ungrown) centroid of
the triangle or the node, the coordinates a scene's expressions and regions use; ``x1_deformed``,
``x2_deformed`` = reference + u (a triangle's centroid moves with the mean u of its corners, u
being linear on it; left out if the run did not write u); then the field: a tensor's components
``NAME_11``, ``NAME_12``, ``NAME_21``, ``NAME_22`` (``Results.field(NAME)[:, i-1, j-1]``), a
vector's ``NAME_1``, ``NAME_2``, a scalar as ``NAME``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from plantgrowth.base.errors import InputError
from plantgrowth.results.reader import NODE_FIELDS

ALL_TIMES = "all"
"""``time`` of every written time (a long table)."""
TIME_TOLERANCE = 1e-9  # relative: a written time and summary.csv's t are the same number


def components(name: str, values: np.ndarray) -> dict[str, np.ndarray]:
    """The columns of a field's values: (n, 2, 2) -> NAME_ij, (n, 2) -> NAME_i, (n,) -> NAME."""
    if values.ndim == 3:
        return {f"{name}_{i + 1}{j + 1}": values[:, i, j] for i in range(2) for j in range(2)}
    if values.ndim == 2:
        return {f"{name}_{i + 1}": values[:, i] for i in range(values.shape[1])}
    return {name: values}


def rows_at(
    name: str, values: np.ndarray, points: np.ndarray, triangles: np.ndarray,
    u: np.ndarray | None, step: int, t: float,
) -> dict[str, np.ndarray]:  # fmt: skip
    """The table of one written time: ``values`` of the field ``name`` per node (``u``) or per
    triangle, on the mesh ``points`` (N, 2), ``triangles`` (M, 3), moved by ``u`` (N, 2) if
    given."""
    on_nodes = name in NODE_FIELDS
    place = points if on_nodes else points[triangles].mean(axis=1)
    n = len(place)
    table = {"step": np.full(n, step, dtype=np.int64), "t": np.full(n, float(t)),
             "node" if on_nodes else "triangle": np.arange(n, dtype=np.int64),
             "x1": place[:, 0], "x2": place[:, 1]}  # fmt: skip
    if u is not None:
        moved = points + u
        deformed = moved if on_nodes else moved[triangles].mean(axis=1)
        table |= {"x1_deformed": deformed[:, 0], "x2_deformed": deformed[:, 1]}
    return table | components(name, values)


def stack(tables: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The tables of several times (the same columns) one after the other."""
    return {key: np.concatenate([table[key] for table in tables]) for key in tables[0]}


def step_of(summary: dict[str, np.ndarray], t: float, directory: Path) -> int:
    """The step of the written time ``t``: the step of summary.csv's row at ``t``."""
    match = np.flatnonzero(np.abs(summary["t"] - t) <= TIME_TOLERANCE * max(1.0, abs(t)))
    if not len(match):
        raise InputError(f"{directory / 'summary.csv'} has no row at t = {t:g} yet (a run "
                         "still going writes it after the step's fields): try again")  # fmt: skip
    return int(summary["step"][match[0]])


def csv_text(table: dict[str, np.ndarray]) -> str:
    """The table as CSV: a header of the column names, then one line per row; every float in
    Python's shortest round-trip form (repr), so the file reads back to the same float64."""
    columns = [[repr(v) for v in column.tolist()] for column in table.values()]
    lines = [",".join(table), *(",".join(row) for row in zip(*columns, strict=True))]
    return "\n".join(lines) + "\n"
