"""MPI for the command line: started once a command needs it, and quickly when alone.

A process started without a launcher (``plantgrowth run ...``, not under mpirun or srun) is an
MPI singleton: one rank that talks only to itself. Open MPI 4.1's MPI_Init then spends about
0.3 s on what such a process never uses: it starts a PMIx support daemon (for MPI_Comm_spawn)
and probes UCX's network devices. For a singleton, :func:`world` skips both with two of Open
MPI's MCA parameters, ``ess_singleton_isolated = 1`` and ``pml = ob1`` (the point-to-point layer
over shared memory and self), set only while MPI_Init runs and only where the user set neither;
other MPI implementations ignore them. Measured (``python -c "from mpi4py import MPI"``, Open MPI
4.1.4, the machine of benchmarks/results/startup.json): 0.36-0.43 s without, 0.04-0.10 s with.
"""

from __future__ import annotations

import os
import sys
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from mpi4py import MPI

LAUNCHED = ("OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE", "SLURM_PROCID")
"""Set by a launcher (Open MPI's mpirun, PMIx, Hydra, Slurm): then MPI starts as configured."""
SINGLETON_MCA = {"OMPI_MCA_ess_singleton_isolated": "1", "OMPI_MCA_pml": "ob1"}
"""Open MPI's parameters for a process without a launcher (see the module docstring)."""


def world() -> MPI.Comm:
    """MPI's world communicator, starting MPI on the first call (``--help``, ``--version`` and a
    command line that fails to parse never start it); a singleton starts isolated."""
    if "mpi4py.MPI" not in sys.modules and not any(k in os.environ for k in LAUNCHED):
        added = {k: v for k, v in SINGLETON_MCA.items() if k not in os.environ}
        os.environ.update(added)
        try:
            from mpi4py import MPI
        finally:  # MPI_Init has read them: processes started later get the user's environment
            for key in added:
                del os.environ[key]
    from mpi4py import MPI

    return MPI.COMM_WORLD
