"""Parameter sweeps: a base scene, the values to vary, one ``plantgrowth run`` per combination.

A sweep file::

    base = "../reference_strain.toml"   # the base scene: relative to the sweep file, or absolute
    mode = "grid"                        # "grid": every combination, the first key slowest;
                                         # "one-at-a-time": each list alone, the others at base
    [vary]                               # dotted scene keys, each a non-empty list of values:
    "material.nu" = [0.1, 0.2, 0.3]      # anything the scene accepts for the key (numbers,
    "growth.eta" = [1.0, {from = 0.5, to = 2.0}]  # strings, {from, to} fields, arrays)

A varied ``accuracy.preset`` sets the knobs the base scene leaves out, as in a scene. The whole
sweep is checked before anything runs: the sweep file's keys, and every run's scene (an error
names the run and its values).

Output directory::

    sweep.toml         the sweep as resolved (absolute base path, mode, vary)
    sweep.csv          one row per run: run, the varied values (columns named by their keys),
                       status (done | failed | interrupted | pending), t, area, growth_rate_11,
                       growth_rate_22, growth_rate_area at the last completed step, seconds,
                       error; ``micro_*`` columns too if a run has model = "both" (the main
                       columns are then its macro side)
    run_NNNN/          one run as ``plantgrowth run`` writes it, and result.json (its row)
    .plantgrowth.lock  held while a sweep runs (shared by the elements of a job array)
    .sweep.lock        serialises the rewrites of sweep.toml and sweep.csv

A restarted sweep (the same sweep file, same DIR) skips a run whose summary reached t_max,
continues an interrupted one with ``--resume`` (same numbers as an uninterrupted run, no work
lost) and retries a failed one the same way. Another sweep file in the same DIR is refused,
naming what differs; so is a run whose saved scene no longer matches (a changed base scene),
except for a larger ``time.t_max``, which extends the runs.

Runs are dealt out round-robin: to the job-array elements (run i to element i mod N), then to
the groups of ``ranks_per_run`` ranks of each element; every group runs its share on its own
sub-communicator and its rank 0 logs into the run's run.log. The rows are written into
result.json per run, and sweep.csv is rebuilt from them (under ``.sweep.lock``, temporary file
and rename) after every run, so concurrent elements and killed sweeps leave a consistent table.
"""

from __future__ import annotations

import csv
import difflib
import fcntl
import gc
import io
import itertools
import json
import logging
import math
import os
import re
import sys
import time
import tomllib
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mpi4py import MPI

from plantgrowth.base.errors import InputError, RunError
from plantgrowth.runner.output import atomic_write_text, last_summary_step, temporary_path
from plantgrowth.runner.rundir import (
    DirectoryLock,
    changed_keys,
    earlier_outputs,
    remove_earlier_outputs,
)
from plantgrowth.runner.timeloop import Interrupted
from plantgrowth.scene import Scene, load_scene, parse_scene
from plantgrowth.scene.limits import EDGES
from plantgrowth.scene.toml_text import dict_to_toml

log = logging.getLogger("plantgrowth")

MODES = ("grid", "one-at-a-time")
SWEEP_KEYS = ("base", "mode", "vary")
MAX_RUNS = 100_000
NUMBERS = ("t", "area", "growth_rate_11", "growth_rate_22", "growth_rate_area")
RESOLVED, TABLE, RESULT, TABLE_LOCK = "sweep.toml", "sweep.csv", "result.json", ".sweep.lock"
_RUN_DIR = re.compile(r"run_\d{4,}")

RunScene = Callable[..., None]
"""``run_scene(scene, outdir, comm, what, resume)``: the run path of ``plantgrowth run``."""


# --- the sweep file -------------------------------------------------------------------------------


def cell(value: Any) -> str:
    """A value as shown in sweep.csv and messages: a string as is, anything else as TOML."""
    if isinstance(value, str):
        return value
    text = dict_to_toml({"v": [value]})  # "v = [<value>]\n": the inline form of any value
    return text[len("v = [") : -len("]\n")]


