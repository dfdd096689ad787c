"""Measured outcomes of the three fibre scenes of ``scenes/biology/`` (issue 22, item 7;
docs/fibres.md, "Biology scenes") into ``benchmarks/results/fibre_biology.json``.

Reads the runs of ``scripts/studies/run_biology_scenes.py`` (the scenes as shipped) in
``results/biology/<name>/`` and runs the primordium once more without ``[feedback]`` beside them
(``fibres_feedback_primordium_nofeedback/``, skipped when complete unless ``--force``):

- ``fibres_one_direction``: the growth rates at t = 0 against consequence 4's formula from the
  fibred cell's own tensors (and the unfibred cell's), the rates at t_max, and how the deformed
  tissue's width, height and aspect ratio changed from t = 0 to t_max;
- ``fibres_feedback_primordium``: how circumferential the fibres lie around the patch
  (:func:`ring_alignment`) at t = 0 and t_max, with and without feedback, and how
  circumferential the stress's principal direction is;
- ``fibres_feedback_pull``: ``fibre_angle_mean(t)`` against the closed form of section 11 with
  the anisotropy of the scene's uniform stress (:func:`pull_anisotropy`), and that anisotropy
  read back from the run's own ``sigma_hom``.

The measures are functions of this module, which tests/test_biology_fibres.py applies to its
draft runs. ``python scripts/studies/fibre_biology.py [--results DIR] [--force]``
"""

from __future__ import annotations

import argparse
import json
import sys
import tomllib
from pathlib import Path

import numpy as np
from mpi4py import MPI

import plantgrowth as pg
from plantgrowth.base.machine import machine_description
from plantgrowth.models import growth
from plantgrowth.models.fibres import cue
from plantgrowth.results.reader import ResultSeries, read_series
from plantgrowth.unitcell.solver import CellSolver

REPO = Path(__file__).resolve().parents[2]
SCENES = REPO / "scenes" / "biology"
OUT = REPO / "benchmarks" / "results" / "fibre_biology.json"
NAMES = ("fibres_one_direction", "fibres_feedback_primordium", "fibres_feedback_pull")
PATCH = (3.464, 3.0)
"""The soft patch's centre (scenes/biology/fibres_feedback_primordium.toml, radius 1)."""
RING = (1.2, 2.0)
"""The annulus around the patch where the fibres are measured: outside the patch's staircase
edge (radius 1 + one draft cell), inside the tissue (the patch centre is 2.0 above x2 = 1)."""


# --- measures ---------------------------------------------------------------------------------


def cell_areas(series: ResultSeries) -> np.ndarray:
    """Reference areas (M,) of the run's fine triangles."""
    p = series.points[series.triangles]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    return 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def director_angle(series: ResultSeries, t: float) -> np.ndarray:
    """The director angle a (radians, (M,)) of each fine cell at the output time t, from the
    field fibre_direction m = (cos a, sin a)."""
    m = series.cell_field("fibre_direction", t)
    return np.arctan2(m[:, 1], m[:, 0])


def stress_angle(series: ResultSeries, t: float) -> np.ndarray:
    """The angle (radians, (M,)) of sigma_hom's largest principal direction per fine cell."""
    sigma = series.cell_field("sigma_hom", t)[:, [0, 1, 3, 4]].reshape(-1, 2, 2)
    return np.radians(cue(sigma).angle)


def ring_alignment(series: ResultSeries, angle: np.ndarray) -> dict[str, float]:
    """How circumferential the axes ``angle`` (radians per fine cell) lie around the patch: the
    area mean of |sin(angle - phi)|, phi the direction from the patch centre to the cell's
    midpoint, over the annulus :data:`RING` ("ring"; 1: all circumferential, 0: all radial,
    2/pi: no preference), its part below the patch (phi within 45 degrees of -90: "below") and
    the rest, beside it ("beside")."""
    d = series.points[series.triangles].mean(axis=1) - np.array(PATCH)
    r, phi = np.hypot(d[:, 0], d[:, 1]), np.arctan2(d[:, 1], d[:, 0])
    ring = (r > RING[0]) & (r < RING[1])
    below = ring & (np.abs(phi + 0.5 * np.pi) < 0.25 * np.pi)
    w, value = cell_areas(series), np.abs(np.sin(angle - phi))
    parts = {"ring": ring, "below": below, "beside": ring & ~below}
    return {k: float(w[p] @ value[p] / w[p].sum()) for k, p in parts.items()}


