"""Measured outcomes of the three water scenes of ``scenes/biology/`` (issue 35, item 7;
docs/hydraulics.md) into ``benchmarks/results/water_biology.json``.

Reads the runs of ``scripts/studies/run_biology_scenes.py`` (the scenes as shipped) in
``results/biology/<name>/`` and runs the fast patch once more with ``model = "micro"`` up to
t = 10 beside them (``fast_patch_micro/``, skipped when complete unless ``--force``; the micro
tissue of 16 cells across costs minutes a step at t_max = 60):

- ``drought``: at the last step of each phase of the supply's potential (before, during and
  after the drought) the growth rate and mean turgor, against the Lockhart-Ortega forms of
  docs/model.md ("Water fluxes", consequence 3) with the run's own L' (:func:`quasi_steady`);
- ``apex_fed_from_below``: the decay length of P above the strand (:func:`decay_length`)
  against the hydraulic length sqrt(kappa / (phi_L (1 - phi_w))) (:func:`hydraulic_length`),
  and the apex's turgor and growth over the strand's;
- ``fast_patch``: turgor and growth of the patch, its neighbours (the ring) and the distant
  cells, and the water the patch draws from its neighbours (macro: :func:`patch_inflow_macro`,
  micro: :func:`patch_inflow_micro`) against what its own supply gives: macro at t = 10 (the
  micro run's t_max) and 60, micro at t = 10.

The measures are functions of this module, which tests/test_biology_water.py applies to its
draft runs. ``python scripts/studies/water_biology.py [--results DIR] [--force]``
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import tomllib
from pathlib import Path

import numpy as np

import plantgrowth as pg
from plantgrowth.base.machine import machine_description
from plantgrowth.models.macro.hydraulics import cell_scale
from plantgrowth.results.reader import ResultSeries, read_series
from plantgrowth.unitcell.hydraulic_coefficients import conductivity

REPO = Path(__file__).resolve().parents[2]
SCENES = REPO / "scenes" / "biology"
OUT = REPO / "benchmarks" / "results" / "water_biology.json"
NAMES = ("drought", "apex_fed_from_below", "fast_patch")
PATCH, RADIUS = (3.464, 1.5), 1.0  # the fast patch's centre and radius (fast_patch.toml)
MICRO_T_MAX = 10.0  # the micro fast patch: five storage relaxation times (about 2 T each)


def row_at(run: Path, t: float) -> dict[str, float]:
    """summary.csv's row at time t."""
    summary = pg.read_results(run).summary
    (i,) = np.flatnonzero(np.isclose(summary["t"], t))
    return {k: float(v[i]) for k, v in summary.items()}


def phi_w_and_phi_L(scene: pg.Scene) -> tuple[float, float]:
    """The wall fraction of the scene's cell (at the origin) and ``phi_L = 2 eta (1 - phi_w) /
    phi_w`` of the stress law at its eta there (docs/model.md, consequence 3)."""
    phi_w = scene.cell.at(0.0, 0.0).phi_w
    return phi_w, 2.0 * scene.growth.eta.start * (1.0 - phi_w) / phi_w


def quasi_steady(scene: pg.Scene, row: dict[str, float]) -> tuple[float, float]:
    """Lockhart-Ortega (docs/model.md, "Water fluxes", consequence 3; tau = 0) for a homogeneous
    rectangular tissue whose supplies are edges of one conductance L_s and one potential: the
    growth rate ``g = phi_L L' (Pi + psi_s) / (phi_L + L')`` and turgor ``P = L' (Pi + psi_s) /
    (L' + phi_L)`` at the row's time, ``L' = L_s perimeter / (f area)`` with the supplied edges'
    reference length (top: the width; left, right: the height) grown by sqrt(Jg) (uniform
    growth: Jg = det_Fg_min) and ``f area`` the lumens' water, summary.csv's ``water``."""
    supplies = scene.hydraulics.supplies
    (L_s,) = {s.conductance for s in supplies}
    length = {"top": scene.tissue.width, "left": scene.tissue.height,
              "right": scene.tissue.height}  # fmt: skip
    perimeter = math.sqrt(row["det_Fg_min"]) * sum(length[s.name] for s in supplies)
    L_prime = L_s * perimeter / row["water"]
    drive = scene.hydraulics.osmotic.start + supplies[0].potential(row["t"])
    _, phi_L = phi_w_and_phi_L(scene)
    return phi_L * L_prime * drive / (phi_L + L_prime), L_prime * drive / (L_prime + phi_L)


