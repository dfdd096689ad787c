"""A run's results as numpy arrays (the Python API's ``Results``): its summary.csv by column, its
written times and each written field on the output mesh. Everything is read from the files when
asked for, so a run that is still going shows its completed steps, and a run written under
``mpirun`` reads as the serial one (the files hold the fields in a canonical order)."""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path

import numpy as np

from plantgrowth.base.errors import InputError
from plantgrowth.results.field_table import ALL_TIMES, rows_at, stack, step_of
from plantgrowth.results.reader import ResultSeries, read_series


class Results:
    """The files ``plantgrowth run`` wrote into one run directory (docs/api.md).

    Attributes:
        directory: the run directory.
    """

    def __init__(self, directory: str | os.PathLike) -> None:
        self.directory = Path(directory)

    def __repr__(self) -> str:
        return f"Results({str(self.directory)!r})"

    @property
    def summary(self) -> dict[str, np.ndarray]:
        """summary.csv, one float64 array per column (docs/api.md), one entry per completed
        step; a last row still being written (no end of line yet) is left out."""
        text = (self.directory / "summary.csv").read_text()
        lines = text.splitlines(keepends=True)
        if lines and not lines[-1].endswith("\n"):
            lines.pop()
        rows = list(csv.reader(io.StringIO("".join(lines))))
        if not rows:
            raise InputError(f"{self.directory / 'summary.csv'} has no header yet")
        header, body = rows[0], [r for r in rows[1:] if len(r) == len(rows[0])]
        values = np.array(body, dtype=float).reshape(len(body), len(header))
        return {name: values[:, i] for i, name in enumerate(header)}

    @property
    def times(self) -> np.ndarray:
        """The times at which fields were written (``output.every``), increasing."""
        return np.array(self._series().times, dtype=float)

    @property
    def fields(self) -> list[str]:
        """The names of the written fields (E_hom as its six components E1111, ...), sorted."""
        return self._series().names

    @property
    def points(self) -> np.ndarray:
        """Reference coordinates of the output mesh's nodes, (N, 2)."""
        return self._series().points

    @property
    def triangles(self) -> np.ndarray:
        """Node indices of the output mesh's triangles, (M, 3)."""
        return self._series().triangles

    def field(self, name: str, t: float | None = None) -> np.ndarray:
        """A written field at time ``t`` (default: the last written time) on the output mesh,
        as float64: ``u`` at the nodes, (N, 2); cell fields per triangle: tensors (M, 2, 2),
        vectors (M, 2), scalars (M,); E_hom's components (``E1111``, ...) interpolated to the
        triangles as the model does.

        Raises:
            InputError: no such field, or no output at ``t``; the message lists what exists.
        """
        series = self._series()
        return read_field(series, name, written_time(series, t))

    def field_table(self, name: str, time: float | str | None = None) -> dict[str, np.ndarray]:
        """The field ``name`` as a table (what ``plantgrowth export`` writes; docs/api.md): one
        row per triangle (cell fields) or node (``u``, ``P``, ``psi``) and written time, as one array per
        column: ``step``, ``t``, ``triangle`` or ``node``, the reference ``x1``, ``x2`` of the
        row's centroid or node, its deformed ``x1_deformed``, ``x2_deformed`` (+ u; without a
        written u, left out), then the field's components (``G_11``, ``G_12``, ``G_21``,
        ``G_22``; ``u_1``, ``u_2``; a scalar under its name).

        Args:
            name: a written field (see :attr:`fields`).
            time: a written time (default: the last), or ``"all"``: every written time, the
                tables one after the other.

        Raises:
            InputError: no such field, no output at ``time``, or no summary row for a written
                time; the message lists what exists.
        """
        series = self._series()
        if time == ALL_TIMES:
            times = series.times or [written_time(series, None)]  # none yet: its error
        elif isinstance(time, str):
            raise InputError(f"time = {time!r} is invalid: a written time or {ALL_TIMES!r}")
        else:
            times = [written_time(series, time)]
        summary = self.summary
        tables = []
        for t in times:
            u = read_field(series, "u", t) if "u" in series.names else None
            step = step_of(summary, t, self.directory)
            values = read_field(series, name, t)
            tables.append(rows_at(name, values, series.points, series.triangles, u, step, t))
        return stack(tables)

    def _series(self) -> ResultSeries:
        return read_series(self.directory)


def written_time(series: ResultSeries, t: float | None) -> float:
    """``t`` if the run wrote fields at it (to 1e-9 relative), the last written time for None;
    InputError listing the written times otherwise."""
    times = series.times
    if not times:
        raise InputError(f"no fields written yet in {series.directory}")
    t = times[-1] if t is None else float(t)
    if not any(abs(s - t) <= 1e-9 * max(1.0, abs(t)) for s in times):
        raise InputError(f"no fields at t = {t:g} in {series.directory} "
                         f"(written times: {', '.join(f'{s:g}' for s in times)})")  # fmt: skip
    return t


def read_field(series: ResultSeries, name: str, t: float) -> np.ndarray:
    """The field ``name`` at the written time ``t`` as :meth:`Results.field` returns it."""
    if name not in series.names:
        raise InputError(f"field {name!r} was not written in {series.directory} "
                         f"(written: {', '.join(series.names)})")  # fmt: skip
    try:
        data = series.field(name, t)
    except KeyError:  # this field's index lags the others' (a run still going)
        raise InputError(f"field {name!r} has no output at t = {t:g} in {series.directory} "
                         "yet (its index lags a step behind)") from None  # fmt: skip
    data = np.asarray(data, dtype=float)
    if name != "u" and data.ndim == 2 and data.shape[1] == 9:
        return data.reshape(-1, 3, 3)[:, :2, :2].copy()
    if name != "u" and data.ndim == 2 and data.shape[1] == 3:
        return data[:, :2].copy()
    return data


def read_results(directory: str | os.PathLike) -> Results:
    """The results of the run in ``directory`` (finished, failed, interrupted or going on),
    written by any number of ranks; serial (call it on one rank, or on each).

    Raises:
        InputError: ``directory`` holds no run (no summary.csv and fields.xdmf), or a
            ``model = "both"`` run (read its ``macro`` and ``micro`` directories).
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise InputError(f"{directory}: no such directory")
    if (directory / "macro").is_dir() and (directory / "micro").is_dir():
        raise InputError(f"{directory} holds a model = 'both' run: read "
                         f"{directory / 'macro'} and {directory / 'micro'}")  # fmt: skip
    for name in ("summary.csv", "fields.xdmf"):
        if not (directory / name).is_file():
            raise InputError(f"{directory}: no {name}: not a plantgrowth run directory")
    return Results(directory)
