"""The director's sparse grid against plain trigonometric interpolation (issue 33, item 2).

The reference cell (l1 = l2 = 1, theta = 30, w = 0.05, nu = 0.3, E_f/E = 5, resolution 2) is
solved at 24 angle nodes (7.5 degrees apart) at 8 random stretches in the range the stress
feedback scene reaches (s1 in [0, 0.15], s2 in [-0.015, 0.04]) and on the level-0 and level-1
stretch grids around them (spacing 0.1 and 0.05), and at 10 random angles in [65, 120] (the
directors' range there at t = 60). For each it records the largest relative error
(director_lattice's measure) of I_6, I_12, I_24 on exact values, of the sparse grid
``I_6[f] + (I_12 - I_6)[P_1 f] + (I_24 - I_12)[P_0 f]`` (f exact at the 6 fine nodes) and of
two cheaper variants, and the interpolant's two estimates. Writes
``benchmarks/results/angle_sparse.json`` (about 600 solves, 10-30 s).

    python scripts/benchmarks/bench_angle_sparse.py
"""

from __future__ import annotations

import itertools
import json
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from plantgrowth.base.machine import machine_description
from plantgrowth.unitcell.director_lattice import trigonometric_weights
from plantgrowth.unitcell.homogenization import Homogenizer
from plantgrowth.unitcell.surrogate import H0, stretch

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/angle_sparse.json"
GEOMETRY, NU, STIFFNESS, RESOLUTION = (1.0, 1.0, 30.0, 0.05), 0.3, 5.0, 2
NODES = 24


def bilinear(corners: dict, spacing: float, s: np.ndarray) -> np.ndarray:
    """The bilinear interpolant at s of the grid values ``corners[(i, j)]`` (spacing apart)."""
    x = s / spacing
    base = np.floor(x).astype(int)
    t = x - base
    hats = {(0, 0): (1 - t[0]) * (1 - t[1]), (1, 0): t[0] * (1 - t[1]),
            (0, 1): (1 - t[0]) * t[1], (1, 1): t[0] * t[1]}  # fmt: skip
    return sum(w * corners[base[0] + a, base[1] + c] for (a, c), w in hats.items())


def main() -> int:
    start = time.perf_counter()
    homogenizer = Homogenizer(RESOLUTION, 1e-6, True, True, MPI.COMM_SELF, cell_tolerance=1.0)
    difference = homogenizer.surrogate.relative_difference

    def f(angle: float, s: np.ndarray) -> np.ndarray:
        return homogenizer._solve_exact(GEOMETRY, NU, stretch(s), (STIFFNESS, float(angle)))

    rng = np.random.default_rng(0)
    stretches = np.column_stack([rng.uniform(0, 0.15, 8), rng.uniform(-0.015, 0.04, 8)])
    angles = rng.uniform(65.0, 120.0, 10)
    nodes = np.arange(NODES) * 180.0 / NODES
    grids = {
        level: {c: np.array([f(a, np.array(c) * H0 / 2**level) for a in nodes])
                for c in itertools.product(range(3 * 2**level - level), [-1, 0, 1])}
        for level in (0, 1)
    }  # fmt: skip
    errors: dict[str, list[float]] = {}
    for s in stretches:
        at_nodes = np.array([f(a, s) for a in nodes])
        p0, p1 = (bilinear(grids[k], H0 / 2**k, s) for k in (0, 1))
        for b in angles:
            exact = f(b, s)

            def interp(values: np.ndarray, count: int, b: float = b) -> np.ndarray:
                return (trigonometric_weights(np.array([b]), count) @ values[:: NODES // count])[0]

            first, tail = interp(p1, 12) - interp(p1, 6), interp(p0, 24) - interp(p0, 12)
            sparse = interp(at_nodes, 6) + first + tail
            mixed = first - (interp(p0, 12) - interp(p0, 6))
            found = {
                "I_6": interp(at_nodes, 6), "I_12": interp(at_nodes, 12),
                "I_24": interp(at_nodes, 24), "sparse": sparse,
                "I_6 + (I_24 - I_6)[P_0]": interp(at_nodes, 6) + interp(p0, 24) - interp(p0, 6),
                "I_12 + (I_24 - I_12)[P_0]": interp(at_nodes, 12) + tail,
            }  # fmt: skip
            for name, value in found.items():
                errors.setdefault(name, []).append(float(difference(value, exact)))
            errors.setdefault("estimate: last surplus", []).append(
                float(difference(sparse - tail, sparse))
            )
            errors.setdefault("estimate: level-1 grid's change", []).append(
                float(difference(sparse - mixed, sparse))
            )
    result = {
        "cell": dict(zip(("l1", "l2", "theta", "w"), GEOMETRY, strict=True)), "nu": NU,
        "fibre_stiffness": STIFFNESS, "resolution": RESOLUTION,
        "stretches": stretches.tolist(), "angles": angles.tolist(),
        "largest": {k: max(v) for k, v in errors.items()},
        "median": {k: float(np.median(v)) for k, v in errors.items()},
        "machine": machine_description(), "script_seconds": time.perf_counter() - start,
    }  # fmt: skip
    print(json.dumps(result["largest"], indent=1))
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