def drought(run: Path, scene: pg.Scene) -> dict:
    """Growth rate and mean turgor at the last step of each phase of the supplies' potential,
    with their Lockhart-Ortega values, and the rates during and after over the rate before."""
    times = scene.hydraulics.supplies[0].potential.times
    ends = [t - scene.time.dt for t in times[1:]] + [scene.time.t_max]
    out = {}
    for phase, t in zip(("before", "during", "after"), ends, strict=True):
        row = row_at(run, t)
        g, P = quasi_steady(scene, row)
        spread = (row["turgor_max"] - row["turgor_min"]) / row["turgor_mean"]
        out[phase] = {"t": t, "growth_rate_area": row["growth_rate_area"], "lockhart_ortega_g": g,
                      "turgor_mean": row["turgor_mean"], "lockhart_ortega_P": P,
                      "turgor_spread": spread}  # fmt: skip
    before = out["before"]["growth_rate_area"]
    out["during_over_before"] = out["during"]["growth_rate_area"] / before
    out["after_over_before"] = out["after"]["growth_rate_area"] / before
    return out


def hydraulic_length(scene: pg.Scene) -> float:
    """``sqrt(kappa / (phi_L (1 - phi_w)))`` at Fg = I (docs/model.md, consequence 4), kappa =
    cell_scale L kappa_unit of the scene's cells (``4 / micro.nx`` times its cell)."""
    phi_w, phi_L = phi_w_and_phi_L(scene)
    kappa = cell_scale(scene.micro_nx) * scene.hydraulics.conductivity.start
    kappa *= conductivity(scene.cell.at(0.0, 0.0), np.eye(2))[1, 1]
    return math.sqrt(kappa / (phi_L * (1.0 - phi_w)))


def decay_length(series: ResultSeries, t: float, x2: float) -> float:
    """The length l of ``P ~ cosh((H - x2) / l)`` below a sealed top edge H (kappa P'' = phi_L
    (1 - phi_w) P, tau = 0): ``(H - x2) / arccosh(P(x2) / P(H))`` from the mean P of the node
    rows at x2 and at the top."""
    rows, P = series.points[:, 1], series.node_field("P", t)
    top = rows.max()
    return (top - x2) / math.acosh(P[np.isclose(rows, x2)].mean() / P[np.isclose(rows, top)].mean())


def apex(run: Path, scene: pg.Scene) -> dict:
    """The decay length above the strand (from x2 = 1) against the hydraulic length, and the
    apex's turgor and growth over the strand's, at t_max."""
    t = scene.time.t_max
    row, measured = row_at(run, t), decay_length(read_series(run), t, 1.0)
    return {"t": t, "decay_length": measured, "hydraulic_length": hydraulic_length(scene),
            "ratio": measured / hydraulic_length(scene),
            "apex_over_strand_turgor": row["apex.turgor_mean"] / row["strand.turgor_mean"],
            "apex_over_strand_trG": row["apex.trG"] / row["strand.trG"]}  # fmt: skip


def triangles_around_patch(series: ResultSeries) -> tuple[np.ndarray, np.ndarray]:
    """The reference areas (M,) of the fine triangles and their midpoints' offsets (M, 2) from
    the patch's centre."""
    corners = series.points[series.triangles]
    e1, e2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    return area, corners.mean(axis=1) - PATCH


def patch_inflow_macro(series: ResultSeries, t: float) -> float:
    """The water that crosses the patch's boundary r = 1 inward per unit time: ``-int Q .
    grad(w) dx`` with w = 1 inside r = 0.8, 0 outside r = 1.2 and linear in r between (the flux
    through the circles 0.8 < r < 1.2, averaged over r), Q the reference-frame water_flux,
    constant on each triangle."""
    area, offset = triangles_around_patch(series)
    r = np.hypot(offset[:, 0], offset[:, 1])
    ring = np.abs(r - RADIUS) < 0.2
    Q = series.cell_field("water_flux", t)[ring, :2]
    inward = -(Q * offset[ring]).sum(axis=1) / r[ring]
    return float(area[ring] @ inward / 0.4)


def patch_uptake_macro(series: ResultSeries, t: float, phi_w: float) -> float:
    """What the patch's growth takes up per unit time, ``(1 - phi_w) int_patch Jg tr G dx``
    over the triangles whose midpoints lie in r < 1: its lumens' growth, at the lumen fraction
    of the unstrained cell, without the change of their elastic strain and storage. The water
    from the supply and from the neighbours should add up to it, a check on
    :func:`patch_inflow_macro`."""
    area, offset = triangles_around_patch(series)
    inside = np.hypot(offset[:, 0], offset[:, 1]) < RADIUS
    grown = area * series.cell_field("Fg", t, "det") * series.cell_field("trG", t)
    return float((1.0 - phi_w) * grown[inside].sum())


