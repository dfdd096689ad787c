"""plantgrowth: multiscale simulation of plant tissue growth (docs/model.md, docs/api.md).

The Python API, as ``import plantgrowth as pg``:

- ``pg.load_scene(path)``, ``pg.Scene.from_dict(data)``, ``scene.replace(**{"material.E": 2.0})``;
- ``pg.run(scene, outdir, comm=None) -> pg.Results``; ``pg.read_results(outdir) -> pg.Results``;
- ``pg.cell(**parameters) -> dict``;
- the errors ``pg.InputError`` (bad input; ``pg.SceneError`` for scenes) and ``pg.RunError``;
  ``pg.Interrupted`` (Ctrl-C stopped a run after a step), a KeyboardInterrupt.

Subpackages, each importing only those after it (tests/test_layout.py checks):
``cli`` -> ``api`` -> ``studies`` -> ``runner``, ``results`` -> ``models`` -> ``unitcell`` ->
``scene`` -> ``base`` -> ``forms``, ``meshes``. The names above are imported when first used, so
``import plantgrowth`` itself loads neither dolfinx nor MPI.
"""

from __future__ import annotations

import importlib
import os
import sys
from typing import Any

from plantgrowth.base.dist_versions import install as install_dist_versions

if "numpy" not in sys.modules:
    # numpy asks Linux for transparent huge pages on every array of 4 MB or more; with the
    # kernel's default "defrag = madvise" each such allocation may stall while the kernel
    # compacts memory. Measured on the organ scene (1 rank, 2 steps, a machine up for a day):
    # 69.6 s with, 48.9 s without (system time 21.5 s against 3.2 s; user time the same, 44.8 s
    # against 45.1 s). numpy reads this at import; a user's own setting is kept.
    os.environ.setdefault("NUMPY_MADVISE_HUGEPAGE", "0")

# dolfinx partitions meshes with PT-SCOTCH, whose version 7 (Debian bookworm's) splits the work
# over threads by default: a rectangle of 384,400 cells made 5 times on 2 ranks got 5 different
# partitions, and with them different BoomerAMG hierarchies (the organ scene's 60 steps took
# 513-596 CG iterations in all, run to run). One thread gives the same partition in every run
# and every process, at the same cost (0.47 s against 0.48 s for that mesh). SCOTCH reads this
# at each partitioning; a user's own setting is kept.
os.environ.setdefault("SCOTCH_PTHREAD_NUMBER", "1")

# ufl and ffcx (imported with dolfinx) import pkg_resources for their version only: 0.07-0.13 s
# of every run's start-up. plantgrowth/base/dist_versions.py answers them from importlib.metadata.
install_dist_versions()

_API = {
    "load_scene": "plantgrowth.scene",
    "Scene": "plantgrowth.scene",
    "SceneError": "plantgrowth.base.errors",
    "InputError": "plantgrowth.base.errors",
    "RunError": "plantgrowth.base.errors",
    "Interrupted": "plantgrowth.base.errors",
    "run": "plantgrowth.api",
    "read_results": "plantgrowth.results.run_results",
    "Results": "plantgrowth.results.run_results",
    "cell": "plantgrowth.api",
}

__all__ = sorted(_API)


def __getattr__(name: str) -> Any:
    if name not in _API:
        raise AttributeError(f"module 'plantgrowth' has no attribute {name!r}")
    return getattr(importlib.import_module(_API[name]), name)
