"""Collective parallel output (issue 23, item 2): every rank writes its own block of each step's
fields and of the resume state, in the canonical order, and no rank gathers them.

Serial and under mpirun (the file's tests are all in-process and collective). Crash safety and
resume under ``mpirun -n 2`` are tests/test_interruptions.py's ``mpirun2`` cases (SIGKILL of a
2-rank run, every completed step readable, --resume equal to the straight run) and
tests/test_output_economy.py's stopped-before-its-state run, which now go through these writers.
"""

from __future__ import annotations

import zlib
from pathlib import Path

import h5py
import numpy as np
import pytest
from dolfinx import fem, mesh
from mpi4py import MPI

from plantgrowth.base import deflate, gather
from plantgrowth.base.blocks import Block, CanonicalBlocks, block_offsets
from plantgrowth.models.macro.model import MacroModel
from plantgrowth.models.macro.problem import rectangle_mesh
from plantgrowth.runner import h5_blocks, output
from plantgrowth.runner.output import FieldSeries, Schedule, StateFile
from plantgrowth.runner.timeloop import run_model
from plantgrowth.scene import parse_scene

pytestmark = pytest.mark.mpi  # scripts/README.md, "Tests": every test also runs on 2 ranks

WORLD = MPI.COMM_WORLD
ULP32 = 2.0**-23  # one float32 unit in the last place (relative)


def small_mesh(comm: MPI.Comm = WORLD) -> mesh.Mesh:
    """An 7 x 5 rectangle of 70 triangles, unevenly cut so the ranks own unequal parts."""
    return mesh.create_rectangle(comm, [np.array([0.0, 0.0]), np.array([1.4, 1.0])], [7, 5])


def p1_and_dg0(msh: mesh.Mesh) -> tuple[fem.FunctionSpace, fem.Function, fem.Function]:
    """V1, u = (x1 + 10 x2, x1 x2) at the nodes and a DG0 tensor (its midpoint's x1, x2, 1, 2)."""
    V1 = fem.VectorFunctionSpace(msh, ("Lagrange", 1))
    u = fem.Function(V1, name="u")
    u.interpolate(lambda x: np.vstack([x[0] + 10 * x[1], x[0] * x[1]]))
    T = fem.TensorFunctionSpace(msh, ("DG", 0), shape=(2, 2))
    F = fem.Function(T, name="Fg")
    F.interpolate(lambda x: np.vstack([x[0], x[1], np.ones_like(x[0]), 2 * np.ones_like(x[0])]))
    return V1, u, F


def dataset_names(f: h5py.File) -> list[str]:
    """Every dataset's path in an HDF5 file."""
    names: list[str] = []
    f.visititems(lambda key, item: names.append(key) if isinstance(item, h5py.Dataset) else None)
    return names


def shared(path: Path, comm: MPI.Comm = WORLD) -> Path:
    """``path``, created by rank 0, on every rank."""
    if comm.rank == 0:
        path.mkdir()
    comm.Barrier()
    return path


def test_blocks_hold_the_gathered_arrays_cut_at_the_offsets():
    """The ranks' blocks, put end to end, are exactly the arrays gathered in the canonical
    order (values are moved, not computed: bitwise), each block at its rank's offset."""
    V1, u, F = p1_and_dg0(small_mesh())
    blocks, everywhere = CanonicalBlocks(V1), gather.MeshGather(V1, root=None)
    for f in (u, F):
        block = blocks.function(f)
        offsets = block_offsets(block.total, WORLD.size)
        assert block.start == offsets[WORLD.rank]
        assert len(block.values) == offsets[WORLD.rank + 1] - offsets[WORLD.rank] > 0
        np.testing.assert_array_equal(np.concatenate(WORLD.allgather(block.values)),
                                      everywhere.function(f))  # fmt: skip
    np.testing.assert_array_equal(blocks.points, everywhere.points())
    np.testing.assert_array_equal(blocks.triangles, everywhere.triangles())


