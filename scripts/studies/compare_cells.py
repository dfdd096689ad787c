"""Micro against macro on generated tissues of rising irregularity (issue 34, item 4;
docs/real_tissues.md, "The macro model from cells").

For each N (``--cells``, default 32 and 128: Nx = 8 and 16) and regularity r (``--r``, default
0, 0.25, 0.5, 1), the reference stress scene with ``[tissue] cells = {voronoi = N, seed, r}``:
the macro model on those cells (their outline, each cell's shape Fs) against the micro model on
the same cells (walls ``cell.w * 4 / Nx``, as a generated tissue's), at the first step and,
with ``--steps n``, at t_max = n dt of a short run (the errors of docs/model.md section 8:
err_u1, err_u2, err_ubar, err_G) through :func:`plantgrowth.studies.compare.compare_one`, for
each seed of ``--seed``. A run that stops (the micro walls of a random
tissue can buckle under turgor: numerics.on_instability = "stop"; a cell too thin for its
walls has no void) is recorded with its error.
Other macro sides (``--variants``): every Fs = I (the regular unit cell on the same outline),
which shows what the shapes change, the shapes smoothed over each cell's neighbours, and the
tissue's mean shape everywhere.

Raw runs go to ``--raw`` (default ``results/compare_cells``, git-ignored); ``--json`` (default
``benchmarks/results/compare_cells.json``) gets the rows, seconds and the machine description.

    nice -n 10 python scripts/studies/compare_cells.py [--cells 32] [--r 0 0.5] [--seed 1 2]
        [--steps 2]
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
from plantgrowth.meshes.cell_outline import CellShapeField
from plantgrowth.meshes.geometry_error import GeometryError
from plantgrowth.meshes.voronoi_tissue import voronoi_nx
from plantgrowth.models.macro.domain import macro_domain
from plantgrowth.scene import parse_scene
from plantgrowth.scene.micro_tissue import micro_tissue
from plantgrowth.scene.tissue_cells import cell_polygons
from plantgrowth.studies.compare import compare_one

ROOT = Path(__file__).resolve().parents[2]
ERRORS = ("err_u1", "err_u2", "err_ubar", "err_G")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add = parser.add_argument
    add("--cells", type=int, nargs="+", default=[32, 128], help="N = Nx^2 / 2 cells")
    add("--r", type=float, nargs="+", default=[0.0, 0.25, 0.5, 1.0], help="regularity r")
    add("--seed", type=int, nargs="+", default=[1])
    add("--steps", type=int, default=0, help="steps of the short run (0: the first step only)")
    add("--kinematics", default="linear", choices=["linear", "finite"])
    variants = ["shaped", "unshaped", "smoothed", "mean"]
    add("--variants", nargs="+", default=variants[:2], choices=variants, help="macro sides")
    add("--raw", type=Path, default=ROOT / "results" / "compare_cells")
    add("--json", type=Path, default=ROOT / "benchmarks" / "results" / "compare_cells.json")
    return parser.parse_args(argv)


def smoothed(field: CellShapeField) -> CellShapeField:
    """Each cell's Fs replaced by the area-weighted log-Euclidean mean over the cell and its
    neighbours, ``exp(sum_j a_j log Fs_j / sum_j a_j)``: the shapes varying more slowly than
    cell by cell."""
    cells, shapes = field.cells, field.shapes
    values, vectors = np.linalg.eigh(shapes.Fg0)
    logs = np.einsum("nik,nk,njk->nij", vectors, np.log(values), vectors)
    total = shapes.areas[:, None, None] * logs
    weight = shapes.areas.copy()
    for found in cells.sides().values():
        if len(found) == 2:
            a, b = found
            total[a] += shapes.areas[b] * logs[b]
            total[b] += shapes.areas[a] * logs[a]
            weight[a] += shapes.areas[b]
            weight[b] += shapes.areas[a]
    values, vectors = np.linalg.eigh(total / weight[:, None, None])
    mean = np.einsum("nik,nk,njk->nij", vectors, np.exp(values), vectors)
    return CellShapeField(cells, dataclasses.replace(shapes, Fg0=mean))


def tissue_mean(field: CellShapeField) -> CellShapeField:
    """Every cell's Fs replaced by the tissue's area-weighted log-Euclidean mean of them: the
    tissue's mean anisotropy, no cell-to-cell variation."""
    shapes = field.shapes
    values, vectors = np.linalg.eigh(shapes.Fg0)
    logs = np.einsum("nik,nk,njk->nij", vectors, np.log(values), vectors)
    values, vectors = np.linalg.eigh(
        np.einsum("n,nij->ij", shapes.areas, logs) / shapes.areas.sum()
    )
    mean = vectors @ np.diag(np.exp(values)) @ vectors.T
    return CellShapeField(
        field.cells, dataclasses.replace(shapes, Fg0=np.broadcast_to(mean, shapes.Fg0.shape))
    )


