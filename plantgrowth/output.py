"""Run outputs: the XDMF/HDF5 field time series and the per-step summary table.

Every step is closed on disk before the next one starts (the XDMF file is reopened in append
mode per step; the CSV row is flushed and fsync'ed), so an interrupted run leaves each completed
step readable and ParaView can open ``fields.xdmf`` while the run goes on.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path

from dolfinx import fem, io
from mpi4py import MPI

OUTPUT_FILES = ("fields.xdmf", "fields.h5", "summary.csv", "scene.toml", "run.log")


def prepare_directory(directory: Path, comm: MPI.Comm) -> None:
    """Create the output directory and remove the outputs of an earlier run in it.

    Raises OSError (on every rank) if the directory cannot be created or written.
    """
    error = None
    if comm.rank == 0:
        try:
            directory.mkdir(parents=True, exist_ok=True)
            for name in OUTPUT_FILES:
                (directory / name).unlink(missing_ok=True)
            probe = directory / ".write-test"
            probe.write_text("")
            probe.unlink()
        except OSError as err:
            error = f"cannot write the output directory {directory}: {err.strerror or err}"
    error = comm.bcast(error, root=0)
    if error:
        raise OSError(error)


class FieldWriter:
    """``fields.xdmf`` (+ ``.h5``): the mesh once, then the given functions at each time."""

    def __init__(self, path: Path, mesh, functions: list[fem.Function]) -> None:
        self.path = str(path)
        self.comm = mesh.comm
        self.functions = functions
        with io.XDMFFile(self.comm, self.path, "w") as xdmf:
            xdmf.write_mesh(mesh)

    def write(self, t: float) -> None:
        """Append every function at time t and close the files."""
        with io.XDMFFile(self.comm, self.path, "a") as xdmf:
            for function in self.functions:
                xdmf.write_function(function, t)


class SummaryWriter:
    """``summary.csv``: one row per step, written by rank 0 and flushed to disk at once."""

    def __init__(self, path: Path, columns: list[str], comm: MPI.Comm) -> None:
        self.path = path
        self.columns = columns
        self.comm = comm
        if comm.rank == 0:
            with open(path, "w", newline="") as f:
                csv.writer(f).writerow(columns)

    def write(self, row: dict[str, float]) -> None:
        if self.comm.rank != 0:
            return
        with open(self.path, "a", newline="") as f:
            csv.writer(f).writerow([f"{row[c]:.17g}" for c in self.columns])
            f.flush()
            os.fsync(f.fileno())