def test_every_rank_writes_its_own_block_and_nothing_is_gathered(mpi_tmp_path, monkeypatch):
    """A step file and the state: each dataset is written by every rank, each its block (on
    two ranks: two disjoint non-empty parts that cover it), while any gather of MeshGather
    fails; the file holds the gathered arrays (float32 fields: rounded once, so equal to the
    float64 values cast)."""
    V1, u, F = p1_and_dg0(small_mesh())
    outdir = mpi_tmp_path
    series = FieldSeries(outdir, V1, [u, F], Schedule(1, 1))
    state = StateFile(outdir, WORLD)
    written: list[tuple[str, int, int, int]] = []
    payload = h5_blocks._payload

    def recording(d, size):
        written.append((d.name, d.block.start, len(d.block.values), d.block.total))
        return payload(d, size)

    def no_gather(self, values):
        raise AssertionError("a MeshGather gather while writing")

    monkeypatch.setattr(h5_blocks, "_payload", recording)
    monkeypatch.setattr(gather.MeshGather, "_collect", no_gather)
    series.write(0, 0.0)
    state.write(0, 0.0, {"u": series.blocks.function(u)})
    monkeypatch.undo()
    parts = WORLD.allgather(written)
    for name, _, _, total in written:
        rows = sorted((start, n) for part in parts for key, start, n, _ in part if key == name)
        assert len(rows) == WORLD.size and all(n > 0 for _, n in rows), (name, rows)
        assert [s for s, _ in rows] == list(np.cumsum([0] + [n for _, n in rows])[:-1])
        assert sum(n for _, n in rows) == total
    everywhere = gather.MeshGather(V1, root=None)
    u_all, F_all = everywhere.function(u), everywhere.function(F)
    if WORLD.rank == 0:
        with h5py.File(outdir / "fields" / "step_000000.h5", "r") as f:
            np.testing.assert_array_equal(f["u"][:, :2], u_all.astype(np.float32))
            np.testing.assert_array_equal(f["Fg"][:, [0, 1, 3, 4]], F_all.astype(np.float32))
        with h5py.File(outdir / "state.h5", "r") as f:
            np.testing.assert_array_equal(f["step_000000/u"][...], u_all)


def test_state_keeps_the_previous_steps_blocks_and_whole_arrays(mpi_tmp_path):
    """The last two steps saved (state_previous.h5, state.h5), each as written; an array every
    rank holds (Block.whole) is written once, by rank 0."""
    state = StateFile(mpi_tmp_path, WORLD)
    whole = np.arange(12.0).reshape(3, 2, 2)
    split = np.arange(10.0 * WORLD.size)
    for step in (1, 2):
        state.write(step, step * 0.5, {"Fg": Block.whole(step * whole, WORLD),
                                       "x": Block.split(step * split, WORLD)})  # fmt: skip
    assert state.steps() == [1, 2]
    for step in (1, 2):
        saved = state.read(step)
        np.testing.assert_array_equal(saved["Fg"], step * whole)
        np.testing.assert_array_equal(saved["x"], step * split)


def test_each_steps_state_is_written_once_and_a_resume_keeps_its_step(mpi_tmp_path):
    """After every write state.h5 holds the new step alone and state_previous.h5 the step before
    (the file state.h5 was: renamed, not written again); a run resumed from the previous step
    keeps it as the previous one when it writes its next step again; a run started afresh
    leaves no previous state of an earlier run."""

    def write(state, step):
        state.write(step, step * 0.5, {"x": Block.split(step * split, WORLD)})

    def groups(name):
        if not (mpi_tmp_path / name).is_file():
            return []
        with h5py.File(mpi_tmp_path / name, "r") as f:
            return sorted(f)

    split = np.arange(10.0 * WORLD.size)
    state = StateFile(mpi_tmp_path, WORLD)
    for step in (1, 2, 3):
        write(state, step)
    assert (groups("state_previous.h5"), groups("state.h5")) == (["step_000002"], ["step_000003"])
    resumed = StateFile(mpi_tmp_path, WORLD)  # summary.csv lost step 3's row: from step 2
    np.testing.assert_array_equal(resumed.read(2)["x"], 2 * split)
    write(resumed, 3)
    assert resumed.steps() == [2, 3]
    assert (groups("state_previous.h5"), groups("state.h5")) == (["step_000002"], ["step_000003"])
    write(StateFile(mpi_tmp_path, WORLD), 0)  # afresh: no previous step
    assert StateFile(mpi_tmp_path, WORLD).steps() == [0]


