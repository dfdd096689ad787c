"""On-disk cache of the surrogate's lattice values, shared by later and concurrent runs.

Layout: ``CACHE/cells/<key>/<writer>.npz``, one directory per table, keyed by a hash of the
cell geometry, nu, the cell-mesh resolution, the lattice (H0, MAX_LEVEL), the packed layout and
the *code version*: the bytes of every source file that shapes a cell solve, so that a changed
solver never reuses old numbers. Each run writes only files of its own (``<host>-<pid>-<n>``),
each under a temporary name renamed when complete, and reads every complete file of the tables
it uses: concurrent runs never write the same file, and a killed run leaves only complete files
(a stray temporary file is ignored). Rank 0 reads and writes; the values are broadcast.
A fibre-reinforced table's own key holds fibre_stiffness and the node of the director's angle
interpolant as well (:mod:`plantgrowth.unitcell.director_lattice`). The cache holds exact
values only: which of them a run's interpolant uses is the run's own refinement.

``CACHE`` is ``$PLANTGROWTH_CACHE_DIR``, else ``$XDG_CACHE_HOME/plantgrowth``, else
``~/.cache/plantgrowth``; ``PLANTGROWTH_CACHE_DIR=off`` disables the cache.
"""

from __future__ import annotations

import hashlib
import logging
import os
import socket
from importlib import import_module
from itertools import count
from pathlib import Path

import numpy as np
from mpi4py import MPI

from plantgrowth.unitcell import surrogate

log = logging.getLogger("plantgrowth")

_SOURCES = (
    "plantgrowth.unitcell.solver", "plantgrowth.unitcell.gradient_basis",
    "plantgrowth.unitcell.periodic",
    "plantgrowth.unitcell.surrogate", "plantgrowth.unitcell.homogenization",
    "plantgrowth.base.tensors", "plantgrowth.forms.cell_problems", "plantgrowth.forms.elasticity",
    "plantgrowth.meshes.unit_cell", "plantgrowth.meshes.honeycomb",
)  # fmt: skip
_writes = count()


def code_version() -> str:
    """Hash of the sources that determine a cell solve's numbers."""
    digest = hashlib.sha256()
    for name in _SOURCES:
        digest.update(name.encode())
        digest.update(Path(import_module(name).__file__).read_bytes())
    return digest.hexdigest()[:16]


def cache_root() -> Path | None:
    """The cache directory, or None when disabled."""
    value = os.environ.get("PLANTGROWTH_CACHE_DIR")
    if value == "off":
        return None
    if value:
        return Path(value)
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "plantgrowth"


class CellCache:
    """Lattice values on disk for the tables of one run (see the module docstring).

    Args:
        root: the cache directory (None: no cache, every call is a no-op).
        fingerprint: what, besides a table's own key, the values depend on (resolution, layout).
        comm: rank 0 does the I/O.
    """

    def __init__(self, root: Path | None, fingerprint: tuple, comm: MPI.Comm) -> None:
        self.root = root
        self.comm = comm
        self.fingerprint = (code_version(), surrogate.H0, surrogate.MAX_LEVEL, *fingerprint)
        self.writer = f"{socket.gethostname()}-{os.getpid()}"

    def _directory(self, table: tuple) -> Path:
        text = repr((self.fingerprint, table)).encode()
        return self.root / "cells" / hashlib.sha256(text).hexdigest()[:24]

    def load(self, table: tuple) -> dict:
        """Every cached lattice value of ``table`` (collective; {} without a cache)."""
        values = {}
        if self.root is not None and self.comm.rank == 0:
            for path in sorted(self._directory(table).glob("*.npz")):
                try:
                    with np.load(path) as data:
                        points, arrays = data["points"], data["values"]
                except (OSError, ValueError, KeyError) as err:
                    log.warning("cell cache: skipped unreadable %s (%s)", path, err)
                    continue
                values.update(
                    {(table, (int(i), int(j))): v for (i, j), v in zip(points, arrays, strict=True)}
                )
        return self.comm.bcast(values, root=0)

    def save(self, new: dict) -> None:
        """Write newly solved lattice values, one file per table (rank 0; atomic)."""
        if self.root is None or self.comm.rank != 0 or not new:
            return
        by_table: dict[tuple, list] = {}
        for (table, point), value in new.items():
            by_table.setdefault(table, []).append((point, value))
        for table, items in by_table.items():
            directory = self._directory(table)
            try:
                directory.mkdir(parents=True, exist_ok=True)
                name = f"{self.writer}-{next(_writes)}"
                tmp = directory / f".{name}.tmp"
                with open(tmp, "wb") as f:
                    np.savez(
                        f,
                        points=np.array([p for p, _ in items], dtype=np.int64),
                        values=np.array([v for _, v in items]),
                    )
                    f.flush()
                    os.fsync(f.fileno())
                os.replace(tmp, directory / f"{name}.npz")
            except OSError as err:
                log.warning("cell cache: could not write to %s (%s); going on", directory, err)
