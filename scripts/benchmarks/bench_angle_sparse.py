"""The director's sparse grid against plain trigonometric interpolation and cheaper variants
(issue 33, item 2).

The reference cell (l1 = l2 = 1, theta = 30, w = 0.05, nu = 0.3, E_f/E = 5, resolution 2) is
solved at the angle nodes of every interpolant below, at 8 random stretches in the range the
stress feedback scene reaches (s1 in [0, 0.15], s2 in [-0.015, 0.04]) and on the level-0 and
level-1 stretch grids around them (spacing 0.1 and 0.05), and at 10 random angles in [65, 120]
(the directors' range there at t = 60). I_N is the trigonometric interpolant of period 180
degrees through N equispaced nodes, one of them at 90 degrees (for the even N used here the
nodes of :func:`plantgrowth.unitcell.director_lattice.trigonometric_weights`; an odd N, which
has no Nyquist term, uses the Dirichlet kernel ``sin(N d) / (N sin d)``). Each variant

    A = I_a[f - G f] + I_b[G f - P_0 f] + I_c[P_0 f]            (written (a, b, c))

takes the exact values f at the a fine nodes, G f the level-1 grid's interpolant (P_1 bilinear
on the level-1 squares, today's; or Q_1 biquadratic on the level-0 squares through their 9
level-1 points) and P_0 the level-0 grid's bilinear interpolant; today's scheme is (6, 12, 24)
with P_1. For each it records the largest relative error (director_lattice's measure), with
those of I_N alone and of today's two estimates. Writes ``benchmarks/results/angle_sparse.json``
(about 2,100 solves, 30-60 s).

    python scripts/benchmarks/bench_angle_sparse.py
"""

from __future__ import annotations

import itertools
import json
import sys
import time
from collections.abc import Callable
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
COUNTS = (3, 4, 5, 6, 8, 10, 12, 16, 20, 24)
VARIANTS = {  # name: (a, b, c, level-1 interpolant)
    "today: (6, 12, 24), P_1": (6, 12, 24, "P"),
    "(6, 12, 12), P_1: no level-0 term": (6, 12, 12, "P"),
    "(5, 10, 20), P_1: odd M": (5, 10, 20, "P"),
    "(4, 8, 16), P_1": (4, 8, 16, "P"),
    "(3, 6, 24), P_1": (3, 6, 24, "P"),
    "(6, 12, 24), Q_1": (6, 12, 24, "Q"),
    "(5, 10, 20), Q_1": (5, 10, 20, "Q"),
    "(3, 12, 24), Q_1": (3, 12, 24, "Q"),
    "(6, 12, 12), Q_1": (6, 12, 12, "Q"),
}


def nodes(count: int) -> np.ndarray:
    """The count equispaced node angles (degrees) of I_count, one at 90 degrees."""
    return 90.0 % (180.0 / count) + np.arange(count) * 180.0 / count


def weights(b: float, count: int) -> np.ndarray:
    """Cardinal functions (count,) of I_count at the angle b (degrees)."""
    phase = nodes(count)[0]
    if count % 2 == 0:
        return trigonometric_weights(np.array([b - phase]), count)[0]
    x = (b - phase) / (180.0 / count) - np.arange(count)
    d = np.pi * x / count
    on = np.abs(x - count * np.round(x / count)) <= 1e-9
    return np.where(on, 1.0, np.sin(count * d) / (count * np.where(on, 1.0, np.sin(d))))


def bilinear(corners: dict, spacing: float, s: np.ndarray) -> np.ndarray:
    """The bilinear interpolant at s of the grid values ``corners[(i, j)]`` (spacing apart)."""
    x = s / spacing
    base = np.floor(x).astype(int)
    t = x - base
    hats = {(0, 0): (1 - t[0]) * (1 - t[1]), (1, 0): t[0] * (1 - t[1]),
            (0, 1): (1 - t[0]) * t[1], (1, 1): t[0] * t[1]}  # fmt: skip
    return sum(w * corners[base[0] + a, base[1] + c] for (a, c), w in hats.items())


