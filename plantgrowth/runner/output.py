"""Run outputs that survive interruption: XDMF time series, the resume state and the summary.

Layout of an output directory::

    fields.xdmf            the fine mesh's time series ParaView opens (rewritten atomically)
    coarse.xdmf            the coarse grid's time series (macro E_hom; only if one is written)
    cells.xdmf             micro runs: the cells' mid-line outlines (2-node lines) with u at
                           their vertices, cell_id per line (ParaView: Warp By Vector)
    fields.h5              the meshes: /Mesh/{geometry,topology}, /CoarseMesh/{geometry,topology},
                           /Outlines/{geometry,topology}
    fields/step_NNNNNN.h5  one file per written step: the fields, coarse ones under /coarse,
                           outline ones under /outlines
    state.h5               the model state after the last completed step (float64, --resume)
    state_previous.h5      the model state after the step before it
    summary.csv            one row per completed step (flushed and fsync'ed)
    cells.csv              micro runs: one row per biological cell and written step

Fields are written at t = 0, every ``output.every``-th step and at the last step
(:class:`Schedule`), in ``output.precision`` (float32 by default: what ParaView's XDMF reader
loads) with gzip and shuffle filters; the state, written after every step, keeps float64 so
that a resumed run continues exactly. Every file is written under a temporary name and renamed
when complete, so a run killed at any moment (even SIGKILL) leaves every written step readable.
Step files and state are written by all ranks together (issue 23, item 2): each rank compresses
and writes its block of the canonical order (:mod:`plantgrowth.base.blocks`) into a file rank 0
lays out (:mod:`plantgrowth.runner.h5_blocks`), the same arrays whatever the ranks, nothing
gathered to one rank; rank 0 writes the XDMF indexes, CSVs and meshes. Only these names are
ever removed (:func:`run_files`).
"""

from __future__ import annotations

import csv
import logging
import os
import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
from dolfinx import fem
from mpi4py import MPI

from plantgrowth.base.blocks import Block, CanonicalBlocks
from plantgrowth.models.step import SideMesh
from plantgrowth.runner.h5_blocks import Dataset, temporary_path, whole_file, write_blocks
from plantgrowth.runner.xdmf import (
    ATTRIBUTE_TYPES,
    STEP_DIR,
    Attribute,
    IndexMesh,
    grid_xml,
    pad,
    series_xml,
)

log = logging.getLogger("plantgrowth")

PREVIOUS_STATE = "state_previous.h5"
"""The state of the step before state.h5's (:class:`StateFile`)."""
OUTPUT_FILES = (
    "fields.xdmf", "coarse.xdmf", "cells.xdmf", "fields.h5", "state.h5", PREVIOUS_STATE,
    "summary.csv", "cells.csv", "scene.toml", "run.log",
)  # fmt: skip
# a kill during an atomic write leaves these
_TEMPORARY = tuple(temporary_path(Path(name)).name for name in OUTPUT_FILES)
_STEP_FILE = re.compile(r"\.?step_\d{6,}\.h5(\.tmp)?")  # a step file or its temporary name


def run_files(directory: Path) -> list[Path]:
    """The files of one run's layout that exist in ``directory`` (nothing else is listed)."""
    found = [directory / n for n in OUTPUT_FILES + _TEMPORARY if (directory / n).is_file()]
    steps = directory / STEP_DIR
    if steps.is_dir():
        found += sorted(p for p in steps.iterdir() if _STEP_FILE.fullmatch(p.name))
    return found


def remove_run_files(directory: Path) -> None:
    """Remove :func:`run_files`, then the step directory if that leaves it empty."""
    for path in run_files(directory):
        path.unlink(missing_ok=True)
    if (directory / STEP_DIR).is_dir() and not any((directory / STEP_DIR).iterdir()):
        (directory / STEP_DIR).rmdir()


def prepare_directory(directory: Path, comm: MPI.Comm, keep: bool = False) -> None:
    """Create the output directory; unless ``keep``, remove the files of an earlier run there
    (:func:`run_files` only).

    Raises OSError (on every rank) if the directory cannot be created or written.
    """
    error = None
    if comm.rank == 0:
        try:
            directory.mkdir(parents=True, exist_ok=True)
            if not keep:
                remove_run_files(directory)
            probe = directory / ".write-test"
            probe.write_text("")
            probe.unlink()
        except OSError as err:
            error = f"cannot write the output directory {directory}: {err.strerror or err}"
    error = comm.bcast(error, root=0)
    if error:
        raise OSError(error)


