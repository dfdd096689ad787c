"""tests/mpi_singleton_env.py forgets exactly what an Open MPI singleton parent exported."""

from mpi_singleton_env import inherited

SINGLETON_CHILD = {
    "OMPI_MCA_ess": "singleton",
    "PMIX_SERVER_URI41": "1330315264.0;tcp4://127.0.0.1:47865",
    "PMIX_RANK": "0",
    "ORTE_SCHIZO_DETECTION": "ORTE",
    "OMPI_MCA_orte_launch": "1",
    "OMPI_APP_CTX_NUM_PROCS": "1",
    "OMPI_MCA_pmix": "^s1,s2,cray,isolated",
    # the user's own settings (scripts/test.sh exports these) stay
    "OMPI_ALLOW_RUN_AS_ROOT": "1",
    "OMPI_MCA_rmaps_base_oversubscribe": "1",
    "HOME": "/root",
}


def test_a_singleton_parents_keys_are_forgotten_and_the_users_kept():
    assert inherited(SINGLETON_CHILD) == sorted([
        "OMPI_APP_CTX_NUM_PROCS", "OMPI_MCA_ess", "OMPI_MCA_orte_launch", "OMPI_MCA_pmix",
        "ORTE_SCHIZO_DETECTION", "PMIX_RANK", "PMIX_SERVER_URI41",
    ])  # fmt: skip


def test_a_rank_started_by_mpirun_keeps_its_launchers_keys():
    launched = dict(SINGLETON_CHILD, OMPI_COMM_WORLD_SIZE="2")
    assert inherited(launched) == []


def test_a_process_without_a_singleton_parent_keeps_everything():
    plain = {k: v for k, v in SINGLETON_CHILD.items() if k != "OMPI_MCA_ess"}
    assert inherited(plain) == []
