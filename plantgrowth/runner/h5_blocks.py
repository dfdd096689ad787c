"""HDF5 files whose datasets every rank fills with its own block, in parallel, without MPI-IO.

A dataset is either contiguous (float64 state) or compressed (fields: HDF5's byte shuffle, then
deflate, one chunk per rank's block). Every rank first prepares its bytes: a compressed block
is shuffled and deflated by the rank that holds it, so the ranks compress in parallel. Rank 0
then lays the file out alone: the datasets, a placeholder of the right length for every
rank's chunk (:meth:`h5py.h5d.DatasetID.write_direct_chunk`) and the attributes; it
closes the file and sends every rank where its bytes go (the chunk's byte offset, or the
contiguous dataset's offset plus the block's first row). Each rank then writes its bytes there
with ``os.pwrite``: a chunk written this way is a zlib stream of the shuffled bytes, what HDF5's
own filters store (made by libdeflate, faster than the zlib HDF5 calls: the bytes differ, what
they inflate to does not), so any HDF5 reader reads the file as if HDF5 had written it.

What no rank does: gather another rank's values (only the chunks' lengths travel), or open the
file through HDF5's MPI-IO driver, whose collective writes with filters scaled 1.3-1.5x from
1 to 2 ranks on the 1e5-dof tissue (docs/large_tissues.md). The file is written under a
temporary name that rank 0 renames once every rank has written (crash safety as before).

A contiguous dataset carries each rank's rows and the CRC-32 of their bytes as written
(:data:`CHECKSUMS`): no file is fsync'ed, so after a crash of the machine a file may hold some
pages of its new bytes and some of what was there before (the state file is rewritten in
place), and :func:`intact` tells such a file from a whole one.
"""

from __future__ import annotations

import os
import zlib
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
from mpi4py import MPI

from plantgrowth.base.blocks import Block, block_offsets
from plantgrowth.base.deflate import LEVEL, deflate

CHECKSUMS = ("block_rows", "block_crc32")
"""Attributes of a contiguous dataset: the rows ``[start, stop)`` of each rank's block (size, 2)
and the CRC-32 of their bytes as the rank wrote them (size,), 0 for an empty block."""

FIELD_FILTERS = {"compression": "gzip", "compression_opts": LEVEL, "shuffle": True}
"""How field datasets are compressed: gzip after byte shuffling (HDF5's built-in filters, which
every HDF5 reader has), one chunk per rank's block; the chunks' bytes are made by
:mod:`plantgrowth.base.deflate` (the level is recorded, as HDF5 records it, not needed to read)."""


@dataclass(frozen=True)
class Dataset:
    """One dataset of the file: its path, this rank's block, the stored dtype, and whether it
    is compressed (chunked by blocks) or contiguous."""

    name: str
    block: Block
    dtype: np.dtype
    compressed: bool


def temporary_path(path: Path) -> Path:
    """Where an atomic write of ``path`` puts its content before renaming it into place."""
    return path.with_name(f".{path.name}.tmp")


def chunk_rows(total: int, size: int) -> int:
    """Rows of one chunk of a compressed dataset: one rank's block (the first of
    :func:`plantgrowth.base.blocks.block_offsets`, all but the last as long), at least 1."""
    return max(int(block_offsets(total, size)[1]), 1)


def deflated(values: np.ndarray, rows: int) -> memoryview:
    """One chunk of ``rows`` rows (``values`` padded with zeros, as HDF5 stores an edge chunk)
    through HDF5's shuffle filter (the k-th byte of every element together, k = 0..itemsize-1)
    and its deflate filter (a zlib stream: :data:`plantgrowth.base.deflate.deflate`)."""
    values = np.ascontiguousarray(values)
    if len(values) < rows:
        chunk = np.zeros((rows, *values.shape[1:]), dtype=values.dtype)
        chunk[: len(values)] = values
        values = chunk
    shuffled = values.view(np.uint8).reshape(-1, values.dtype.itemsize).T
    return deflate(np.ascontiguousarray(shuffled))


