"""Who may write into an output directory: one run at a time, never over an earlier run unless
asked, and a resumed run only with its own scene (or a larger ``time.t_max``, which extends it).

A run holds ``DIR/.plantgrowth.lock``: an exclusive ``flock`` that rank 0 keeps for the whole
run, in a file that names the holder (host, pid, start time, command) for the message another
run gets. The kernel drops the lock when the holder ends, however it ends (even SIGKILL), so a
killed run never blocks a later one; the file it leaves behind is only read for that message.

"What plantgrowth wrote" is the fixed layout of :func:`plantgrowth.runner.output.run_files` in the
directory and in ``macro/``, ``micro/`` (``model = "both"``) and ``nx<N>/{macro,micro}`` plus
``compare.csv`` (``compare``); nothing else is ever removed.
"""

from __future__ import annotations

import fcntl
import json
import os
import re
import socket
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

from plantgrowth.base.errors import InputError, on_rank_zero
from plantgrowth.runner.output import remove_run_files, run_files
from plantgrowth.scene import Scene, load_scene


@dataclass(frozen=True)
class Options:
    """How the messages name a run's options: the CLI's flags or the Python API's arguments."""

    overwrite: str
    resume: str
    resume_at: str  # the option with the run's directory, ``{}``


CLI_OPTIONS = Options("--overwrite", "--resume", "--resume {}")
API_OPTIONS = Options("overwrite=True", "resume=True", "resume=True (outdir {})")

LOCK_NAME = ".plantgrowth.lock"
COMPARE_TABLE = "compare.csv"
_NX_DIR = re.compile(r"nx\d+")


def _run_directories(directory: Path) -> list[Path]:
    """The directories a run or a comparison writes one run's layout into, deepest first."""
    nested = [d for d in sorted(directory.glob("nx*")) if _NX_DIR.fullmatch(d.name) and d.is_dir()]
    runs = [sub / side for sub in [*nested, directory] for side in ("macro", "micro")]
    return [d for d in runs if d.is_dir()] + [directory]


def earlier_outputs(directory: Path) -> list[Path]:
    """Every file an earlier run or comparison wrote in ``directory`` (and nothing else)."""
    found = [f for d in _run_directories(directory) for f in run_files(d)]
    table = directory / COMPARE_TABLE
    return found + ([table] if table.is_file() else [])


def remove_earlier_outputs(directory: Path) -> None:
    """Remove :func:`earlier_outputs`, then the run directories that this leaves empty."""
    (directory / COMPARE_TABLE).unlink(missing_ok=True)
    for d in _run_directories(directory):
        remove_run_files(d)
        if d != directory and not any(d.iterdir()):
            d.rmdir()
        if _NX_DIR.fullmatch(d.parent.name) and d.parent.is_dir() and not any(d.parent.iterdir()):
            d.parent.rmdir()


class DirectoryLock:
    """The exclusive lock of one output directory, held by this process until :meth:`release`.

    ``shared``: a lock that other shared holders may hold too (the elements of a job array
    sharing a sweep's directory), never together with an exclusive one; it leaves the file.
    """

    def __init__(self, directory: Path, shared: bool = False) -> None:
        self.path = directory / LOCK_NAME
        self.shared = shared
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, (fcntl.LOCK_SH if shared else fcntl.LOCK_EX) | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.pread(fd, 4096, 0).decode(errors="replace")
                os.close(fd)
                raise InputError(
                    f"{directory} is in use by another plantgrowth run ({_describe(holder)}): "
                    "one run per output directory; wait for it to end or choose another -o"
                ) from None
            except OSError:
                os.close(fd)
                raise
            if _same_file(fd, self.path):
                break
            os.close(fd)  # the holder removed the file between our open and flock: again
        info = {"host": socket.gethostname(), "pid": os.getpid(), "command": " ".join(sys.argv),
                "started": time.strftime("%Y-%m-%d %H:%M:%S")}  # fmt: skip
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps(info).encode(), 0)
        self.fd: int | None = fd

    def release(self) -> None:
        """Remove the lock file (while still holding it; not a shared one, which other holders
        may still use) and drop the lock."""
        if self.fd is not None:
            if not self.shared:
                self.path.unlink(missing_ok=True)
            os.close(self.fd)
            self.fd = None


def _same_file(fd: int, path: Path) -> bool:
    try:
        return os.path.samestat(os.fstat(fd), os.stat(path))
    except FileNotFoundError:
        return False


def _describe(holder: str) -> str:
    try:
        info = json.loads(holder)
        return (
            f"pid {info['pid']} on host {info['host']}, started {info['started']}: "
            f"{info['command']}"
        )
    except (ValueError, KeyError, TypeError):
        return "a run that is starting"


def claim(
    directory: Path, comm: MPI.Comm, resume: bool = False, overwrite: bool = False,
    options: Options = CLI_OPTIONS,
) -> DirectoryLock | None:  # fmt: skip
    """Collective: create and lock ``directory`` for this run (rank 0 holds the lock and gets
    it back; other ranks get None). A new run refuses a directory that holds an earlier run's
    files unless ``overwrite``, which removes those files and only those; the message names
    the options as ``options`` do.

    Raises:
        InputError: on every rank: the directory is in use, holds an earlier run, or cannot be
            written. Nothing is changed then.
    """
    return on_rank_zero(comm, lambda: _claim(directory, resume, overwrite, options))


def _claim(directory: Path, resume: bool, overwrite: bool, options: Options) -> DirectoryLock:
    try:
        directory.mkdir(parents=True, exist_ok=True)
        lock = DirectoryLock(directory)
    except OSError as err:
        raise InputError(
            f"cannot write the output directory {directory}: {err.strerror or err}"
        ) from None
    try:
        earlier = [] if resume else earlier_outputs(directory)
        if earlier and not overwrite:
            names = [str(p.relative_to(directory)) for p in earlier]
            shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
            raise InputError(
                f"{directory} holds an earlier run ({shown}): use {options.overwrite} to "
                f"replace it (removes only plantgrowth's own files), "
                f"{options.resume_at.format(directory)} to continue it, or another output "
                "directory"
            )
        if earlier:
            remove_earlier_outputs(directory)
    except BaseException:
        lock.release()
        raise
    return lock


def check_resumable(directory: Path, scene: Scene, options: Options = CLI_OPTIONS) -> bool:
    """Whether ``scene`` extends the run in ``directory`` (a larger ``time.t_max``, the only change
    allowed); raise InputError naming the keys (and the option as ``options`` do) if it changes
    anything else."""
    saved_path = directory / "scene.toml"
    resume = options.resume_at.format(directory)
    if not saved_path.is_file():
        raise InputError(f"{resume}: no scene.toml there, so no run to resume")
    saved = load_scene(saved_path)
    changed = changed_keys(saved, scene)
    if not changed:
        return False
    if changed == ["time.t_max"] and scene.time.t_max > saved.time.t_max:
        return True
    if changed == ["time.t_max"]:
        raise InputError(
            f"{resume}: time.t_max = {scene.time.t_max:g} is smaller than the run's "
            f"{saved.time.t_max:g}; a resumed run can only be extended"
        )
    raise InputError(
        f"{resume}: the scene differs from the one the run started with in "
        f"{', '.join(changed)}; only a larger time.t_max may change (to extend the run)"
    )


def changed_keys(a: Scene, b: Scene) -> list[str]:
    """Dotted keys (``material.E``, ``model``) whose resolved values differ between two scenes."""
    flat_a, flat_b = a.dotted(), b.dotted()
    return sorted(k for k in flat_a.keys() | flat_b.keys() if flat_a.get(k) != flat_b.get(k))
