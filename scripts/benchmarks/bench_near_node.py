"""The near-node form's error against the distance to the node (issue 33; the choice of
``plantgrowth.unitcell.director_lattice.NEAR_NODE``).

Near a fine node b_k of the director's angle interpolant the answer is the near-node form

    A_k(b, s) = S_k(s) + (I_M - I_k)[P_0 f](b, s)

(module docstring of :mod:`plantgrowth.unitcell.director_lattice`): node k's own stretch table
plus the angle interpolant's change on the M nodes' level-0 stretch grid. Its error is first
order in the distance d = |b - b_k| times the error of the angle derivative that P_0 and I_M
give, plus the second-order term the form leaves out. This script measures it on the reference
cell (l1 = l2 = 1, theta = 30, w = 0.05, nu = 0.3, E_f/E = 5, resolution 2: the ``balanced``
cell) with M = 6: at 8 random stretches in the range the fibred gradient scenes reach (s1 in
[0, 0.15], s2 in [-0.015, 0.04]) and at distances ``DISTANCES`` on both sides of the nodes 90
and 60 degrees, against the exact cell solve at (b, s). S_k is taken exact (the stretch table's
own error is the stretch surrogate's, held to the tolerance separately). Records the largest and
median relative errors (the surrogate's measure, Frobenius per segment) per distance, with the
exact map's own relative change from the node (what answering S_k alone would err by). Writes
``benchmarks/results/near_node.json`` (about 500 solves, 10-20 s).

    python scripts/benchmarks/bench_near_node.py
"""

from __future__ import annotations

import itertools
import json
import sys
import time
from pathlib import Path

import numpy as np
from bench_angle_sparse import GEOMETRY, NU, RESOLUTION, STIFFNESS, bilinear, fibred_cell

from plantgrowth.base.machine import machine_description
from plantgrowth.unitcell.director_lattice import FINE_NODES, trigonometric_weights
from plantgrowth.unitcell.surrogate import H0

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks/results/near_node.json"
DISTANCES = (0.005, 0.01, 0.025, 0.05, 0.1, 0.2, 0.5)
"""Distances to the node (degrees); the fine spacing at M = 6 is 30 degrees."""
NODES = (90.0, 60.0)


def main() -> int:
    start = time.perf_counter()
    f, difference, stretches, _ = fibred_cell()
    fine = np.arange(FINE_NODES) * 180.0 / FINE_NODES
    grid0 = {c: [f(a, np.array(c) * H0) for a in fine]
             for c in itertools.product(range(3), [-1, 0, 1])}  # fmt: skip
    errors: dict[str, list[float]] = {}
    changes: dict[str, list[float]] = {}
    for s in stretches:
        coarse = np.array([bilinear({c: v[j] for c, v in grid0.items()}, H0, s)
                           for j in range(FINE_NODES)])  # fmt: skip
        for node, d, side in itertools.product(NODES, DISTANCES, (-1.0, 1.0)):
            k = int(np.argmin(np.abs(fine - node)))
            b = node + side * d
            own = np.arange(FINE_NODES) == k
            change = (trigonometric_weights(np.array([b]), FINE_NODES)[0] - own) @ coarse
            at_node, exact = f(node, s), f(b, s)
            errors.setdefault(f"{d:g}", []).append(float(difference(at_node + change, exact)))
            changes.setdefault(f"{d:g}", []).append(float(difference(at_node, exact)))
    result = {
        "cell": dict(zip(("l1", "l2", "theta", "w"), GEOMETRY, strict=True)), "nu": NU,
        "fibre_stiffness": STIFFNESS, "resolution": RESOLUTION, "fine_nodes": FINE_NODES,
        "nodes_degrees": NODES, "stretches": stretches.tolist(),
        "near_node_error": {
            d: {"largest": max(v), "median": float(np.median(v))} for d, v in errors.items()
        },
        "node_value_alone_error": {
            d: {"largest": max(v), "median": float(np.median(v))} for d, v in changes.items()
        },
        "machine": machine_description(), "script_seconds": time.perf_counter() - start,
    }  # fmt: skip
    print(json.dumps({k: result[k] for k in ("near_node_error", "node_value_alone_error")},
                     indent=1))  # fmt: skip
    OUT.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