def write_blocks(
    path: Path, datasets: list[Dataset], attrs: dict[str, dict[str, float]], comm: MPI.Comm,
    recycle: bool = False,
) -> None:  # fmt: skip
    """Write the file ``path`` (as :func:`temporary_path`, renamed to ``path`` when complete):
    collective, every rank gives the same datasets in the same order, each with its block;
    ``attrs``: the attributes of the file (``"/"``) or of a group, path -> {name: value}.
    ``recycle``: a file already at the temporary name that :func:`_relaid` can take is
    rewritten in place rather than laid out afresh."""
    tmp = temporary_path(path)
    payloads = [_payload(d, comm.size) for d in datasets]
    written = comm.gather([_written(d, p) for d, p in zip(datasets, payloads, strict=True)])
    offsets = None
    if comm.rank == 0:
        sums = [_checksums(written, i) for i in range(len(datasets))]
        offsets = _relaid(tmp, datasets, attrs, sums) if recycle else None
        if offsets is None:
            offsets = _lay_out(tmp, datasets, attrs, written, sums)
    offsets = comm.bcast(offsets, root=0)
    if any(len(p) for p in payloads):
        fd = os.open(tmp, os.O_WRONLY)
        try:
            for d, p, where in zip(datasets, payloads, offsets, strict=True):
                if len(p):
                    row = d.block.start * _row_bytes(d)
                    os.pwrite(fd, p, where[comm.rank] if d.compressed else where + row)
        finally:
            os.close(fd)
    comm.Barrier()  # every rank's bytes are in the file
    if comm.rank == 0:
        os.replace(tmp, path)
    comm.Barrier()  # a later write of the same name starts after the rename


def intact(dataset: h5py.Dataset) -> bool:
    """Whether every rank's block of a contiguous dataset holds the bytes it wrote (the CRC-32s
    of :data:`CHECKSUMS`); a dataset without them (compressed, or written before them) passes."""
    if not all(name in dataset.attrs for name in CHECKSUMS):
        return True
    values = np.ascontiguousarray(dataset[...])
    row = values.dtype.itemsize * int(np.prod(values.shape[1:], dtype=np.int64))
    data = memoryview(values).cast("B") if values.size else memoryview(b"")
    rows, sums = (dataset.attrs[name] for name in CHECKSUMS)
    return all(
        zlib.crc32(data[start * row : stop * row]) == crc
        for (start, stop), crc in zip(rows.tolist(), sums.tolist(), strict=True)
    )


def whole_file(path: Path) -> bool:
    """Whether ``path`` opens as an HDF5 file and every contiguous dataset in it is
    :func:`intact`."""
    arrays: list[h5py.Dataset] = []
    try:
        with h5py.File(path, "r") as f:
            f.visititems(lambda _, item: arrays.append(item)
                         if isinstance(item, h5py.Dataset) else None)  # fmt: skip
            return all(intact(array) for array in arrays)
    except OSError:
        return False


def _written(d: Dataset, payload: bytes | memoryview) -> tuple[int, int, int, int]:
    """What rank 0 needs of this rank's bytes of a dataset: the chunk's length (compressed),
    or the block's rows and their CRC-32 (contiguous)."""
    if d.compressed:
        return len(payload), 0, 0, 0
    stop = d.block.start + len(d.block.values)
    return 0, d.block.start if len(payload) else stop, stop, zlib.crc32(payload)


def _checksums(written: list[list[tuple]], i: int) -> dict[str, np.ndarray]:
    """The :data:`CHECKSUMS` attributes of dataset i from every rank's :func:`_written`."""
    blocks = [w[i] for w in written]
    rows = np.array([[start, stop] for _, start, stop, _ in blocks], dtype=np.int64)
    return {CHECKSUMS[0]: rows, CHECKSUMS[1]: np.array([b[3] for b in blocks], dtype=np.uint32)}


def _row_bytes(d: Dataset) -> int:
    return int(np.prod(d.block.values.shape[1:], dtype=np.int64)) * np.dtype(d.dtype).itemsize


def _payload(d: Dataset, size: int) -> bytes | memoryview:
    """This rank's bytes of a dataset: its deflated chunk, or its rows as they are stored."""
    values = np.ascontiguousarray(d.block.values, dtype=d.dtype)
    if not len(values):
        return b""
    if d.compressed:
        rows = chunk_rows(d.block.total, size)
        assert d.block.start % rows == 0 and len(values) <= rows, "a block is not one chunk"
        return deflated(values, rows)
    return memoryview(values).cast("B")