@dataclass(frozen=True)
class Run:
    """One run of a sweep: its number, the values it varies and its validated scene."""

    index: int
    values: dict[str, Any]
    scene: Scene

    @property
    def name(self) -> str:
        return f"run_{self.index:04d}"

    @property
    def label(self) -> str:
        """``run_0002 (material.nu = 0.3, time.t_max = 10.0)``."""
        return _label(self.index, self.values)


def _label(index: int, values: dict[str, Any]) -> str:
    return f"run_{index:04d} ({', '.join(f'{k} = {cell(v)}' for k, v in values.items())})"


@dataclass(frozen=True)
class Sweep:
    """A validated sweep: the resolved sweep file and its runs."""

    path: Path
    base: Path  # absolute
    mode: str
    vary: dict[str, list]
    runs: list[Run]
    base_cells: dict[str, str]  # the base scene's value of each varied key ("" if it has none)

    def resolved(self) -> dict[str, Any]:
        return {"base": str(self.base), "mode": self.mode, "vary": self.vary}

    def to_toml(self) -> str:
        header = f"# plantgrowth sweep, resolved from {self.path.resolve()}\n"
        return header + dict_to_toml(self.resolved())

    def cells(self, run: Run) -> dict[str, str]:
        """The varied-value columns of a run's row (one-at-a-time: the others at base)."""
        return {
            k: cell(run.values[k]) if k in run.values else self.base_cells[k] for k in self.vary
        }

    def columns(self) -> list[str]:
        micro = [f"micro_{n}" for n in NUMBERS] if self._has_both() else []
        return ["run", *self.vary, "status", *NUMBERS, *micro, "seconds", "error"]

    def _has_both(self) -> bool:
        return any(run.scene.model == "both" for run in self.runs)


class SweepError(InputError):
    """Bad sweep file; the message names the key and ends with the file."""


def load_sweep(path: Path) -> Sweep:
    """Read and check a sweep file, its base scene and the scene of every run.

    Raises:
        InputError: one line naming the key (or the run and its values) and the file.
    """
    data = _read_toml(path)
    _check_top_keys(data, path)
    base = _base_path(data, path)
    base_scene = load_scene(base)  # its errors name the base file
    base_data = tomllib.loads(base.read_text(encoding="utf-8"))  # load_scene read it already
    keys = _scene_keys(base_scene)
    mode = _mode(data, path)
    vary = _vary(data, keys, mode, path)
    runs = [
        _run(i, values, base_data, path, base.parent)
        for i, values in enumerate(_combinations(vary, mode))
    ]
    flat = base_scene.dotted()
    base_cells = {k: cell(flat[k]) if k in flat else "" for k in vary}
    return Sweep(path, base, mode, vary, runs, base_cells)


def _fail(path: Path, message: str) -> SweepError:
    return SweepError(f"{message} (in {path})")


def _read_toml(path: Path) -> dict:
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SweepError(f"{path}: sweep file not found") from None
    except IsADirectoryError:
        raise SweepError(f"{path}: is a directory, not a sweep file") from None
    except UnicodeDecodeError as e:
        raise SweepError(
            f"{path}: not UTF-8 text (bad byte at {e.start}): a binary file?"
        ) from None
    except OSError as e:
        raise SweepError(f"{path}: cannot read the sweep file: {e.strerror or e}") from None
    except ValueError as e:  # TOMLDecodeError
        raise SweepError(f"{path}: invalid TOML: {e}") from None