def deformed_extent(series: ResultSeries, t: float) -> tuple[float, float]:
    """(width, height) of the deformed tissue X + u(t) (its bounding box)."""
    x = series.points + series.displacement(t)
    return float(np.ptp(x[:, 0])), float(np.ptp(x[:, 1]))


def grown_stretch(series: ResultSeries, t: float) -> tuple[float, float]:
    """The area means of Fg11 and Fg22 at the output time t: the grown (stress-free) tissue's
    stretches along x1 and x2 when Fg is uniform and diagonal."""
    w = cell_areas(series)
    return tuple(float(w @ series.cell_field("Fg", t, c) / w.sum()) for c in ("11", "22"))


def pull_anisotropy(scene: pg.Scene) -> float:
    """A = (q1 - q2) / (|q1| + |q2|) of the uniform stress ``sigma_hom = p I + s e1 e1`` of a
    homogeneous rectangle under the turgor P1 (p = (1 - phi_w) P1, docs/model.md section 4) and
    the balanced total forces ``loads.right = {force = [F, 0]}`` = -``loads.left`` on its side
    edges (s = F / height: the edges do not grow when the yield threshold stops growth along
    x2): ``A = s / (s + 2 p)``."""
    p = (1.0 - scene.cell.at(0.0, 0.0).phi_w) * scene.P1.start
    s = scene.loads["right"].force[0] / scene.tissue.height
    return s / (s + 2.0 * p)


def closed_form_angle(t: np.ndarray, a0: float, rate: float, A: float) -> np.ndarray:
    """Section 11 under a constant cue along x1: ``tan a(t) = tan a0 exp(-k A t)`` (degrees)."""
    return np.degrees(np.arctan(np.tan(np.radians(a0)) * np.exp(-rate * A * np.asarray(t))))


def strain_law_rate(scene: pg.Scene, resolution: int, fibre_stiffness: float) -> np.ndarray:
    """Consequence 4: the homogeneous strain-law G (2, 2) at Fg = I from the scene's cell solved
    alone at the scene's E (a constant) and nu, with the scene's director and the given
    E_f / E (0: the unfibred tissue's)."""
    solver = CellSolver(scene.cell.at(0.0, 0.0), resolution, MPI.COMM_SELF, fibres=True)
    cell = solver.solve(np.eye(2), scene.material.E.start, scene.material.nu.start,
                        fibre_stiffness=fibre_stiffness,
                        fibre_angle=scene.walls.fibre_angle.start)  # fmt: skip
    g = scene.growth
    return growth.homogeneous_strain_rate(cell, scene.P1.start, g.eta.start, g.tau.start)


# --- the study --------------------------------------------------------------------------------


def one_direction(run: Path) -> dict:
    scene = pg.load_scene(SCENES / "fibres_one_direction.toml")
    summary, series = pg.read_results(run).summary, read_series(run)
    resolution = scene.accuracy.cell_resolution
    fibred, plain = (strain_law_rate(scene, resolution, e)
                     for e in (scene.walls.fibre_stiffness.start, 0.0))  # fmt: skip
    (w0, h0), (w1, h1) = (deformed_extent(series, t) for t in (series.times[0], series.times[-1]))
    return {
        "rates_t0": [summary["growth_rate_11"][0], summary["growth_rate_22"][0]],
        "formula_t0": [fibred[0, 0], fibred[1, 1]],
        "formula_unfibred": [plain[0, 0], plain[1, 1]],
        "cell_resolution": resolution,
        "rates_tmax": [summary["growth_rate_11"][-1], summary["growth_rate_22"][-1]],
        "width_ratio": w1 / w0,
        "height_ratio": h1 / h0,
        "aspect_ratio_change": (h1 / w1) / (h0 / w0),
        "grown_stretch_tmax": grown_stretch(series, series.times[-1]),
        "unfibred_aspect_ratio_change": 1.0,  # isotropic growth: formula_unfibred's g11 = g22
        "elastic_strain_max_tmax": summary["elastic_strain_max"][-1],
    }


