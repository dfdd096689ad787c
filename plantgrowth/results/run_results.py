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
        times = series.times
        if not times:
            raise InputError(f"no fields written yet in {self.directory}")
        if name not in series.names:
            raise InputError(f"field {name!r} was not written in {self.directory} "
                             f"(written: {', '.join(series.names)})")  # fmt: skip
        t = times[-1] if t is None else float(t)
        if not any(abs(s - t) <= 1e-9 * max(1.0, abs(t)) for s in times):
            raise InputError(f"no fields at t = {t:g} in {self.directory} "
                             f"(written times: {', '.join(f'{s:g}' for s in times)})")  # fmt: skip
        try:
            data = series.displacement(t) if name == "u" else series.cell_field(name, t)
        except KeyError:  # this field's index lags the others' (a run still going)
            raise InputError(f"field {name!r} has no output at t = {t:g} in {self.directory} "
                             "yet (its index lags a step behind)") from None  # fmt: skip
        data = np.asarray(data, dtype=float)
        if name != "u" and data.ndim == 2 and data.shape[1] == 9:
            return data.reshape(-1, 3, 3)[:, :2, :2].copy()
        if name != "u" and data.ndim == 2 and data.shape[1] == 3:
            return data[:, :2].copy()
        return data

    def _series(self) -> ResultSeries:
        return read_series(self.directory)


def read_results(directory: str | os.PathLike) -> Results:
    """The results of the run in ``directory`` (finished, failed, interrupted or going on),
    written by any number of ranks; serial (call it on one rank, or on each).

    Raises:
        InputError: ``directory`` holds no run (no summary.csv and fields.xdmf), or a
            ``model = "both"`` run (read its ``macro`` and ``micro`` directories).
    """
    directory = Path(directory)
    if (directory / "macro").is_dir() and (directory / "micro").is_dir():
        raise InputError(f"{directory} holds a model = 'both' run: read "
                         f"{directory / 'macro'} and {directory / 'micro'}")  # fmt: skip
    for name in ("summary.csv", "fields.xdmf"):
        if not (directory / name).is_file():
            raise InputError(f"{directory}: no {name}: not a plantgrowth run directory")
    return Results(directory)
