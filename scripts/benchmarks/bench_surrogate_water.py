"""The cell surrogate's error on the water coefficients b and 1/M (docs/model.md, "The unit cell's
coefficients"; issue 35).

b = (1 - phi_w) I - K_hom and 1/M = -tr dbar[v] come from the surrogate's interpolated K_hom,
phi_w and dbar[v] (kappa is a closed form of the lattice and Fg: no surrogate). For each cell
geometry and tolerance, a Homogenizer with the surrogate (pressure and strain averages, as a scene
with [hydraulics] builds it) answers random stretches |s_i| <= 0.3; each answer is compared with an
exact cell solve at the same stretch (same mesh, so only the interpolation error is measured):
the relative (Frobenius) errors of E_hom, K_hom, dbar[v], b, 1/M and the estimates. Two other
refinement indicators are measured alongside the shipped one (every segment: E_hom, K_hom,
dbar[w], dbar[v]): without dbar[v] (the storage's quantity left out), and without dbar[w]
(what the water alone needs). Per query it also records the conditioning factors that turn a
segment's error into b's and 1/M's: ``|K_hom| / |b|`` and ``sqrt(2) |dbar[v]| / |tr dbar[v]|``.

    python scripts/benchmarks/bench_surrogate_water.py [--resolution 2] [--queries 40]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

from plantgrowth.unitcell import surrogate
from plantgrowth.unitcell.homogenization import Homogenizer

GEOMETRIES = {
    "reference (l1 = l2 = 1, theta 30, w = 0.05)": (1.0, 1.0, 30.0, 0.05),
    "elongated (l1 = 1.5, w = 0.1)": (1.5, 1.0, 30.0, 0.1),
    "thick (w = 0.2)": (1.0, 1.0, 30.0, 0.2),
}
TOLERANCES = (1e-2, 1e-3)
NU = 0.3
# packed layout with pressure and strain averages (homogenization._pack): E_hom Voigt 0:9,
# phi_w 9, P2 10:14, K_hom 14:18, dbar[w] 18:34, dbar[v] 34:38
E_HOM, PHI_W, K_HOM, DBAR_W, DBAR_V = slice(0, 9), 9, slice(14, 18), slice(18, 34), slice(34, 38)
INDICATORS = {
    "shipped (E_hom, K_hom, dbar[w], dbar[v])": (E_HOM, K_HOM, DBAR_W, DBAR_V),
    "without dbar[v]": (E_HOM, K_HOM, DBAR_W),
    "without dbar[w]": (E_HOM, K_HOM, DBAR_V),
}


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--resolution", type=int, default=2, help="cell mesh (the default preset)")
    parser.add_argument("--queries", type=int, default=40)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/surrogate_water.json"))
    return parser.parse_args(argv)


def relative(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``|a - b| / |b|`` per row (Frobenius)."""
    return np.linalg.norm(a - b, axis=1) / np.linalg.norm(b, axis=1)


def water_coefficients(packed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """b (n, 4) = (1 - phi_w) I - K_hom and 1/M (n, 1) = -tr dbar[v] from packed rows."""
    b = (1.0 - packed[:, PHI_W])[:, None] * np.eye(2).ravel() - packed[:, K_HOM]
    dbar_v = packed[:, DBAR_V]
    return b, -(dbar_v[:, 0] + dbar_v[:, 3])[:, None]


def measure(geometry: tuple, tolerance: float, segments: tuple, s: np.ndarray, resolution: int,
            exact: np.ndarray) -> dict:  # fmt: skip
    """One surrogate (a fresh lattice) asked at the stretches s, against the exact rows."""
    h = Homogenizer(resolution, 1e-6, True, True, MPI.COMM_SELF, tolerance)
    h.surrogate.segments = segments
    table = h._key(np.array(geometry), NU, np.eye(2))[:5]
    start = time.process_time()
    answer = h.surrogate.evaluate([table], np.zeros(len(s), dtype=np.int64), s)
    seconds = time.process_time() - start
    b, inv_M = water_coefficients(answer.values)
    b_exact, inv_M_exact = water_coefficients(exact)
    errors = {
        "E_hom": relative(answer.values[:, E_HOM], exact[:, E_HOM]),
        "K_hom": relative(answer.values[:, K_HOM], exact[:, K_HOM]),
        "dbar_v": relative(answer.values[:, DBAR_V], exact[:, DBAR_V]),
        "b": relative(b, b_exact),
        "inv_M": relative(inv_M, inv_M_exact),
    }
    row = {"lattice_solves": answer.solves, "cpu_seconds": seconds}
    row["largest_relative_error"] = {k: float(v.max()) for k, v in errors.items()}
    row["largest_over_tolerance"] = {k: float(v.max() / tolerance) for k, v in errors.items()}
    row["largest_estimate_over_tolerance"] = float(answer.estimates.max() / tolerance)
    return row


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    args.out.parent.mkdir(parents=True, exist_ok=True)  # fail before solving, not after
    s = np.random.default_rng(0).uniform(-0.3, 0.3, size=(args.queries, 2))
    results = {"resolution": args.resolution, "queries": args.queries, "nu": NU, "cases": []}
    for name, geometry in GEOMETRIES.items():
        h = Homogenizer(args.resolution, 1e-6, True, True, MPI.COMM_SELF, 0.0)
        table = h._key(np.array(geometry), NU, np.eye(2))[:5]
        exact = np.array([h._solve_stretch(table, surrogate.stretch(x)) for x in s])
        b, inv_M = water_coefficients(exact)
        dbar_v = exact[:, DBAR_V]
        conditioning = {
            "K_over_b": float((np.linalg.norm(exact[:, K_HOM], axis=1)
                               / np.linalg.norm(b, axis=1)).max()),
            "sqrt2_dbar_v_over_trace": float((np.sqrt(2.0) * np.linalg.norm(dbar_v, axis=1)
                                              / np.abs(inv_M[:, 0])).max()),
            "dbar_v_largest_eigenvalue": float(
                np.linalg.eigvalsh(dbar_v.reshape(-1, 2, 2)).max()
            ),
        }  # fmt: skip
        for tolerance in TOLERANCES:
            for indicator, segments in INDICATORS.items():
                row = measure(geometry, tolerance, segments, s, args.resolution, exact)
                row |= {"geometry": name, "tolerance": tolerance, "indicator": indicator}
                row["conditioning"] = conditioning
                results["cases"].append(row)
                over = row["largest_over_tolerance"]
                print(f"{name:45s} tol {tolerance:g} {indicator:42s} solves "
                      f"{row['lattice_solves']:4d}  err/tol: E {over['E_hom']:.3f} "
                      f"K {over['K_hom']:.3f} dbar_v {over['dbar_v']:.3f} b {over['b']:.3f} "
                      f"1/M {over['inv_M']:.3f}", flush=True)  # fmt: skip
    args.out.write_text(json.dumps(results, indent=1) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