def atomic_write_text(path: Path, text: str, durable: bool = True) -> None:
    """Write ``text`` under a temporary name and rename it into place (a killed process leaves
    the old or the new file); ``durable``: fsync'ed before the rename (also a power loss)."""
    tmp = temporary_path(path)
    with open(tmp, "w") as f:
        f.write(text)
        if durable:
            f.flush()
            os.fsync(f.fileno())
    os.replace(tmp, path)


def step_file(outdir: Path, step: int) -> Path:
    return outdir / STEP_DIR / f"step_{step:06d}.h5"


def completed_steps(outdir: Path) -> list[tuple[int, float]]:
    """(step, t) of every completed step file, in order."""
    steps = []
    for path in sorted((outdir / STEP_DIR).glob("step_*.h5")):
        with h5py.File(path, "r") as f:
            steps.append((int(f.attrs["step"]), float(f.attrs["t"])))
    return steps


def last_summary_step(path: Path) -> int | None:
    """The step of the last row of a summary.csv (None if it has no row)."""
    if not path.exists():
        return None
    with open(path, newline="") as f:
        steps = [int(float(row["step"])) for row in csv.DictReader(f) if row.get("step")]
    return steps[-1] if steps else None


@contextmanager
def _atomic_h5(path: Path) -> Iterator[h5py.File]:
    """An HDF5 file written by this rank under a temporary name and renamed into place when
    complete."""
    tmp = temporary_path(path)
    with h5py.File(tmp, "w") as f:
        yield f
    os.replace(tmp, path)


@dataclass(frozen=True)
class Schedule:
    """The steps whose fields are written: t = 0, every ``every``-th step and the last one."""

    every: int
    n_steps: int

    def __contains__(self, step: int) -> bool:
        return step % self.every == 0 or step == self.n_steps


class StateFile:
    """``state.h5`` and ``state_previous.h5``: what --resume needs to continue after either of
    the last two completed steps, in float64, one group ``step_NNNNNN`` in each file.

    After every step ``state.h5`` is renamed to ``state_previous.h5`` and the new step's state
    written as ``state.h5`` (atomically), so each step's arrays are written once: a file of both
    steps, rewritten whole after every step, wrote the previous step's arrays a second time
    (160 MB a step on the organ scene, 0.43 s of a 2-rank step; docs/large_tissues.md). Two
    steps, not one: a step's summary row is written before its state, so the newest state's
    row exists, and the previous state still serves if summary.csv lost its last row; a kill
    between the rename and the new file leaves the previous state, one step behind. The older
    state is not deleted: it is renamed to the new file's temporary name, and the new step is
    written into its bytes where its arrays have the same shapes (``write_blocks``'s
    ``recycle``), so no step frees and allocates its disk blocks (on rank 0 alone: 7 ms a step
    on the 1e5-dof tissue). Nothing is fsync'ed, so a crash of the machine may leave a file
    rewritten in place with some of the older step's pages: every array carries its blocks'
    CRC-32s, and a file that fails them is not resumed from (:meth:`_saved`). Written
    collectively: every rank writes its blocks of the arrays.
    """

    def __init__(self, outdir: Path, comm: MPI.Comm) -> None:
        self.path = outdir / "state.h5"
        self.previous_path = outdir / PREVIOUS_STATE
        self.comm = comm
        self._kept: Path | None = None  # the file whose step the next write keeps as previous
        self._offered: dict[int, Path] | None = None  # rank 0: _saved()'s, until a write

    def write(self, step: int, t: float, state: dict[str, Block]) -> None:
        """Save the state of (step, t): collective, every rank gives its blocks (the same keys
        in the same order on every rank); the step written or read last becomes the previous
        one (none before the first write of a run started afresh)."""
        self._offered = None
        if self.comm.rank == 0:
            if self._kept == self.path and self.path.is_file():
                if self.previous_path.is_file():  # its disk blocks take the new step
                    os.replace(self.previous_path, temporary_path(self.path))
                os.replace(self.path, self.previous_path)
            elif self._kept is None:
                self.previous_path.unlink(missing_ok=True)
        group = f"step_{step:06d}"
        datasets = [Dataset(f"{group}/{key}", block, block.values.dtype, False)
                    for key, block in state.items()]  # fmt: skip
        write_blocks(self.path, datasets, {group: {"t": t}}, self.comm, recycle=True)
        self._kept = self.path

    def _saved(self) -> dict[int, Path]:
        """Rank 0: the steps whose state is saved and the file of each (state.h5's first). A
        file that is not a :func:`~plantgrowth.runner.h5_blocks.whole_file` (a crash of the
        machine before its bytes reached the disk) is not offered: the other one serves. Found
        once until the next write: a resume's :meth:`steps` and :meth:`read` check each file's
        checksums once (every array read whole: 80 MB a file on the organ scene)."""
        if self._offered is not None:
            return self._offered
        saved: dict[int, Path] = {}
        for path in (self.previous_path, self.path):
            if not path.is_file():
                continue
            if not whole_file(path):
                log.warning("%s does not hold what its step wrote (a crash of the machine before "
                            "it reached the disk?): --resume does not use it", path)  # fmt: skip
                continue
            with h5py.File(path, "r") as f:
                saved |= {int(name.removeprefix("step_")): path for name in f}
        self._offered = saved
        return saved

    def steps(self) -> list[int]:
        """The steps whose state is saved, on every rank."""
        steps = sorted(self._saved()) if self.comm.rank == 0 else []
        return self.comm.bcast(steps, root=0)

    def read(self, step: int) -> dict[str, np.ndarray]:
        """The state saved with ``step`` (global arrays, read on every rank); the next
        :meth:`write` keeps it as the previous step."""
        path = self.comm.bcast(self._saved()[step] if self.comm.rank == 0 else None, root=0)
        with h5py.File(path, "r") as f:
            group = f[f"step_{step:06d}"]
            state = {key: group[key][...] for key in group}
        self._kept = path
        return state


