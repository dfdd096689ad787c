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

import logging
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from mpi4py import MPI

from plantgrowth.base.errors import InputError
from plantgrowth.base.std_streams import StdStreamHandler
from plantgrowth.meshes.honeycomb import GeometryError
from plantgrowth.results.run_results import Results, read_results
from plantgrowth.runner.rundir import API_OPTIONS, Options
from plantgrowth.runner.scene_run import run_scene
from plantgrowth.scene import Scene
from plantgrowth.unitcell.properties import cell_properties

__all__ = ["Results", "cell", "read_results", "run"]

log = logging.getLogger("plantgrowth")


def run(
    scene: Scene, outdir: str | os.PathLike, comm: MPI.Comm | None = None, *,
    resume: bool = False, overwrite: bool = False, label: str = "plantgrowth.run",
) -> Results | dict[str, Results]:  # fmt: skip
    """Run ``scene`` into ``outdir`` as ``plantgrowth run -o OUTDIR`` does (collective on
    ``comm``, default ``MPI.COMM_WORLD``); ``resume`` and ``overwrite`` as ``--resume`` and
    ``--overwrite`` (its messages name them ``resume=True`` and ``overwrite=True``); ``label``
    names the run in run.log's first line. Returns the run's :class:`Results` on every rank,
    once every file is complete (``model = "both"``: a dict with the ``"macro"`` and
    ``"micro"`` results).

    Raises:
        InputError: the scene is invalid where the run uses it (nothing is written), or the
            directory is refused (in use, holds an earlier run, cannot be resumed).
        RunError: a step failed (every completed step stays readable).
        Interrupted: SIGINT stopped the run after a completed step (``pg.Interrupted``, a
            KeyboardInterrupt: ``except Exception`` does not catch it).
    """
    return run_with(
        API_OPTIONS, scene, outdir, comm, resume=resume, overwrite=overwrite, label=label
    )


def run_with(
    options: Options, scene: Scene, outdir: str | os.PathLike, comm: MPI.Comm | None = None, *,
    resume: bool = False, overwrite: bool = False, label: str = "plantgrowth.run",
) -> Results | dict[str, Results]:  # fmt: skip
    """:func:`run`, its messages naming ``resume`` and ``overwrite`` as ``options`` do (the
    API's arguments, or the CLI's flags for ``plantgrowth run``)."""
    if not isinstance(scene, Scene):
        raise TypeError(f"scene must be a Scene (pg.load_scene, pg.Scene.from_dict), got {scene!r}")
    comm = MPI.COMM_WORLD if comm is None else comm
    outdir = Path(outdir)
    try:
        with _progress_logged(comm):
            run_scene(scene, outdir, comm, label, resume, overwrite, options)
    except GeometryError as err:  # an impossible cell met while building a model
        raise InputError(str(err)) from None
    comm.Barrier()  # rank 0 writes the last summary row and log line after the collectives
    if scene.model == "both":
        return {side: read_results(outdir / side) for side in ("macro", "micro")}
    return read_results(outdir)


@contextmanager
def _progress_logged(comm: MPI.Comm) -> Iterator[None]:
    """During the run, unless the caller has configured the ``plantgrowth`` logger (its level
    or handlers; the CLI does): its progress goes into run.log (rank 0) as under the CLI, and
    only its warnings to stderr, as ``plantgrowth: warning: ...`` (errors are raised)."""
    if log.level != logging.NOTSET or log.handlers:
        yield
        return
    console = StdStreamHandler("stderr", logging.WARNING)
    console.addFilter(lambda record: record.levelno < logging.ERROR)
    console.setFormatter(logging.Formatter("plantgrowth: %(message)s"))
    log.addHandler(console)
    propagate, log.propagate = log.propagate, False  # dolfinx's root handler would print INFO
    log.setLevel(logging.INFO if comm.rank == 0 else logging.ERROR)
    try:
        yield
    finally:
        log.setLevel(logging.NOTSET)
        log.propagate = propagate
        log.removeHandler(console)
        console.close()


def cell(
    *, l1: float = 1.0, l2: float = 1.0, theta: float = 30.0, w: float = 0.05, E: float = 1.0,
    nu: float = 0.3, Fg: object = ((1.0, 0.0), (0.0, 1.0)), resolution: int | None = None,
    comm: MPI.Comm | None = None, fibre_stiffness: float = 0.0, fibre_angle: float = 0.0,
) -> dict[str, object]:  # fmt: skip
    """One honeycomb unit cell's homogenized properties, as ``plantgrowth cell --json`` prints
    them: E_hom's six components (E1111, ...), K11, K22, K12, the orthotropic moduli, phi_w,
    ndofs (an int), seconds, and the strain averages dbar_w ({"11": [d11, d22, d12], "22": ...,
    "12": ...}) and dbar_v ([d11, d22, d12]). ``theta`` in degrees, ``Fg`` a 2x2 growth tensor,
    ``resolution`` P2 elements across a wall (default: about 0.3% error on the moduli);
    ``comm`` the ranks that share the solve (default ``MPI.COMM_SELF``: each caller alone);
    ``fibre_stiffness`` E_f / E >= 0 and ``fibre_angle`` the director in degrees from x1
    (fibre-reinforced walls, docs/fibres.md; 0: the paper's isotropic walls).

    Raises:
        InputError: a parameter out of range or an impossible cell; the message names it.
    """
    comm = MPI.COMM_SELF if comm is None else comm
    try:
        return cell_properties(
            l1, l2, theta, w, E, nu, Fg, resolution, comm,
            fibre_stiffness=fibre_stiffness, fibre_angle=fibre_angle,
        )  # fmt: skip
    except GeometryError as err:
        raise InputError(str(err)) from None
