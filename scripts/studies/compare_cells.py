"""Micro against macro on generated tissues of rising irregularity (issue 34, item 4;
docs/real_tissues.md, "The macro model from cells").

For each N (``--cells``, default 32 and 128: Nx = 8 and 16) and regularity r (``--r``, default
0, 0.25, 0.5, 1), the reference stress scene with ``[tissue] cells = {voronoi = N, seed, r}``:
the macro model on those cells (their outline, each cell's shape Fs) against the micro model on
the same cells (walls ``cell.w * 4 / Nx``, as a generated tissue's), at the first step (the
errors of docs/model.md section 8: err_u1, err_u2, err_ubar, err_G) through
:func:`plantgrowth.studies.compare.compare_one`. A run that stops (the micro walls of a random
tissue can buckle under turgor: numerics.on_instability = "stop") is recorded with its error.
A second macro run with every Fs = I (the regular unit cell on the same outline) shows what
the shapes change.

Raw runs go to ``--raw`` (default ``results/compare_cells``, git-ignored); ``--json`` (default
``benchmarks/results/compare_cells.json``) gets the rows, seconds and the machine description.

    nice -n 19 python scripts/studies/compare_cells.py [--cells 32] [--r 0 0.5] [--seed 1]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from plantgrowth.base.errors import RunError
from plantgrowth.base.machine import machine_description
from plantgrowth.meshes.cell_tissue import CellTissue
from plantgrowth.meshes.voronoi_tissue import voronoi_nx
from plantgrowth.models.macro.domain import macro_domain
from plantgrowth.scene import parse_scene
from plantgrowth.scene.tissue_cells import cell_polygons
from plantgrowth.studies.compare import compare_one

ROOT = Path(__file__).resolve().parents[2]
ERRORS = ("err_u1", "err_u2", "err_ubar", "err_G")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add = parser.add_argument
    add("--cells", type=int, nargs="+", default=[32, 128], help="N = Nx^2 / 2 cells")
    add("--r", type=float, nargs="+", default=[0.0, 0.25, 0.5, 1.0], help="regularity r")
    add("--seed", type=int, default=1)
    add("--raw", type=Path, default=ROOT / "results" / "compare_cells")
    add("--json", type=Path, default=ROOT / "benchmarks" / "results" / "compare_cells.json")
    return parser.parse_args(argv)


def one(n: int, r: float, seed: int, raw: Path, comm: MPI.Comm) -> dict:
    """The compare row of N cells at regularity r, with and without the cells' shapes."""
    nx = voronoi_nx(n)
    scene = parse_scene({
        "model": "macro", "tissue": {"cells": {"voronoi": n, "seed": seed, "regularity": r}},
        "growth": {"law": "stress"}, "micro": {"resolution": 2},
    })  # fmt: skip
    cells = cell_polygons(scene)
    tissue = CellTissue.from_cells(cells, scene.cell.at(0.0, 0.0).w * 4.0 / nx)
    domain = macro_domain(scene, comm)
    shapes = domain.cell_shape.shapes
    out = {
        "cells": n,
        "nx": nx,
        "r": r,
        "seed": seed,
        "neighbours": np.bincount(cells.neighbour_counts).tolist(),
        "det_Fs": [float(np.linalg.det(shapes.Fg0).min()), float(np.linalg.det(shapes.Fg0).max())],
        "anisotropy_Fs_max": float(np.max(np.divide(*np.linalg.eigvalsh(shapes.Fg0).T[::-1]))),
    }
    for label, dom in (
        ("shaped", domain),
        ("unshaped", dataclasses.replace(domain, cell_shape=None)),
    ):
        start = time.perf_counter()
        try:
            row = compare_one(scene, dom, nx, raw / f"n{n}_r{r:g}_{label}", comm, None, 0, tissue)
        except RunError as err:  # e.g. the micro walls of a random tissue buckle
            out[label] = {"error": str(err), "seconds": time.perf_counter() - start}
            continue
        out[label] = {
            k: row[k]
            for k in (*ERRORS, "rate_macro_t0", "rate_micro_t0", "dofs_macro", "dofs_micro")
        }
        out[label]["seconds"] = time.perf_counter() - start
    return out


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    comm = MPI.COMM_WORLD
    rows = []
    for n in args.cells:
        for r in args.r:
            rows.append(one(n, r, args.seed, args.raw, comm))
            if comm.rank == 0:
                s, u = rows[-1]["shaped"], rows[-1]["unshaped"]
                text = s.get("error") or ", ".join(
                    f"{k} {s[k]:.4g} (Fs = I: {u[k]:.4g})" for k in ERRORS
                )  # fmt: skip
                print(f"N = {n}, r = {r:g}: {text}", flush=True)
    if comm.rank == 0:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(
            json.dumps(
                {"machine": machine_description(), "ranks": comm.size, "rows": rows}, indent=1
            )
        )


if __name__ == "__main__":
    main()
