"""Parameter sweeps: a base scene, the values to vary, one ``plantgrowth run`` per combination.

A sweep file::

    base = "../reference_strain.toml"   # the base scene: relative to the sweep file, or absolute
    mode = "grid"                        # "grid": every combination, the first key slowest;
                                         # "one-at-a-time": each list alone, the others at base;
                                         # "zip": run i takes the i-th value of every list
                                         # (lists of equal length: keys varied together)
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
                       growth_rate_22, growth_rate_area and the regions' columns
                       (``<name>.area``, ...) at the last completed step, seconds, error;
                       ``micro_*`` columns too if a run has model = "both" (the main columns
                       are then its macro side)
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
import gc
import json
import logging
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from mpi4py import MPI

from plantgrowth.base.errors import InputError, RunError
from plantgrowth.models.regions import region_columns
from plantgrowth.runner.output import atomic_write_text, last_summary_step
from plantgrowth.scene import Scene
from plantgrowth.studies.sweep_directory import (
    RESULT,
    TABLE,
    claim_sweep,
    read_result,
    update_table,
)
from plantgrowth.studies.sweep_file import NUMBERS, Run, RunScene, Sweep
from plantgrowth.studies.sweep_share import Share

log = logging.getLogger("plantgrowth")


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
    """A run's row: status, the last completed step's numbers (and its regions'), seconds,
    error."""
    out = {"status": status, "seconds": "" if seconds is None else f"{seconds:.3f}", "error": error}
    numbers = [*NUMBERS, *region_columns(scene.regions)]
    for prefix, side in _sides(scene.model).items():
        row = _last_row(run_dir / side / "summary.csv")
        out.update({prefix + k: row.get(k) or "" for k in numbers})
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
    previous = read_result(run_dir)
    spent = float(previous["seconds"] or 0) if previous.get("status") == "interrupted" else 0.0
    return _finished(run_dir, run.scene), (run_dir / "scene.toml").is_file(), spent


def _run_one(sweep: Sweep, run: Run, outdir: Path, group: MPI.Comm, run_scene: RunScene) -> str:
    """Collective on ``group``: run (or skip) one run, record its row; its status ("busy": its
    directory is held by another process, nothing recorded)."""
    run_dir, leader = outdir / run.name, group.rank == 0
    finished, resume, spent = group.bcast(_run_state(run_dir, run) if leader else None, root=0)
    if finished:
        if leader and read_result(run_dir).get("status") != "done":
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
        except KeyboardInterrupt as err:  # Interrupted after a step, or during the set-up
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
    update_table(sweep, outdir)
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
    lock = claim_sweep(sweep, outdir, comm, shared=share.elements > 1, overwrite=overwrite)
    group = comm.Split(comm.rank // share.ranks_per_run, comm.rank)
    try:
        _log_start(sweep, outdir, comm, share)
        indices = share.group_runs(len(sweep.runs), comm.rank, comm.size)
        with _group_logging(group.rank == 0):
            code = _run_share(sweep, indices, outdir, group, run_scene)
        code = comm.allreduce(code, op=MPI.MAX)
        if comm.rank == 0:
            update_table(sweep, outdir)
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
    statuses = [read_result(outdir / run.name).get("status", "pending") for run in sweep.runs]
    counts = ", ".join(f"{statuses.count(s)} {s}" for s in ("done", "failed", "interrupted",
                                                              "pending"))  # fmt: skip
    log.info("sweep: %s: %s", counts, outdir / TABLE)
