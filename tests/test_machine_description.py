"""The machine description recorded next to benchmark results (plantgrowth/base/machine.py)."""

from __future__ import annotations

import json
import os

from plantgrowth.base.machine import machine_description


def test_the_description_names_the_blas_this_process_loaded():
    """The BLAS is part of what a timing depends on (the reference BLAS against OpenBLAS:
    docs/large_tissues.md): its files are the ones mapped into this process, each of which
    exists, and the description stays JSON."""
    description = machine_description()
    paths = description["blas"].split(", ")
    names = [os.path.basename(p) for p in paths]
    assert any(n.startswith(("libblas", "libopenblas")) for n in names), names
    assert all(os.path.isfile(p) for p in paths)
    assert json.loads(json.dumps(description)) == description