def _check_top_keys(data: dict, path: Path) -> None:
    for key in data:
        if key not in SWEEP_KEYS:
            close = difflib.get_close_matches(key, SWEEP_KEYS, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            valid = ", ".join(SWEEP_KEYS)
            raise _fail(path, f"unknown key '{key}' (valid keys: {valid}){hint}")


def _base_path(data: dict, path: Path) -> Path:
    if "base" not in data:
        raise _fail(path, "base is required: the path of the base scene")
    raw = data["base"]
    if not isinstance(raw, str) or not raw:
        raise _fail(path, f"base: expected the path of the base scene, got {raw!r}")
    base = (path.parent / raw).resolve()  # an absolute raw path stays as it is
    if not base.is_file():
        raise _fail(path, f"base = {raw!r}: no such scene file ({base})")
    return base


def _mode(data: dict, path: Path) -> str:
    mode = data.get("mode", "grid")
    if mode not in MODES:
        options = ", ".join(map(repr, MODES))
        raise _fail(path, f"mode = {mode!r} is invalid: it must be one of {options}")
    return mode


def _scene_keys(scene: Scene) -> set[str]:
    """Every dotted key a scene has (``model``, ``material.nu``, ..., ``loads.right``)."""
    edges = set(EDGES) | set(scene.tissue.edge_lengths())
    return set(scene.dotted()) | {f"loads.{edge}" for edge in edges}


def _vary_items(table: dict, keys: set[str], prefix: str = "") -> Iterator[tuple[str, Any]]:
    """(dotted key, value) of a [vary] table, quoted (``"material.nu"``) or dotted
    (``material.nu``) keys alike; a scene key's table value is kept (it is not a list)."""
    for key, value in table.items():
        dotted = prefix + key
        if isinstance(value, dict) and dotted not in keys:
            yield from _vary_items(value, keys, dotted + ".")
        else:
            yield dotted, value


def _vary(data: dict, keys: set[str], mode: str, path: Path) -> dict[str, list]:
    table = data.get("vary")
    if not isinstance(table, dict) or not table:
        raise _fail(path, "vary is required: a table of dotted scene keys, each a list of values")
    vary: dict[str, list] = {}
    for key, values in _vary_items(table, keys):
        if key not in keys:
            raise _fail(path, f"vary: '{key}' is not a scene key{_suggest(key, keys)}")
        if key in vary:
            raise _fail(path, f"vary: '{key}' is given twice")
        if not isinstance(values, list) or not values:
            raise _fail(path, f"vary.'{key}': expected a non-empty list of values, got {values!r}")
        for i, value in enumerate(values):
            if value in values[:i]:
                raise _fail(path, f"vary.'{key}' lists {cell(value)} twice")
        vary[key] = values
    sizes = [len(values) for values in vary.values()]
    count = math.prod(sizes) if mode == "grid" else sum(sizes)
    if count > MAX_RUNS:
        raise _fail(path, f"vary: the sweep has {count} runs (at most {MAX_RUNS})")
    return vary


def _suggest(key: str, keys: set[str]) -> str:
    last = key.rsplit(".", 1)[-1]
    close = sorted(k for k in keys if k.rsplit(".", 1)[-1] == last)
    close = close or difflib.get_close_matches(key, sorted(keys), n=1)
    return f"; did you mean '{close[0]}'?" if close else ""


def _combinations(vary: dict[str, list], mode: str) -> list[dict[str, Any]]:
    """The varied values of each run, in run order."""
    if mode == "grid":
        return [
            dict(zip(vary, values, strict=True)) for values in itertools.product(*vary.values())
        ]
    return [{key: value} for key, values in vary.items() for value in values]


def _run(index: int, values: dict[str, Any], base_data: dict, path: Path, directory: Path) -> Run:
    """One run: the base scene with the run's values (a relative tissue.mesh is relative to the
    base scene's directory, ``directory``)."""
    data = {k: dict(v) if isinstance(v, dict) else v for k, v in base_data.items()}
    for key, value in values.items():
        section, _, name = key.rpartition(".")
        (data.setdefault(section, {}) if section else data)[name] = value
    source = f"{path}: {_label(index, values)}"
    return Run(index, values, parse_scene(data, source=source, directory=directory))


# --- which runs a process takes -------------------------------------------------------------------


@dataclass(frozen=True)
class Share:
    """How runs are dealt out: to ``elements`` job-array elements (this is ``element``), then to
    the groups of ``ranks_per_run`` ranks of each element."""

    ranks_per_run: int = 1
    element: int = 0
    elements: int = 1

    @classmethod
    def check(
        cls, size: int, ranks_per_run: int, array_index: int | None, array_count: int | None
    ) -> Share:
        """The share of the command line's options on ``size`` ranks, or InputError."""
        k = ranks_per_run
        if k < 1:
            raise InputError(f"--ranks-per-run = {k} is invalid: it must be an integer >= 1")
        if size % k:
            raise InputError(
                f"--ranks-per-run = {k} does not divide the number of MPI ranks, {size}: start "
                f"mpirun -n with a multiple of {k}"
            )
        if (array_index is None) != (array_count is None):
            raise InputError(
                "give --array-index and --array-count together (Slurm: $SLURM_ARRAY_TASK_ID "
                "and $SLURM_ARRAY_TASK_COUNT)"
            )
        if array_count is None:
            return cls(k)
        if array_count < 1:
            raise InputError(f"--array-count = {array_count} is invalid: it must be >= 1")
        if not 0 <= array_index < array_count:
            raise InputError(
                f"--array-index = {array_index} is out of range: it must be in "
                f"[0, {array_count - 1}] for --array-count = {array_count} (Slurm: number the "
                f"array from 0, --array=0-{array_count - 1})"
            )
        return cls(k, array_index, array_count)

    def element_runs(self, n_runs: int) -> list[int]:
        """The runs of this job-array element: element, element + elements, ..."""
        return list(range(self.element, n_runs, self.elements))

    def group_runs(self, n_runs: int, rank: int, size: int) -> list[int]:
        """The runs of the group of ranks that ``rank`` belongs to (round-robin)."""
        groups = size // self.ranks_per_run
        return self.element_runs(n_runs)[rank // self.ranks_per_run :: groups]


def dry_run(sweep: Sweep, share: Share, comm: MPI.Comm) -> int:
    """List the runs of the sweep (those of this element); write nothing."""
    mine = share.element_runs(len(sweep.runs))
    for i in mine:
        log.info("%s", sweep.runs[i].label)
    element = f"; element {share.element} of {share.elements}" if share.elements > 1 else ""
    log.info("%s: %d runs (%s)%s: %d listed", sweep.path, len(sweep.runs), sweep.mode, element,
             len(mine))  # fmt: skip
    return 0


# --- the output directory -------------------------------------------------------------------------


@contextmanager
def _table_lock(outdir: Path) -> Iterator[None]:
    """Exclusive for the moment it takes to rewrite sweep.toml or sweep.csv."""
    fd = os.open(outdir / TABLE_LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def _claim(sweep: Sweep, outdir: Path, comm: MPI.Comm, shared: bool, overwrite: bool):
    """Collective: lock DIR (rank 0 holds the lock), check what it holds, write sweep.toml and
    the first sweep.csv. InputError on every rank, with nothing changed, if DIR is refused."""
    lock, error = None, None
    if comm.rank == 0:
        try:
            lock = _hold(sweep, outdir, shared, overwrite)
        except InputError as err:
            error = str(err)
    error = comm.bcast(error, root=0)
    if error:
        raise InputError(error)
    return lock


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
    saved["vary"] = dict(_vary_items(vary, set(sweep.vary)))
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
        if run_dir.is_dir() and _RUN_DIR.fullmatch(run_dir.name):
            for name in (RESULT, f".{RESULT}.tmp"):
                (run_dir / name).unlink(missing_ok=True)
            remove_earlier_outputs(run_dir)
            if not any(run_dir.iterdir()):
                run_dir.rmdir()
    for name in (TABLE, RESOLVED):
        for path in (outdir / name, outdir / f".{name}.tmp"):
            path.unlink(missing_ok=True)


def _read_result(run_dir: Path) -> dict[str, str]:
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
        result = _read_result(outdir / run.name) or {"status": "pending"}
        table.writerow({"run": run.name, **sweep.cells(run), **result})
    atomic_write_text(outdir / TABLE, text.getvalue())


def _update_table(sweep: Sweep, outdir: Path) -> None:
    with _table_lock(outdir):
        _write_table(sweep, outdir)


# --- running ------------------------------------------------------------------------------------


def _sides(model: str) -> dict[str, str]:
    """Column prefix -> the sub-directory with that side's summary.csv."""
    return {"": "macro", "micro_": "micro"} if model == "both" else {"": ""}


def _last_row(path: Path) -> dict[str, str]:
    try:
        with open(path, newline="") as f:
            rows = [row for row in csv.DictReader(f) if row.get("step")]
    except FileNotFoundError:
        return {}
    return rows[-1] if rows else {}


def _finished(run_dir: Path, scene: Scene) -> bool:
    """Whether every summary.csv of the run has its last step."""
    n_steps = 0 if scene.growth.law == "none" else scene.time.n_steps
    steps = [
        last_summary_step(run_dir / side / "summary.csv") for side in _sides(scene.model).values()
    ]
    return all(step is not None and step >= n_steps for step in steps)


def _result(run_dir: Path, scene: Scene, status: str, error: str, seconds: float | None) -> dict:
    """A run's row: status, the last completed step's numbers, seconds, error."""
    out = {"status": status, "seconds": "" if seconds is None else f"{seconds:.3f}", "error": error}
    for prefix, side in _sides(scene.model).items():
        row = _last_row(run_dir / side / "summary.csv")
        out.update({prefix + k: row.get(k) or "" for k in NUMBERS})
    return out


@contextmanager
def _group_logging(leader: bool) -> Iterator[None]:
    """Each group's rank 0 logs (progress into its runs' run.log)."""
    level = log.level
    log.setLevel(logging.INFO if leader else logging.ERROR)
    try:
        yield
    finally:
        log.setLevel(level)


def _mute(record: logging.LogRecord) -> bool:
    return False


@contextmanager
def _run_logging(name: str) -> Iterator[None]:
    """During one run: its progress goes to its run.log only (stdout gets one line per run), its
    warnings to stderr as ``plantgrowth: run_NNNN: warning: ...``."""
    consoles = [h for h in log.handlers if getattr(h, "stream", None) is sys.stdout]
    errors = [(h, h.formatter) for h in log.handlers if getattr(h, "stream", None) is sys.stderr]
    for handler in consoles:
        handler.addFilter(_mute)
    for handler, _ in errors:
        handler.setFormatter(logging.Formatter(f"plantgrowth: {name}: %(message)s"))
    try:
        yield
    finally:
        for handler in consoles:
            handler.removeFilter(_mute)
        for handler, formatter in errors:
            handler.setFormatter(formatter)


def _run_state(run_dir: Path, run: Run) -> tuple[bool, bool, float]:
    """(finished, resume, seconds already spent by interrupted attempts), read by one rank."""
    previous = _read_result(run_dir)
    spent = float(previous["seconds"] or 0) if previous.get("status") == "interrupted" else 0.0
    return _finished(run_dir, run.scene), (run_dir / "scene.toml").is_file(), spent


def _run_one(sweep: Sweep, run: Run, outdir: Path, group: MPI.Comm, run_scene: RunScene) -> str:
    """Collective on ``group``: run (or skip) one run, record its row; its status ("busy": its
    directory is held by another process, nothing recorded)."""
    run_dir, leader = outdir / run.name, group.rank == 0
    finished, resume, spent = group.bcast(_run_state(run_dir, run) if leader else None, root=0)
    if finished:
        if leader and _read_result(run_dir).get("status") != "done":
            _record(sweep, outdir, run, "done", "", None)  # killed before its row was written
        log.info("%s: finished earlier, skipped", run.label)
        return "done"
    start = time.perf_counter()
    status, error = "done", ""
    with _run_logging(run.name):
        try:
            what = f"plantgrowth sweep {sweep.path}: {run.label}"
            run_scene(run.scene, run_dir, group, what, resume)
        except RunError as err:
            status, error = "failed", str(err)
        except (Interrupted, KeyboardInterrupt) as err:
            status, error = "interrupted", str(err) or "interrupted during the set-up"
        except InputError as err:  # held by another process, or changed since the check
            log.warning("warning: skipped: %s", err)
            return "busy"
    seconds = spent + time.perf_counter() - start
    if leader:
        row = _record(sweep, outdir, run, status, error, seconds)
        _report(run, row)
    gc.collect()  # free this run's PETSc objects now, on every rank of the group
    return status


def _record(sweep: Sweep, outdir: Path, run: Run, status: str, error: str, seconds) -> dict:
    run_dir = outdir / run.name
    row = _result(run_dir, run.scene, status, error, seconds)
    atomic_write_text(run_dir / RESULT, json.dumps(row) + "\n")
    _update_table(sweep, outdir)
    return row


def _report(run: Run, row: dict) -> None:
    if row["status"] == "failed":
        log.warning("%s: failed: %s", run.label, row["error"])
    elif row["status"] == "interrupted":
        log.info("%s: %s", run.label, row["error"])
    else:
        shown = ", ".join(f"{k} = {float(row[k]):.6g}" for k in ("t", "area", "growth_rate_area"))
        log.info("%s: done: %s (%s s)", run.label, shown, row["seconds"])


def _run_share(
    sweep: Sweep, indices: list[int], outdir: Path, group: MPI.Comm, run_scene: RunScene
) -> int:
    """Collective on ``group``: its runs in turn; 0 all done, 3 some failed or busy, 130 stopped
    by SIGINT (after the current run's current step)."""
    code = 0
    try:
        for i in indices:
            status = _run_one(sweep, sweep.runs[i], outdir, group, run_scene)
            if status == "interrupted":
                return 130
            if status != "done":
                code = 3
    except KeyboardInterrupt:  # between two runs
        return 130
    return code


def run_sweep(
    sweep: Sweep, outdir: Path, comm: MPI.Comm, share: Share, run_scene: RunScene,
    overwrite: bool = False,
) -> int:  # fmt: skip
    """Collective: run this process's share of the sweep into ``outdir``.

    Args:
        share: the job-array element and ranks per run (checked against ``comm.size``).
        run_scene: the run path of ``plantgrowth run``
        (:func:`plantgrowth.runner.scene_run.run_scene`). overwrite: remove an earlier sweep's files
        in ``outdir`` first.
    Returns:
        0 every run of this share done, 3 some failed (or were held by another process), 130
        interrupted by SIGINT.
    Raises:
        InputError: ``outdir`` is refused (busy, another sweep, a changed base scene).
    """
    lock = _claim(sweep, outdir, comm, shared=share.elements > 1, overwrite=overwrite)
    group = comm.Split(comm.rank // share.ranks_per_run, comm.rank)
    try:
        _log_start(sweep, outdir, comm, share)
        indices = share.group_runs(len(sweep.runs), comm.rank, comm.size)
        with _group_logging(group.rank == 0):
            code = _run_share(sweep, indices, outdir, group, run_scene)
        code = comm.allreduce(code, op=MPI.MAX)
        if comm.rank == 0:
            _update_table(sweep, outdir)
            _log_end(sweep, outdir)
    finally:
        gc.collect()
        group.Free()
        if lock is not None:
            lock.release()
    return code


def _log_start(sweep: Sweep, outdir: Path, comm: MPI.Comm, share: Share) -> None:
    k, groups = share.ranks_per_run, comm.size // share.ranks_per_run
    element = ""
    if share.elements > 1:
        n = len(share.element_runs(len(sweep.runs)))
        element = f"; job-array element {share.element} of {share.elements}: {n} of them"
    log.info("plantgrowth sweep %s -> %s: %d runs (%s over %s)%s; %d at a time on %d rank(s)",
             sweep.path, outdir, len(sweep.runs), sweep.mode, ", ".join(sweep.vary), element,
             groups, k)  # fmt: skip


def _log_end(sweep: Sweep, outdir: Path) -> None:
    statuses = [_read_result(outdir / run.name).get("status", "pending") for run in sweep.runs]
    counts = ", ".join(f"{statuses.count(s)} {s}" for s in ("done", "failed", "interrupted",
                                                              "pending"))  # fmt: skip
    log.info("sweep: %s: %s", counts, outdir / TABLE)