class FieldSeries:
    """Writes the XDMF time series of a run, one HDF5 file per written step.

    Args:
        outdir: the output directory.
        V1: the P1 vector space that numbers the written mesh's nodes.
        functions: P1 (node) or DG0 (cell) functions, written by name.
        schedule: the steps to write.
        precision: "float32" (what ParaView's XDMF reader loads) or "float64".
        side: fields on a second mesh (:class:`SideMesh`: macro ``coarse.xdmf``, micro
            ``cells.xdmf``), or None; one without fields is not written.
        keep_until: resume: keep the steps already written up to this one that are on the
            schedule (files of the others are removed); None starts the series afresh.
    """

    def __init__(
        self, outdir: Path, V1: fem.FunctionSpace, functions: list[fem.Function],
        schedule: Schedule, precision: str = "float32", side: SideMesh | None = None,
        keep_until: int | None = None,
    ) -> None:  # fmt: skip
        self.outdir = outdir
        self.functions = functions
        self.schedule = schedule
        self.dtype = np.dtype(precision)
        self.side = side if side is not None and side.fields else None
        self.comm = V1.mesh.comm
        self.blocks = CanonicalBlocks(V1)
        points, triangles = self.blocks.points, self.blocks.triangles
        self.steps: list[tuple[int, float]] = []
        self._grids: dict[tuple[str, int, float], str] = {}  # (index, step, t) -> its grid
        if self.comm.rank == 0:
            self._write_meshes(points, triangles)
            self.indexes = {"fields.xdmf": self._fine_index(points, triangles)}
            if self.side is not None:
                self.indexes[self.side.index] = self._side_index()
            self._keep(keep_until)
        self.comm.Barrier()  # the step directory exists before any rank writes into it

    def _write_meshes(self, points: np.ndarray, triangles: np.ndarray) -> None:
        (self.outdir / STEP_DIR).mkdir(exist_ok=True)
        path = self.outdir / "fields.h5"
        with _atomic_h5(path) as f:
            f["Mesh/geometry"] = points
            f["Mesh/topology"] = triangles.astype(np.int64)
            if self.side is not None:
                f[f"{self.side.group}/geometry"] = self.side.points
                f[f"{self.side.group}/topology"] = self.side.cells.astype(np.int64)

    def _fine_index(
        self, points: np.ndarray, triangles: np.ndarray
    ) -> tuple[IndexMesh, list[Attribute]]:
        """The fine mesh and its attributes (fields.xdmf)."""
        n_nodes, n_cells = len(points), len(triangles)
        attributes = []
        for f in self.functions:
            kind, width = ATTRIBUTE_TYPES[f.function_space.dofmap.index_map_bs]
            cell = f.function_space.ufl_element().degree() == 0
            center, n = ("Cell", n_cells) if cell else ("Node", n_nodes)
            attributes.append(
                Attribute(f.name, f.name, kind, center, (n, width), self.dtype.itemsize)
            )
        return IndexMesh("Mesh", n_nodes, n_cells), attributes

    def _side_index(self) -> tuple[IndexMesh, list[Attribute]]:
        """The second mesh and its attributes (coarse.xdmf or cells.xdmf)."""
        side, size = self.side, self.dtype.itemsize
        n_nodes, (n_cells, k) = len(side.points), side.cells.shape
        attributes = []
        for name, (center, components) in side.fields.items():
            kind, width = ATTRIBUTE_TYPES[components]
            n = n_nodes if center == "Node" else n_cells
            attributes.append(
                Attribute(name, f"{side.prefix}/{name}", kind, center, (n, width), size)
            )
        return IndexMesh(side.group, n_nodes, n_cells, k), attributes

    def _keep(self, keep_until: int | None) -> None:
        """Index the written steps to keep, then remove the files of the others."""
        on_disk = completed_steps(self.outdir)
        last = -1 if keep_until is None else keep_until
        self.steps = [(s, t) for s, t in on_disk if s <= last and s in self.schedule]
        self._write_index()
        kept = {s for s, _ in self.steps}
        for step, _ in on_disk:
            if step not in kept:
                step_file(self.outdir, step).unlink()

    def write(self, step: int, t: float) -> None:
        """Write all fields at (step, t): collective, every rank its blocks of each field; the
        side mesh's fields, which every rank holds whole, cut into the same blocks."""
        blocks = {f.name: self.blocks.function(f) for f in self.functions}
        for name, (_, components) in self.side.fields.items() if self.side else ():
            v = np.reshape(self.side.values[name], (-1, components))
            blocks[f"{self.side.prefix}/{name}"] = Block.split(v, self.comm)
        datasets = [
            Dataset(name, Block(pad(block.values, self.dtype), block.start, block.total),
                    self.dtype, True)  # fmt: skip
            for name, block in blocks.items()
        ]  # fmt: skip
        attrs = {"/": {"step": step, "t": t}}
        write_blocks(step_file(self.outdir, step), datasets, attrs, self.comm)
        if self.comm.rank != 0:
            return
        self.steps = [(s, tt) for s, tt in self.steps if s < step] + [(step, t)]
        self._write_index()

    def _write_index(self) -> None:
        """fields.xdmf (and coarse.xdmf or cells.xdmf) for the steps written so far, each
        replaced atomically (a step's grid is formatted once). Not fsync'ed: the step files
        are the record, and a resumed run writes the index again from those on disk."""
        for name, (mesh, attributes) in self.indexes.items():
            for s, t in self.steps:
                if (name, s, t) not in self._grids:
                    self._grids[name, s, t] = grid_xml(attributes, s, t)
            grids = [self._grids[name, s, t] for s, t in self.steps]
            atomic_write_text(self.outdir / name, series_xml(mesh, grids), durable=False)


