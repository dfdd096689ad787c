"""The Python API: build a scene, run it, read its results, solve one unit cell.

Every function here does what the ``plantgrowth`` command of the same name does, with the same
files and the same checks; bad input raises :class:`InputError` (the CLI's exit 2), a run that
fails numerically :class:`RunError` (exit 3). Documented in docs/api.md::

    import plantgrowth as pg
    scene = pg.load_scene("scenes/reference_stress.toml").replace(**{"material.E": 2.0})
    results = pg.run(scene, "results/stiffer")
    results.summary["area"], results.field("G", t=10.0)
"""

from __future__ import annotations

import os
from pathlib import Path

from mpi4py import MPI

from plantgrowth.results.run_results import Results, read_results
from plantgrowth.runner.scene_run import run_scene
from plantgrowth.scene import Scene
from plantgrowth.unitcell.solver import cell_properties

__all__ = ["Results", "cell", "read_results", "run"]


def run(
    scene: Scene, outdir: str | os.PathLike, comm: MPI.Comm | None = None, *,
    resume: bool = False, overwrite: bool = False, label: str = "plantgrowth.run",
) -> Results | dict[str, Results]:  # fmt: skip
    """Run ``scene`` into ``outdir`` as ``plantgrowth run -o OUTDIR`` does (collective on
    ``comm``, default ``MPI.COMM_WORLD``); ``resume`` and ``overwrite`` as ``--resume`` and
    ``--overwrite``; ``label`` names the run in run.log's first line. Returns the run's
    :class:`Results` (``model = "both"``: a dict with the ``"macro"`` and ``"micro"`` results).

    Raises:
        InputError: the scene is invalid where the run uses it, or the directory is refused.
        RunError: a step failed (every completed step stays readable).
        Interrupted: SIGINT stopped the run after a completed step.
    """
    comm = MPI.COMM_WORLD if comm is None else comm
    outdir = Path(outdir)
    run_scene(scene, outdir, comm, label, resume, overwrite)
    if scene.model == "both":
        return {side: read_results(outdir / side) for side in ("macro", "micro")}
    return read_results(outdir)


def cell(
    *, l1: float = 1.0, l2: float = 1.0, theta: float = 30.0, w: float = 0.05, E: float = 1.0,
    nu: float = 0.3, Fg: object = ((1.0, 0.0), (0.0, 1.0)), resolution: int | None = None,
    comm: MPI.Comm | None = None,
) -> dict[str, float]:  # fmt: skip
    """One honeycomb unit cell's homogenized properties, as ``plantgrowth cell --json`` prints
    them: E_hom's six components (E1111, ...), K11, K22, K12, the orthotropic moduli, phi_w,
    ndofs and seconds. ``theta`` in degrees, ``Fg`` a 2x2 growth tensor, ``resolution`` P2
    elements across a wall (default: about 0.3% error on the moduli)."""
    comm = MPI.COMM_SELF if comm is None else comm
    return cell_properties(l1, l2, theta, w, E, nu, Fg, resolution, comm)