def primordium(run: Path, plain: Path) -> dict:
    series, still = read_series(run), read_series(plain)
    t0, t1 = series.times[0], series.times[-1]
    summary = pg.read_results(run).summary
    return {
        "fibres_t0": ring_alignment(series, director_angle(series, t0)),
        "fibres_tmax": ring_alignment(series, director_angle(series, t1)),
        "fibres_tmax_no_feedback": ring_alignment(still, director_angle(still, t1)),
        "stress_t0": ring_alignment(series, stress_angle(series, t0)),
        "stress_tmax": ring_alignment(series, stress_angle(series, t1)),
        "stress_tmax_no_feedback": ring_alignment(still, stress_angle(still, t1)),
        "fibre_order_tmax": summary["fibre_order"][-1],
        "u2_max_tmax": summary["u2_max"][-1],
        "u2_max_tmax_no_feedback": pg.read_results(plain).summary["u2_max"][-1],
        "elastic_strain_max_tmax": summary["elastic_strain_max"][-1],
        "t_max": t1,
    }


def pull(run: Path) -> dict:
    scene = pg.load_scene(SCENES / "fibres_feedback_pull.toml")
    summary, series = pg.read_results(run).summary, read_series(run)
    A = pull_anisotropy(scene)
    expected = closed_form_angle(summary["t"], scene.walls.fibre_angle.start,
                                 scene.feedback.rate, A)  # fmt: skip
    sigma = series.cell_field("sigma_hom", series.times[-1])[:, [0, 1, 3, 4]].reshape(-1, 2, 2)
    return {
        "anisotropy": A,
        "anisotropy_from_run_tmax": [
            float(cue(sigma).anisotropy.min()),
            float(cue(sigma).anisotropy.max()),
        ],  # fmt: skip
        "angle_tmax": summary["fibre_angle_mean"][-1],
        "closed_form_tmax": expected[-1],
        "largest_difference_degrees": float(np.abs(summary["fibre_angle_mean"] - expected).max()),
        "growth_rate_11": summary["growth_rate_11"][-1],
        "growth_rate_22_max": float(np.abs(summary["growth_rate_22"]).max()),
    }


def run_without_feedback(results: Path, force: bool) -> Path:
    """Runs the primordium without [feedback] into ``results/<name>_nofeedback`` (unless
    complete) and returns that directory."""
    from run_gradient_scenes import run_scene_data  # scripts/studies/, next to this file

    data = tomllib.loads((SCENES / "fibres_feedback_primordium.toml").read_text())
    del data["feedback"]
    return run_scene_data(data, "fibres_feedback_primordium_nofeedback", results, force)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", type=Path, default=REPO / "results" / "biology")
    parser.add_argument("--force", action="store_true", help="rerun the run without feedback")
    args = parser.parse_args(argv)
    missing = [n for n in NAMES if not (args.results / n / "summary.csv").is_file()]
    if missing:
        print(f"no run of {', '.join(missing)} in {args.results}: run "
              "python scripts/studies/run_biology_scenes.py first", file=sys.stderr)  # fmt: skip
        return 1
    plain = run_without_feedback(args.results, args.force)
    out = {
        "machine": machine_description(),
        "fibres_one_direction": one_direction(args.results / NAMES[0]),
        "fibres_feedback_primordium": primordium(args.results / NAMES[1], plain),
        "fibres_feedback_pull": pull(args.results / NAMES[2]),
    }
    OUT.write_text(json.dumps(out, indent=2, default=float) + "\n")
    print(json.dumps(out, indent=2, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