def patch_inflow_micro(run: Path, t: float) -> tuple[float, int]:
    """The water the patch's cells (centres within r < 1) take from their neighbours per unit
    time: their cells.csv ``inflow`` (neighbours and supply) less summary.csv's
    ``inflow.region.patch`` (their supply); and how many cells the patch has."""
    with open(run / "cells.csv", newline="") as f:
        rows = [r for r in csv.DictReader(f) if math.isclose(float(r["t"]), t)]
    x = np.array([[float(r["x1_ref"]), float(r["x2_ref"]), float(r["inflow"])] for r in rows])
    inside = np.hypot(x[:, 0] - PATCH[0], x[:, 1] - PATCH[1]) < RADIUS
    return float(x[inside, 2].sum() - row_at(run, t)["inflow.region.patch"]), int(inside.sum())


def patch_outcome(run: Path, t: float, lateral: float) -> dict:
    """Turgor and growth of the patch, ring and far regions at t, their ratios, and the water
    drawn from the neighbours (``lateral``) over the patch's own supply's."""
    row = row_at(run, t)
    out = {"t": t, "from_neighbours": lateral, "from_supply": row["inflow.region.patch"],
           "neighbours_over_supply": lateral / row["inflow.region.patch"]}  # fmt: skip
    for region in ("patch", "ring", "far"):
        out[f"{region}_turgor"], out[f"{region}_trG"] = (row[f"{region}.turgor_mean"],
                                                         row[f"{region}.trG"])  # fmt: skip
    out["patch_over_ring_turgor"] = out["patch_turgor"] / out["ring_turgor"]
    out["ring_over_far_turgor"] = out["ring_turgor"] / out["far_turgor"]
    out["ring_over_far_trG"] = out["ring_trG"] / out["far_trG"]
    return out


def macro_patch(run: Path, t: float, scene: pg.Scene) -> dict:
    """:func:`patch_outcome` of a macro run, with the patch's growth uptake
    (:func:`patch_uptake_macro`) beside the water it takes from its supply and neighbours."""
    series = read_series(run)
    out = patch_outcome(run, t, patch_inflow_macro(series, t))
    out["growth_uptake"] = patch_uptake_macro(series, t, scene.cell.at(0.0, 0.0).phi_w)
    out["inflow_over_uptake"] = (out["from_supply"] + out["from_neighbours"]) / out["growth_uptake"]
    return out


def run_micro_patch(results: Path, force: bool) -> Path:
    """fast_patch.toml with ``model = "micro"`` and t_max = MICRO_T_MAX (its output's
    macro-only water fields left out) into ``results/fast_patch_micro`` (unless complete);
    returns that directory."""
    from run_gradient_scenes import run_scene_data  # scripts/studies/, next to this file

    data = tomllib.loads((SCENES / "fast_patch.toml").read_text())
    data |= {"model": "micro", "output": {}, "time": {"t_max": MICRO_T_MAX}}
    return run_scene_data(data, "fast_patch_micro", results, force)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--results", type=Path, default=REPO / "results" / "biology")
    parser.add_argument("--force", action="store_true", help="rerun the micro fast patch")
    args = parser.parse_args(argv)
    missing = [n for n in NAMES if not (args.results / n / "summary.csv").is_file()]
    if missing:
        print(f"no run of {', '.join(missing)} in {args.results}: run "
              "python scripts/studies/run_biology_scenes.py first", file=sys.stderr)  # fmt: skip
        return 1
    scenes = {n: pg.load_scene(SCENES / f"{n}.toml") for n in NAMES}
    macro, micro = args.results / "fast_patch", run_micro_patch(args.results, args.force)
    t_max = scenes["fast_patch"].time.t_max
    out = {
        "machine": machine_description(),
        "drought": drought(args.results / "drought", scenes["drought"]),
        "apex_fed_from_below": apex(args.results / "apex_fed_from_below",
                                    scenes["apex_fed_from_below"]),
        "fast_patch_macro": [macro_patch(macro, t, scenes["fast_patch"])
                             for t in (MICRO_T_MAX, t_max)],
        "fast_patch_micro": patch_outcome(micro, MICRO_T_MAX,
                                          patch_inflow_micro(micro, MICRO_T_MAX)[0]),
    }  # fmt: skip
    OUT.write_text(json.dumps(out, indent=2, default=float) + "\n")
    print(json.dumps(out, indent=2, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
