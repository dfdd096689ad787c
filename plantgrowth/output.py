"""Run outputs that survive interruption: an XDMF time series and the per-step summary table.

Layout of an output directory::

    fields.xdmf            the time series ParaView opens (rewritten atomically after each step)
    fields.h5              the mesh: /Mesh/geometry, /Mesh/topology
    fields/step_NNNNNN.h5  one file per completed step: the fields, and /state for --resume
    summary.csv            one row per completed step (flushed and fsync'ed)

A step's HDF5 file is written under a temporary name and renamed when complete, and the XDMF
file likewise, so a run killed at any moment (even SIGKILL) leaves every completed step
readable; files of completed steps are never opened for writing again. Data are gathered to
rank 0, which alone writes (Debian's h5py is serial). Only these names are ever removed
(:func:`run_files`): a user's own files in the directory are left alone.
"""

from __future__ import annotations

import csv
import os
import re
from pathlib import Path

import h5py
import numpy as np
from dolfinx import fem
from mpi4py import MPI

from plantgrowth.gather import MeshGather

OUTPUT_FILES = ("fields.xdmf", "fields.h5", "summary.csv", "scene.toml", "run.log")
STEP_DIR = "fields"
_TEMPORARY = tuple(f".{name}.tmp" for name in OUTPUT_FILES)  # a kill during an atomic write
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


def atomic_write_text(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "w") as f:
        f.write(text)
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


def read_state(outdir: Path, step: int) -> dict[str, np.ndarray]:
    """The model state saved with a step (for --resume)."""
    with h5py.File(step_file(outdir, step), "r") as f:
        return {key: f["state"][key][...] for key in f["state"]}


_ATTRIBUTE_TYPES = {1: ("Scalar", 1), 2: ("Vector", 3), 4: ("Tensor", 9)}
"""Block size -> XDMF attribute type and its padded width (2D vectors/tensors padded to 3D)."""


def _pad(values: np.ndarray) -> np.ndarray:
    n, bs = values.shape
    if bs == 2:
        return np.column_stack([values, np.zeros(n)])
    if bs == 4:
        out = np.zeros((n, 9))
        out[:, [0, 1, 3, 4]] = values
        return out
    return values


