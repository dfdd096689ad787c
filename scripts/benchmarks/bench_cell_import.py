"""Generated tissues rasterised and imported again (issue 34, docs/real_tissues.md): the round
trip's errors and the time each stage takes.

For each (cells, regularity, pixel size): the generator's tissue
(meshes/voronoi_tissue.py), its label image (scripts/studies/make_synthetic_tissue.py's
rasteriser), then the import (specks, checks, tracing); per cell the area error over perimeter
times pixel size, the perimeter error in pixels per side, the centroid error in pixels, and how
many cells' neighbour counts differ. Times are medians of ``--repeats`` runs (seconds).

    python scripts/benchmarks/bench_cell_import.py [--repeats 3]
        -> benchmarks/results/cell_import.json
"""

from __future__ import annotations

import argparse
import json
import runpy
import time
from pathlib import Path

import numpy as np

from plantgrowth.base.machine import machine_description
from plantgrowth.meshes.honeycomb import HoneycombCell
from plantgrowth.meshes.label_checks import absorb_specks, check_labels
from plantgrowth.meshes.label_tracing import trace_cells
from plantgrowth.meshes.voronoi_tissue import voronoi_tissue

ROOT = Path(__file__).resolve().parents[2]
RASTERISE = runpy.run_path(str(ROOT / "scripts" / "studies" / "make_synthetic_tissue.py"))[
    "rasterise"
]
CASES = [(32, 0.5, 0.02), (968, 0.5, 0.005), (968, 1.0, 0.005), (968, 1.0, 0.0025)]
"""(cells, regularity, pixel size): the shipped example, then 1,000 cells at about 31 and 62
pixels across a cell (the tissue is 6.9 x 2.8 length units whatever the cell count)."""


def _timed(repeats: int, f, *args):
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = f(*args)
        times.append(time.perf_counter() - t0)
    return out, float(np.median(times))


def _import(image: np.ndarray, pixel_size: float):
    labels = absorb_specks(image)
    check_labels(labels, "image")
    return trace_cells(labels, pixel_size)


def measure(n: int, r: float, p: float, repeats: int) -> dict:
    truth, generate = _timed(repeats, voronoi_tissue, HoneycombCell(), n, 1, r)
    image = RASTERISE(truth, p, 6).astype(np.int32)
    cells, trace = _timed(repeats, _import, image, p)
    order = np.argsort(cells.labels)
    sides = np.array([len(c) for c in truth.cells])
    return {
        "cells": n, "regularity": r, "pixel_size": p, "image": list(image.shape),
        "pixels_across_a_cell": float(np.sqrt(truth.areas.mean()) / p),
        "area_error_over_P_p": float((abs(cells.areas[order] - truth.areas)
                                      / (truth.perimeters * p)).max()),
        "perimeter_error_pixels_per_side": float((abs(cells.perimeters[order] - truth.perimeters)
                                                  / p / sides).max()),
        "centroid_error_pixels": float(abs(cells.centroids[order] - truth.centroids).max() / p),
        "neighbour_counts_differ": int((cells.neighbour_counts[order]
                                        != truth.neighbour_counts).sum()),
        "seconds_generate": generate, "seconds_import": trace,
    }  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks/results/cell_import.json")
    args = parser.parse_args(argv)
    rows = [measure(n, r, p, args.repeats) for n, r, p in CASES]
    for row in rows:
        print(json.dumps(row))
    result = {"rows": rows, "repeats": args.repeats, "machine": machine_description()}
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