def _relaid(
    tmp: Path, datasets: list[Dataset], attrs: dict[str, dict[str, float]],
    sums: list[dict[str, np.ndarray]],
) -> list | None:  # fmt: skip
    """Rank 0: where the datasets' bytes go in the file ``tmp`` if it holds exactly these
    contiguous datasets, shapes and dtypes and these attributes' names under one top-level
    group of another name (an earlier step's state); the group renamed and the attributes
    set, its bytes left for the ranks to overwrite (every row is written). None (the file
    untouched) if it does not: it is then laid out afresh. Rewriting a file in place frees
    and allocates no disk blocks: replacing the older of the two state files cost rank 0
    alone 7 ms a step on the 1e5-dof tissue (8 MB) and 50 ms on an 80 MB file
    (docs/large_tissues.md, "The older state rewritten in place")."""
    groups = {d.name.split("/", 1)[0] for d in datasets}
    if not tmp.is_file() or len(groups) != 1 or any(d.compressed for d in datasets):
        return None
    (group,) = groups
    wanted = {d.name.split("/", 1)[-1]: ((d.block.total, *d.block.values.shape[1:]), d.dtype)
              for d in datasets}  # fmt: skip
    names = {key.rsplit("/", k)[0] for key in wanted for k in range(key.count("/") + 1)}
    try:
        with h5py.File(tmp, "r+") as f:
            tops = list(f)
            old = tops[0] if len(tops) == 1 and isinstance(f[tops[0]], h5py.Group) else None
            if old is None or len(f.attrs) or set(attrs) != {group}:
                return None
            if set(f[old].attrs) != set(attrs[group]):
                return None
            held: dict[str, h5py.Dataset | None] = {}
            f[old].visititems(lambda key, item: held.update(
                {key: item if isinstance(item, h5py.Dataset) else None}
            ))  # fmt: skip
            if set(held) != names or any(
                held[key] is None or held[key].chunks is not None
                or (held[key].shape, held[key].dtype) != shape_dtype
                or any(held[key].attrs.get(name, np.zeros(0)).shape != value.shape
                       for name, value in checks.items())
                for (key, shape_dtype), checks in zip(wanted.items(), sums, strict=True)
            ):  # fmt: skip
                return None
            if old != group:
                f.move(old, group)
            for key, value in attrs[group].items():
                f[group].attrs.modify(key, value)
            for d, checks in zip(datasets, sums, strict=True):
                for name, value in checks.items():
                    f[d.name].attrs.modify(name, value)
            return [f[d.name].id.get_offset() for d in datasets]
    except (OSError, KeyError):  # not a whole HDF5 file (a layout killed mid-way): afresh
        return None


def _lay_out(
    tmp: Path, datasets: list[Dataset], attrs: dict[str, dict[str, float]],
    written: list[list[tuple]], sums: list[dict[str, np.ndarray]],
) -> list:  # fmt: skip
    """Rank 0: the file with every dataset and attribute, each rank's chunks as
    placeholders of their lengths (:func:`_written`), a contiguous dataset's checksums;
    per dataset, where its bytes go (compressed: the byte offset of each rank's chunk;
    contiguous: the dataset's)."""
    size = len(written)
    offsets: list = []
    contiguous = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    contiguous.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)  # its offset exists before any write
    contiguous.set_fill_time(h5py.h5d.FILL_TIME_NEVER)  # every row is written by its rank
    with h5py.File(tmp, "w") as f:
        for i, d in enumerate(datasets):
            tail = d.block.values.shape[1:]
            shape = (d.block.total, *tail)
            if not d.compressed:
                dataset = f.create_dataset(d.name, shape=shape, dtype=d.dtype, dcpl=contiguous)
                offsets.append(dataset.id.get_offset())  # None: no bytes (no rank writes)
                for name, value in sums[i].items():
                    dataset.attrs[name] = value
                continue
            rows = chunk_rows(d.block.total, size)
            dataset = f.create_dataset(
                d.name, shape=shape, dtype=d.dtype, chunks=(rows, *tail), **FIELD_FILTERS
            )
            where = [0] * size
            for rank in range(size):
                if written[rank][i][0]:
                    corner = (rank * rows, *(0,) * len(tail))
                    dataset.id.write_direct_chunk(corner, bytes(written[rank][i][0]))
                    where[rank] = dataset.id.get_chunk_info_by_coord(corner).byte_offset
            offsets.append(where)
        for name, values in attrs.items():
            group = f if name == "/" else f.require_group(name)
            for key, value in values.items():
                group.attrs[key] = value
    return offsets
