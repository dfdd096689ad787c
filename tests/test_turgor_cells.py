"""Turgor against cell size in an irregular tissue (issue 34, item 5; Long et al. 2020;
docs/real_tissues.md, "Turgor and cell size"): a draft of scenes/biology/irregular_turgor.toml
(32 generated cells instead of 128, one step), serial and under ``mpirun -n 2``.

Asserted: over the interior cells (every side shared), the Spearman rank correlation of each
cell's growth rate tr G with its current area at t = 1 is above MARGIN: the sign that
scripts/studies/turgor_vs_cells.py finds for 128 cells on seeds 1-3 at every time
(benchmarks/results/turgor_vs_cells.json: 0.63-0.75 at t = 1). Not asserted: the sign of turgor
against area. It is negative for 128 cells on every seed and time, as Long et al. found, but
weak (-0.03 to -0.20) and gone once the tissue-scale turgor pattern is taken out, and on this
draft's 11-12 interior cells it is not robust (seeds 1, 2, 3: -0.17, +0.07, +0.61).
"""

from __future__ import annotations

import csv
import tomllib
from pathlib import Path

import numpy as np
import pytest
from mpi4py import MPI
from scipy import stats

from plantgrowth.api import run
from plantgrowth.scene import parse_scene
from plantgrowth.scene.tissue_cells import cell_polygons

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "biology" / "irregular_turgor.toml"
MARGIN = 0.5  # see test_growth_rate_rises_with_cell_area


def draft(seed: int):
    data = tomllib.loads(SCENE.read_text())
    data["tissue"]["cells"] |= {"voronoi": 32, "seed": seed}
    data["time"]["t_max"] = 1.0
    data["micro"] = {"resolution": 1}  # one P2 element across a wall (the scene: 2)
    return parse_scene(data, directory=SCENE.parent)


def interior(scene) -> np.ndarray:
    """The cells whose every side is shared with another cell."""
    cells = cell_polygons(scene)
    outer = {found[0] for found in cells.sides().values() if len(found) == 1}
    return np.array([i for i in range(cells.n_cells) if i not in outer])


def rows_at(outdir: Path, t: float) -> dict[str, np.ndarray]:
    with (outdir / "cells.csv").open(newline="") as f:
        rows = sorted((r for r in csv.DictReader(f) if float(r["t"]) == t),
                      key=lambda r: int(r["cell"]))  # fmt: skip
    return {k: np.array([float(r[k]) for r in rows]) for k in ("P", "area", "trG")}


@pytest.mark.mpi
def test_growth_rate_rises_with_cell_area(tmp_path_factory):
    comm = MPI.COMM_WORLD
    outdir = Path(comm.bcast(str(tmp_path_factory.mktemp("turgor_cells")) if comm.rank == 0
                             else None))  # fmt: skip
    scene = draft(2)
    run(scene, outdir / "run", comm)
    columns, cells = rows_at(outdir / "run", 1.0), interior(scene)
    assert len(cells) == 11
    assert np.ptp(columns["P"][cells]) > 0.0  # the cells' turgor differs
    rho = stats.spearmanr(columns["area"][cells], columns["trG"][cells])[0]
    # MARGIN 0.5: measured 0.92 (seed 2; seeds 1 and 3: 0.59, 0.91), so a clear positive trend
    # is asserted, not just the sign; mpirun changes cells.csv by 1e-8 relative at most
    # (tests/test_micro_cells.py), far too little to move a rank correlation
    assert rho > MARGIN, rho