class SummaryWriter:
    """A CSV of rows keyed by ``step``, written by rank 0, fsync'ed at once: ``summary.csv``
    (one row per completed step) and ``cells.csv`` (micro: one row per cell and written step).

    With ``keep_until`` (resume), the rows of steps up to that one are kept (and, given a
    ``schedule``, only those of its steps), later ones dropped.
    """

    def __init__(
        self, path: Path, columns: list[str], comm: MPI.Comm, keep_until: int | None = None,
        schedule: Schedule | None = None,
    ) -> None:  # fmt: skip
        self.path = path
        self.columns = columns
        self.comm = comm
        self.kept: list[dict[str, str]] = []  # rank 0: the rows kept from before a resume
        if comm.rank == 0:
            kept = []
            if keep_until is not None and path.exists():
                with open(path, newline="") as f:
                    kept = [r for r in csv.DictReader(f) if _kept(r, columns, keep_until, schedule)]
            text = (
                ",".join(columns)
                + "\n"
                + "".join(",".join(r[c] for c in columns) + "\n" for r in kept)
            )
            atomic_write_text(path, text)
            self.kept = kept

    def kept_max(self, column: str) -> float:
        """Collective: the largest value of a column in the rows kept (0 without rows)."""
        largest = max((float(row[column]) for row in self.kept), default=0.0)
        return self.comm.bcast(largest, root=0)

    def write(self, row: dict[str, float]) -> None:
        self.write_rows([row])

    def write_rows(self, rows: list[dict[str, float]]) -> None:
        """Append the rows (rank 0; the others pass through) in one write."""
        if self.comm.rank != 0:
            return
        with open(self.path, "a", newline="") as f:
            csv.writer(f).writerows([f"{row[c]:.17g}" for c in self.columns] for row in rows)
            f.flush()
            os.fsync(f.fileno())


def _kept(row: dict, columns: list[str], last: int, schedule: Schedule | None) -> bool:
    """A complete row (a kill can cut the last one short) of a step to keep on resume."""
    if any(row.get(c) in (None, "") for c in columns):
        return False
    step = int(float(row["step"]))
    return step <= last and (schedule is None or step in schedule)
