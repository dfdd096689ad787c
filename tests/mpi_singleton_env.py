"""The environment Open MPI's singleton start leaves behind, and how a child process forgets it.

``MPI_Init`` in a process started without a launcher (a *singleton*: the pytest controller, which
imports mpi4py through tests/conftest.py) exports ``OMPI_MCA_ess=singleton``, the address of its
PMIx server (``PMIX_SERVER_URI*``), its namespace and rank. A pytest-xdist worker inherits them:
its own MPI_Init then joins the controller's PMIx namespace, and an ``mpirun`` it launches exits
with code 1 and no message (measured with Open MPI 4.1.4). A launcher's own variables
(``OMPI_COMM_WORLD_*`` under mpirun) are never touched: only a singleton's are forgotten.
"""

from __future__ import annotations

import os

SINGLETON_PREFIXES = ("PMIX_", "ORTE_", "OMPI_MCA_orte_")
SINGLETON_KEYS = ("OMPI_MCA_ess", "OMPI_MCA_pmix", "OMPI_APP_CTX_NUM_PROCS")


def inherited(environ: dict[str, str]) -> list[str]:
    """The keys of ``environ`` that a singleton parent exported (none unless
    ``OMPI_MCA_ess=singleton`` is there and no launcher started this process)."""
    if environ.get("OMPI_MCA_ess") != "singleton" or "OMPI_COMM_WORLD_SIZE" in environ:
        return []
    return sorted(k for k in environ if k.startswith(SINGLETON_PREFIXES) or k in SINGLETON_KEYS)


def forget_inherited() -> list[str]:
    """Remove the singleton parent's keys from ``os.environ``; return them."""
    keys = inherited(dict(os.environ))
    for key in keys:
        del os.environ[key]
    return keys