def biquadratic(corners: dict, s: np.ndarray) -> np.ndarray:
    """The biquadratic interpolant at s on the level-0 square holding it, through its 9 points
    of the level-1 grid ``corners[(i, j)]`` (spacing H0 / 2): continuous across the squares."""
    x = s / H0
    base = np.floor(x).astype(int)
    t = x - base
    lagrange = [np.array([2 * (u - 0.5) * (u - 1), -4 * u * (u - 1), 2 * u * (u - 0.5)]) for u in t]
    return sum(
        lagrange[0][i] * lagrange[1][j] * corners[2 * base[0] + i, 2 * base[1] + j]
        for i in range(3) for j in range(3)
    )  # fmt: skip


def fibred_cell() -> tuple[Callable, Callable, np.ndarray, np.random.Generator]:
    """The reference fibred cell's exact packed values ``f(angle, s)`` (one cell solve), the
    surrogate's relative difference, 8 random stretches in the feedback scene's range and the
    generator that drew them (seed 0)."""
    homogenizer = Homogenizer(RESOLUTION, 1e-6, True, True, MPI.COMM_SELF, cell_tolerance=1.0)

    def f(angle: float, s: np.ndarray) -> np.ndarray:
        return homogenizer._solve_exact(GEOMETRY, NU, stretch(s), (STIFFNESS, float(angle)))

    rng = np.random.default_rng(0)
    stretches = np.column_stack([rng.uniform(0, 0.15, 8), rng.uniform(-0.015, 0.04, 8)])
    return f, homogenizer.surrogate.relative_difference, stretches, rng


def main() -> int:
    start = time.perf_counter()
    f, difference, stretches, rng = fibred_cell()
    angles = rng.uniform(65.0, 120.0, 10)
    every = sorted({round(a, 9) for count in COUNTS for a in nodes(count)})
    grid0 = {c: {a: f(a, np.array(c) * H0) for a in every}
             for c in itertools.product(range(3), [-1, 0, 1])}  # fmt: skip
    grid1 = {c: {a: f(a, np.array(c) * H0 / 2) for a in every}
             for c in itertools.product(range(5), range(-2, 3))}  # fmt: skip
    errors: dict[str, list[float]] = {}
    for s in stretches:
        exact_at = {a: f(a, s) for a in every}
        level0 = {a: bilinear({c: v[a] for c, v in grid0.items()}, H0, s) for a in every}
        level1 = {
            "P": {a: bilinear({c: v[a] for c, v in grid1.items()}, H0 / 2, s) for a in every},
            "Q": {a: biquadratic({c: v[a] for c, v in grid1.items()}, s) for a in every},
        }
        for b in angles:
            exact = f(b, s)

            def interp(values: dict, count: int, b: float = b) -> np.ndarray:
                at = np.array([values[round(a, 9)] for a in nodes(count)])
                return weights(b, count) @ at

            for count in COUNTS:
                errors.setdefault(f"I_{count}", []).append(
                    float(difference(interp(exact_at, count), exact))
                )
            for name, (a, c, d, kind) in VARIANTS.items():
                grid = level1[kind]
                value = (interp(exact_at, a) - interp(grid, a) + interp(grid, c)
                         - interp(level0, c) + interp(level0, d))  # fmt: skip
                errors.setdefault(name, []).append(float(difference(value, exact)))
            p1 = level1["P"]
            first, tail = interp(p1, 12) - interp(p1, 6), interp(level0, 24) - interp(level0, 12)
            today = interp(exact_at, 6) + first + tail
            mixed = first - (interp(level0, 12) - interp(level0, 6))
            errors.setdefault("today's estimate: last surplus", []).append(
                float(difference(today - tail, today))
            )
            errors.setdefault("today's estimate: level-1 grid's change", []).append(
                float(difference(today - mixed, today))
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
