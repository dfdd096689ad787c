"""numpy's transparent huge pages are off in a plantgrowth process unless the user asks for them
(plantgrowth/__init__.py: with the kernel's "defrag = madvise", every array of 4 MB or more
could stall on memory compaction; measured 30% of a large run's time). Each case runs in a fresh
process: numpy reads the setting once, at its import. Subprocess tests: ``skip_in_parallel``.
"""

from __future__ import annotations

import subprocess
import sys

import pytest
from cli_helpers import ENV

pytestmark = pytest.mark.skip_in_parallel
PROBE = "import plantgrowth, numpy; print(numpy.core.multiarray._get_madvise_hugepage())"


def huge_pages(env: dict) -> str:
    done = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True,
                          env=env, timeout=60, check=True)  # fmt: skip
    return done.stdout.strip()


def test_importing_plantgrowth_first_turns_numpy_huge_pages_off():
    env = {k: v for k, v in ENV.items() if k != "NUMPY_MADVISE_HUGEPAGE"}
    assert huge_pages(env) == "False"


def test_the_users_own_setting_is_kept():
    assert huge_pages(dict(ENV, NUMPY_MADVISE_HUGEPAGE="1")) == "True"