def test_the_older_state_file_takes_the_new_step_in_place(mpi_tmp_path, monkeypatch):
    """From the third write on, state.h5 is the file that was state_previous.h5 (the same
    inode), rewritten in place: not laid out afresh (which truncates it, freeing its disk
    blocks), its size that of a fresh file's (the renamed group and the modified attribute
    take no new space), and it reads back as written: every row of every rank overwritten,
    the group and t of the new step."""
    layouts = []
    lay_out = h5_blocks._lay_out
    monkeypatch.setattr(h5_blocks, "_lay_out", lambda *a: layouts.append(1) or lay_out(*a))
    split = np.arange(12.0 * WORLD.size).reshape(-1, 2)
    state = StateFile(mpi_tmp_path, WORLD)
    inodes, sizes = [], []
    for step in range(1, 7):
        whole = np.full(3, -step, float)
        state.write(step, step / 4, {"x": Block.split(step * split, WORLD),
                                     "w": Block.whole(whole, WORLD)})  # fmt: skip
        inodes.append((mpi_tmp_path / "state.h5").stat().st_ino)
        sizes.append((mpi_tmp_path / "state.h5").stat().st_size)
        with h5py.File(mpi_tmp_path / "state.h5", "r") as f:
            assert list(f) == [f"step_{step:06d}"] and f[f"step_{step:06d}"].attrs["t"] == step / 4
            np.testing.assert_array_equal(f[f"step_{step:06d}/x"][...], step * split)
            np.testing.assert_array_equal(f[f"step_{step:06d}/w"][...], np.full(3, -step))
        WORLD.Barrier()  # read by every rank before rank 0 renames it for the next step
    assert len(layouts) == (2 if WORLD.rank == 0 else 0)  # steps 1 and 2 only
    assert inodes[2:] == inodes[:4]  # step k's file was step k - 2's
    assert len(set(sizes)) == 1, sizes
    assert not (mpi_tmp_path / ".state.h5.tmp").exists()


def test_a_state_file_holding_an_older_steps_pages_is_not_resumed_from(mpi_tmp_path):
    """Each contiguous array carries its ranks' rows and the CRC-32 of their bytes. A state
    file rewritten in place that a machine crash left with some rows of the older step it
    was (here the last rank's block of x, as step 1 wrote it) fails them and is not offered
    to --resume: the previous state serves. A file that is not HDF5 at all is skipped, not
    an error; with neither file whole there is no step to resume."""
    split = np.arange(10.0 * WORLD.size).reshape(-1, 2)
    state = StateFile(mpi_tmp_path, WORLD)
    for step in (1, 2, 3):
        state.write(step, step / 2, {"x": Block.split(step * split, WORLD),
                                     "w": Block.whole(np.full(4, step, float), WORLD)})  # fmt: skip
    offsets = block_offsets(len(split), WORLD.size)
    with h5py.File(mpi_tmp_path / "state.h5", "r") as f:
        rows = f["step_000003/x"].attrs["block_rows"]
        np.testing.assert_array_equal(rows, np.column_stack([offsets[:-1], offsets[1:]]))
        assert f["step_000003/w"].attrs["block_rows"].tolist()[0] == [0, 4]
        offset = f["step_000003/x"].id.get_offset()
    assert state.steps() == [2, 3]
    WORLD.Barrier()
    if WORLD.rank == 0:  # the last block's pages as step 1 left them in this file
        start, stop = rows[-1]
        with open(mpi_tmp_path / "state.h5", "r+b") as f:
            f.seek(offset + start * split[0].nbytes)
            f.write((1 * split[start:stop]).tobytes())
    WORLD.Barrier()
    assert StateFile(mpi_tmp_path, WORLD).steps() == [2]
    np.testing.assert_array_equal(StateFile(mpi_tmp_path, WORLD).read(2)["x"], 2 * split)
    WORLD.Barrier()  # every rank has read the file before rank 0 spoils it
    if WORLD.rank == 0:
        (mpi_tmp_path / "state_previous.h5").write_bytes(b"\0" * 4096)
    WORLD.Barrier()
    assert StateFile(mpi_tmp_path, WORLD).steps() == []