def one(
    n: int, r: float, seed: int, raw: Path, comm: MPI.Comm, variants: list[str], steps: int,
    kinematics: str = "linear",
) -> dict:  # fmt: skip
    """The compare row of N cells at regularity r for each variant of the macro side: the
    cells' shapes, none (Fs = I), the shapes smoothed over neighbours (:func:`smoothed`), the
    tissue's mean shape (:func:`tissue_mean`)."""
    nx = voronoi_nx(n)
    scene = parse_scene({
        "model": "macro", "kinematics": kinematics,
        "tissue": {"cells": {"voronoi": n, "seed": seed, "regularity": r}},
        "growth": {"law": "stress"}, "micro": {"resolution": 2},
    })  # fmt: skip
    cells = cell_polygons(scene)
    tissue = micro_tissue(scene)  # walls cell.w * 4 / Nx, the bottom row cut
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
    domains = {
        "shaped": domain,
        "unshaped": dataclasses.replace(domain, cell_shape=None),
        "smoothed": dataclasses.replace(domain, cell_shape=smoothed(domain.cell_shape)),
        "mean": dataclasses.replace(domain, cell_shape=tissue_mean(domain.cell_shape)),
    }
    for label in variants:
        dom = domains[label]
        start = time.perf_counter()
        try:
            name = f"n{n}_r{r:g}_s{seed}_{label}_{kinematics}"
            row = compare_one(scene, dom, nx, raw / name, comm, None, steps, tissue)
        except (RunError, GeometryError) as err:  # walls buckle; a cell too thin for its walls
            out[label] = {"error": str(err), "seconds": time.perf_counter() - start}
            continue
        out[label] = {
            k: row[k]
            for k in (*ERRORS, *(f"{e}_tmax" for e in ERRORS), "rate_macro_t0",
                      "rate_micro_t0", "rate_macro_tmax", "rate_micro_tmax", "dofs_macro",
                      "dofs_micro")
        }  # fmt: skip
        out[label]["seconds"] = time.perf_counter() - start
    return out


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    comm = MPI.COMM_WORLD
    rows = []
    for seed in args.seed:
        for n in args.cells:
            for r in args.r:
                rows.append(
                    one(n, r, seed, args.raw, comm, args.variants, args.steps, args.kinematics)
                )
                if comm.rank == 0:
                    for label in args.variants:
                        row = rows[-1][label]
                        text = row.get("error") or ", ".join(
                            f"{k} {row[k]:.4g}" for k in ERRORS if row[k] is not None
                        )
                        print(f"N = {n}, r = {r:g}, seed {seed}, {label}: {text}", flush=True)
                    args.json.parent.mkdir(parents=True, exist_ok=True)
                    args.json.write_text(  # after every row: a long study keeps what it ran
                        json.dumps(
                            {"machine": machine_description(), "ranks": comm.size,
                             "steps": args.steps, "kinematics": args.kinematics, "rows": rows},
                            indent=1,
                        )  # fmt: skip
                    )


if __name__ == "__main__":
    main()