class FieldSeries:
    """Writes the XDMF time series of a run, one HDF5 file per step.

    Args:
        outdir: the output directory.
        V1: the P1 vector space that numbers the written mesh's nodes.
        functions: P1 (node) or DG0 (cell) functions, written by name at every step.
        resume: continue the series already in ``outdir`` instead of starting it.
    """

    def __init__(
        self, outdir: Path, V1: fem.FunctionSpace, functions: list[fem.Function],
        resume: bool = False,
    ) -> None:  # fmt: skip
        self.outdir = outdir
        self.functions = functions
        self.gather = MeshGather(V1)
        self.comm = V1.mesh.comm
        points, triangles = self.gather.points(), self.gather.triangles()
        self.steps: list[tuple[int, float]] = []
        if self.comm.rank == 0:
            (outdir / STEP_DIR).mkdir(exist_ok=True)
            if resume:
                self.steps = completed_steps(outdir)
            if not self.steps:
                with h5py.File(outdir / "fields.h5", "w") as f:
                    f["Mesh/geometry"] = points
                    f["Mesh/topology"] = triangles.astype(np.int64)
            self.n_nodes, self.n_cells = len(points), len(triangles)
        self.steps = self.comm.bcast(self.steps, root=0)

    @property
    def last_step(self) -> int | None:
        return self.steps[-1][0] if self.steps else None

    def forget_after(self, step: int | None) -> None:
        """Drop the steps after ``step`` from the index (their files get rewritten)."""
        self.steps = [(s, t) for s, t in self.steps if step is not None and s <= step]

    def write(self, step: int, t: float, state: dict[str, np.ndarray] | None) -> None:
        """Write all functions at (step, t) with the model state (given on rank 0)."""
        values = {f.name: self.gather.function(f) for f in self.functions}
        if self.comm.rank != 0:
            return
        path = step_file(self.outdir, step)
        tmp = path.with_name(f".{path.name}.tmp")
        with h5py.File(tmp, "w") as f:
            f.attrs["step"], f.attrs["t"] = step, t
            for name, v in values.items():
                f[name] = _pad(v)
            for key, v in (state or {}).items():
                f[f"state/{key}"] = v
        os.replace(tmp, path)
        self.steps = [(s, tt) for s, tt in self.steps if s < step] + [(step, t)]
        atomic_write_text(self.outdir / "fields.xdmf", self._xml())

    def _xml(self) -> str:
        """XDMF 3: the mesh grid, then a temporal collection with one grid per step."""
        mesh = (
            f'    <Grid Name="mesh" GridType="Uniform">\n'
            f'      <Topology TopologyType="Triangle" NumberOfElements="{self.n_cells}" '
            f'NodesPerElement="3">\n'
            f'        <DataItem Dimensions="{self.n_cells} 3" NumberType="Int" Precision="8" '
            f'Format="HDF">fields.h5:/Mesh/topology</DataItem>\n'
            f"      </Topology>\n"
            f'      <Geometry GeometryType="XY">\n'
            f'        <DataItem Dimensions="{self.n_nodes} 2" Format="HDF">'
            f"fields.h5:/Mesh/geometry</DataItem>\n"
            f"      </Geometry>\n"
            f"    </Grid>\n"
        )
        include = (
            "<xi:include xpointer=\"xpointer(/Xdmf/Domain/Grid[@GridType='Uniform'][1]/"
            '*[self::Topology or self::Geometry])" />'
        )
        grids = []
        for step, t in self.steps:
            attributes = []
            for f in self.functions:
                bs = f.function_space.dofmap.index_map_bs
                kind, width = _ATTRIBUTE_TYPES[bs]
                cell = f.function_space.ufl_element().degree() == 0
                center, n = ("Cell", self.n_cells) if cell else ("Node", self.n_nodes)
                attributes.append(
                    f'        <Attribute Name="{f.name}" AttributeType="{kind}" '
                    f'Center="{center}">\n'
                    f'          <DataItem Dimensions="{n} {width}" Format="HDF">'
                    f"{STEP_DIR}/step_{step:06d}.h5:/{f.name}</DataItem>\n"
                    f"        </Attribute>\n"
                )
            grids.append(
                f'      <Grid Name="step_{step}" GridType="Uniform">\n'
                f"        {include}\n"
                f'        <Time Value="{t!r}" />\n' + "".join(attributes) + "      </Grid>\n"
            )
        return (
            '<?xml version="1.0"?>\n'
            '<Xdmf Version="3.0" xmlns:xi="http://www.w3.org/2001/XInclude">\n'
            "  <Domain>\n" + mesh
            + '    <Grid Name="fields" GridType="Collection" CollectionType="Temporal">\n'
            + "".join(grids)
            + "    </Grid>\n  </Domain>\n</Xdmf>\n"
        )  # fmt: skip


class SummaryWriter:
    """``summary.csv``: one row per completed step, written by rank 0, fsync'ed at once.

    With ``keep_until`` (resume), the rows of steps up to that one are kept, later ones dropped.
    """

    def __init__(
        self, path: Path, columns: list[str], comm: MPI.Comm, keep_until: int | None = None
    ) -> None:
        self.path = path
        self.columns = columns
        self.comm = comm
        if comm.rank == 0:
            kept = []
            if keep_until is not None and path.exists():
                with open(path, newline="") as f:
                    kept = [r for r in csv.DictReader(f) if int(float(r["step"])) <= keep_until]
            text = (
                ",".join(columns)
                + "\n"
                + "".join(",".join(r[c] for c in columns) + "\n" for r in kept)
            )
            atomic_write_text(path, text)

    def write(self, row: dict[str, float]) -> None:
        if self.comm.rank != 0:
            return
        with open(self.path, "a", newline="") as f:
            csv.writer(f).writerow([f"{row[c]:.17g}" for c in self.columns])
            f.flush()
            os.fsync(f.fileno())