def test_a_resume_checks_each_state_file_once(mpi_tmp_path, monkeypatch):
    """A resume asks the saved steps, then reads one: each state file's checksums (every array
    read whole) are checked once for both, on rank 0 only; after a write the files are new, so
    the next question checks them again."""
    checked = []
    whole = output.whole_file
    monkeypatch.setattr(output, "whole_file", lambda path: checked.append(path.name) or whole(path))
    split = np.arange(8.0 * WORLD.size)
    state = StateFile(mpi_tmp_path, WORLD)
    for step in (1, 2):
        state.write(step, step / 2, {"x": Block.split(step * split, WORLD)})
    resumed = StateFile(mpi_tmp_path, WORLD)
    assert resumed.steps() == [1, 2]
    np.testing.assert_array_equal(resumed.read(1)["x"], split)
    files = ["state_previous.h5", "state.h5"]
    assert checked == (files if WORLD.rank == 0 else [])
    resumed.write(2, 1.0, {"x": Block.split(4 * split, WORLD)})
    assert resumed.steps() == [1, 2]
    np.testing.assert_array_equal(resumed.read(2)["x"], 4 * split)
    assert checked == (2 * files if WORLD.rank == 0 else [])


def test_a_state_of_new_shapes_or_a_broken_leftover_is_laid_out_afresh(mpi_tmp_path):
    """The older file is not rewritten in place where the new step's arrays differ from its
    own (more rows, another key, another dtype) or where a killed write left bytes that are
    not an HDF5 file at the temporary name: the new file then holds exactly the new arrays."""
    state = StateFile(mpi_tmp_path, WORLD)
    base = np.arange(8.0 * WORLD.size)
    steps = [
        {"x": base},
        {"x": 2 * base},
        {"x": np.arange(9.0 * WORLD.size)},  # more rows
        {"x": 3 * base, "y": base[:2]},  # another key
        {"x": (4 * base).astype(np.int64), "y": base[:2]},  # another dtype
        {"x": 5 * base, "y": base[:2]},
    ]
    for step, arrays in enumerate(steps):
        if step == 5 and WORLD.rank == 0:  # a leftover of a killed write, not HDF5
            (mpi_tmp_path / "state_previous.h5").write_bytes(b"not hdf5" * 100)
        WORLD.Barrier()
        state.write(step, float(step), {k: Block.split(v, WORLD) for k, v in arrays.items()})
        saved = state.read(step)
        WORLD.Barrier()  # read by every rank before rank 0 renames it for the next step
        assert set(saved) == set(arrays), step
        for key, values in arrays.items():
            assert saved[key].dtype == values.dtype, (step, key)
            np.testing.assert_array_equal(saved[key], values, err_msg=f"{step} {key}")


SCENE = {
    "tissue": {"h": 0.35, "H": 1.0},
    "accuracy": {"cell_resolution": 1, "cell_tolerance": 0.0},
    "growth": {"law": "stress", "eta": {"from": 0.5, "to": 2.0}},
    "time": {"t_max": 2.0},
}


@pytest.mark.skipif(WORLD.size == 1, reason="compares a distributed run with a serial one")
def test_distributed_files_equal_the_serial_run_files(mpi_tmp_path):
    """The same scene on COMM_WORLD and on COMM_SELF (each rank its own run): fields.h5's
    meshes are equal (the canonical order does not depend on the ranks), every step file's
    datasets and the state equal the serial ones without any reordering, to the parallel
    solve's round-off (LU: ~1e-14 relative, measured) carried into float32 (at most one
    rounding flip: 2 ulp of the dataset's largest entry) and float64 (1e-10 relative); the
    kept LU factors' floor (the round-off a fresh solve left) is round-off in both."""
    sc = parse_scene(SCENE)
    both = shared(mpi_tmp_path / "both")
    run_model(MacroModel(sc, rectangle_mesh(sc, WORLD), WORLD), sc, both, WORLD)
    alone = mpi_tmp_path / f"alone_{WORLD.rank}"
    alone.mkdir()
    run_model(MacroModel(sc, rectangle_mesh(sc, MPI.COMM_SELF), MPI.COMM_SELF), sc, alone,
              MPI.COMM_SELF)  # fmt: skip
    if WORLD.rank != 0:
        return
    names = [p.relative_to(alone) for p in sorted((alone / "fields").glob("*.h5"))]
    assert len(names) == 3 and names == [p.relative_to(both) for p in
                                         sorted((both / "fields").glob("*.h5"))]  # fmt: skip
    with h5py.File(both / "fields.h5", "r") as a, h5py.File(alone / "fields.h5", "r") as b:
        np.testing.assert_array_equal(a["Mesh/topology"][...], b["Mesh/topology"][...])
        np.testing.assert_allclose(a["Mesh/geometry"][...], b["Mesh/geometry"][...], atol=1e-14)
    for name in [*names, Path("state.h5"), Path("state_previous.h5")]:
        with h5py.File(both / name, "r") as a, h5py.File(alone / name, "r") as b:
            datasets = dataset_names(b)
            assert datasets
            for key in datasets:
                x, y = a[key][...], b[key][...]
                assert x.shape == y.shape and x.dtype == y.dtype, key
                if key.endswith("lu_floor"):  # the residual a fresh LU left: round-off, whose
                    # value depends on the ranks' factorization (5.5e-15 / 6.7e-15 measured),
                    # so each run's must be round-off, not the other's
                    assert x.max() < 1e-12 and y.max() < 1e-12, (key, x, y)
                    continue
                if key.endswith(("lu_Fg", "lu_C")):  # what the kept factors were made from:
                    continue  # serially an earlier step's, under mpirun this step's (FactorReuse)
                scale = max(np.abs(y).max(), 1e-300)
                tolerance = 2 * ULP32 * scale if y.dtype == np.float32 else 1e-10 * scale
                np.testing.assert_allclose(x, y, rtol=0, atol=tolerance, err_msg=str(key))


