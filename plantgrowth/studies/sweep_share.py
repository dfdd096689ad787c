"""Which runs of a sweep a process takes: job-array elements, then groups of ranks."""

from __future__ import annotations

import logging
from dataclasses import dataclass

from mpi4py import MPI

from plantgrowth.base.errors import InputError
from plantgrowth.studies.sweep_file import Sweep

log = logging.getLogger("plantgrowth")


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
