"""A sweep's output directory: who may write into it, the runs' directories and result.json
files, and sweep.csv rebuilt from them."""

from __future__ import annotations

import csv
import fcntl
import io
import json
import os
import re
import tomllib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from mpi4py import MPI

from plantgrowth.base.errors import InputError, on_rank_zero
from plantgrowth.runner.output import atomic_write_text, temporary_path
from plantgrowth.runner.rundir import (
    DirectoryLock,
    changed_keys,
    earlier_outputs,
    remove_earlier_outputs,
)
from plantgrowth.scene import load_scene
from plantgrowth.studies.sweep_file import Run, Sweep, cell, vary_items

RESOLVED, TABLE, RESULT, TABLE_LOCK = "sweep.toml", "sweep.csv", "result.json", ".sweep.lock"
RUN_DIR = re.compile(r"run_\d{4,}")


@contextmanager
def _table_lock(outdir: Path) -> Iterator[None]:
    """Exclusive for the moment it takes to rewrite sweep.toml or sweep.csv."""
    fd = os.open(outdir / TABLE_LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def claim_sweep(sweep: Sweep, outdir: Path, comm: MPI.Comm, shared: bool, overwrite: bool):
    """Collective: lock DIR (rank 0 holds the lock), check what it holds, write sweep.toml and
    the first sweep.csv. InputError on every rank, with nothing changed, if DIR is refused."""
    return on_rank_zero(comm, lambda: _hold(sweep, outdir, shared, overwrite))


def _hold(sweep: Sweep, outdir: Path, shared: bool, overwrite: bool) -> DirectoryLock:
    try:
        outdir.mkdir(parents=True, exist_ok=True)
        lock = DirectoryLock(outdir, shared=shared)
    except OSError as err:
        raise InputError(
            f"cannot write the output directory {outdir}: {err.strerror or err}"
        ) from None
    try:
        _check_directory(sweep, outdir, overwrite)
        with _table_lock(outdir):
            if overwrite:
                _remove_earlier_sweep(outdir)
            if not (outdir / RESOLVED).is_file():
                atomic_write_text(outdir / RESOLVED, sweep.to_toml())
            elif differs := _differences(sweep, outdir):  # an element that started meanwhile
                raise _another_sweep(outdir, differs)
            _write_table(sweep, outdir)
    except BaseException:
        lock.release()
        raise
    return lock


def _check_directory(sweep: Sweep, outdir: Path, overwrite: bool) -> None:
    """InputError unless DIR is new, or holds this sweep (or ``overwrite`` and an earlier one)."""
    if earlier := earlier_outputs(outdir):
        raise InputError(
            f"{outdir} holds a plantgrowth run ({earlier[0].name}, ...), not a sweep: choose "
            "another -o"
        )
    if overwrite:
        return
    if (outdir / TABLE).is_file() and not (outdir / RESOLVED).is_file():
        raise InputError(f"{outdir} holds a {TABLE} that no sweep wrote: choose another -o")
    if (outdir / RESOLVED).is_file() and (differs := _differences(sweep, outdir)):
        raise _another_sweep(outdir, differs)
    for run in sweep.runs:
        check_run_directory(outdir / run.name, run)


def _another_sweep(outdir: Path, differs: str) -> InputError:
    return InputError(
        f"{outdir} holds another sweep ({RESOLVED} differs in {differs}): continue it with its "
        "own sweep file, replace it with --overwrite, or choose another -o"
    )


def _differences(sweep: Sweep, outdir: Path) -> str:
    """What differs between DIR/sweep.toml and the sweep ("" if nothing)."""
    try:
        saved = tomllib.loads((outdir / RESOLVED).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return "everything (it cannot be read as TOML)"
    vary = saved.get("vary") if isinstance(saved.get("vary"), dict) else {}
    saved["vary"] = dict(vary_items(vary, set(sweep.vary)))
    mine = sweep.resolved()
    shown = [f"{k} ({cell(saved.get(k))} there, {cell(mine[k])} here)" for k in ("base", "mode")
             if saved.get(k) != mine[k]]  # fmt: skip
    for key in sorted(saved["vary"].keys() | mine["vary"].keys()):
        there, here = saved["vary"].get(key), mine["vary"].get(key)
        if there != here:
            show = [cell(v) if v is not None else "none" for v in (there, here)]
            shown.append(f"vary.'{key}' ({show[0]} there, {show[1]} here)")
    return ", ".join(shown)


def check_run_directory(run_dir: Path, run: Run) -> None:
    """A run directory of an earlier start must hold this run's scene (or one with a smaller
    time.t_max: the run is extended)."""
    saved = run_dir / "scene.toml"
    if not saved.is_file():
        starting = temporary_path(saved)  # another element's run is writing it
        if run_dir.is_dir() and set(earlier_outputs(run_dir)) - {starting}:
            raise InputError(
                f"{run_dir} holds plantgrowth files but no scene.toml: use --overwrite"
            )
        return
    old = load_scene(saved)
    changed = changed_keys(old, run.scene)
    if changed and (changed != ["time.t_max"] or run.scene.time.t_max < old.time.t_max):
        raise InputError(
            f"{run_dir} ran another scene ({', '.join(changed)} differ): has the base scene "
            "changed since the sweep started? Use --overwrite to start again, or another -o"
        )


def _remove_earlier_sweep(outdir: Path) -> None:
    """Remove what an earlier sweep wrote in DIR, and only that."""
    for run_dir in sorted(outdir.iterdir()):
        if run_dir.is_dir() and RUN_DIR.fullmatch(run_dir.name):
            for name in (RESULT, f".{RESULT}.tmp"):
                (run_dir / name).unlink(missing_ok=True)
            remove_earlier_outputs(run_dir)
            if not any(run_dir.iterdir()):
                run_dir.rmdir()
    for name in (TABLE, RESOLVED):
        for path in (outdir / name, outdir / f".{name}.tmp"):
            path.unlink(missing_ok=True)


def read_result(run_dir: Path) -> dict[str, str]:
    try:
        return json.loads((run_dir / RESULT).read_text())
    except (OSError, ValueError):
        return {}


def _write_table(sweep: Sweep, outdir: Path) -> None:
    """Rebuild sweep.csv from the runs' result.json (the caller holds the table lock)."""
    text = io.StringIO()
    table = csv.DictWriter(text, sweep.columns(), restval="", extrasaction="ignore",
                           lineterminator="\n")  # fmt: skip
    table.writeheader()
    for run in sweep.runs:
        result = read_result(outdir / run.name) or {"status": "pending"}
        table.writerow({"run": run.name, **sweep.cells(run), **result})
    atomic_write_text(outdir / TABLE, text.getvalue())


def update_table(sweep: Sweep, outdir: Path) -> None:
    with _table_lock(outdir):
        _write_table(sweep, outdir)