@pytest.mark.parametrize("use_libdeflate", [True, False])
def test_a_deflated_chunk_inflates_to_hdf5s_own_and_reads_back(
    tmp_path, monkeypatch, use_libdeflate
):
    """The bytes a rank writes for its chunk (shuffle, then deflate; libdeflate, or zlib where it
    is missing) inflate to what HDF5's own filters store for the same chunk, an edge chunk
    (padded) included, and HDF5 reads a file made of them as the values: any HDF5 reader does."""
    compressor = deflate.Deflater(use_libdeflate=use_libdeflate)
    assert compressor.library == ("libdeflate" if use_libdeflate else "zlib")
    monkeypatch.setattr(h5_blocks, "deflate", compressor)
    values = (np.arange(21.0).reshape(7, 3) ** 1.5).astype(np.float32)
    with h5py.File(tmp_path / "h.h5", "w") as f:
        f.create_dataset("x", data=values, chunks=(4, 3), **h5_blocks.FIELD_FILTERS)
        ours = f.create_dataset("y", shape=(7, 3), dtype=np.float32, chunks=(4, 3),
                                **h5_blocks.FIELD_FILTERS)  # fmt: skip
        for start in (0, 4):
            chunk = bytes(h5_blocks.deflated(values[start : start + 4], 4))
            _, raw = f["x"].id.read_direct_chunk((start, 0))
            assert zlib.decompress(chunk) == zlib.decompress(raw), start
            ours.id.write_direct_chunk((start, 0), chunk)
    with h5py.File(tmp_path / "h.h5", "r") as f:
        np.testing.assert_array_equal(f["y"][...], values)


def test_a_rank_without_rows_writes_nothing_and_the_file_is_whole(mpi_tmp_path):
    """Datasets of one row (the other ranks' blocks empty), compressed and contiguous, and an
    empty one: read back equal on every rank count; attributes as laid out."""
    one = np.array([[1.5, -2.0]])
    datasets = [
        h5_blocks.Dataset("a/x", Block.split(one, WORLD), np.dtype(np.float32), True),
        h5_blocks.Dataset("a/y", Block.split(one, WORLD), np.dtype(np.float64), False),
        h5_blocks.Dataset("e", Block.split(np.zeros((0, 3)), WORLD), np.dtype(np.float64), False),
    ]
    path = mpi_tmp_path / "one.h5"
    h5_blocks.write_blocks(path, datasets, {"/": {"step": 3}, "a": {"t": 0.5}}, WORLD)
    with h5py.File(path, "r") as f:
        np.testing.assert_array_equal(f["a/x"][...], one.astype(np.float32))
        np.testing.assert_array_equal(f["a/y"][...], one)
        assert f["e"].shape == (0, 3) and f.attrs["step"] == 3 and f["a"].attrs["t"] == 0.5
    assert not (mpi_tmp_path / ".one.h5.tmp").exists()
