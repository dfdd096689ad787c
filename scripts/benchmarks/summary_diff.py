"""Whether two runs gave the same results: the largest difference of every column of their
summary.csv but the timings (``seconds*``) and the linear solve's round-off (``residual``, the
true relative residual of an LU solve, ~1e-16), relative to the column's largest magnitude.

Issue 33, item 3 checks an optimised checkout against main this way (the reference scene's
summary.csv equal to 1e-12). Exit status 1 if a column differs by more than ``--rtol``, the two
files have different columns or steps.

    python scripts/benchmarks/summary_diff.py A/summary.csv B/summary.csv [--rtol 1e-12]
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

SKIPPED = ("residual", "newton_residual")
"""Round-off of the solves, not results (any change of the arithmetic's order moves them)."""


def read(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def differences(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> dict[str, float]:
    """Column -> max |a - b| over max(|a|, |b|) of the column (0 for a column of zeros)."""
    out = {}
    for key in a:
        if key.startswith("seconds") or key in SKIPPED:
            continue
        scale = max(np.abs(a[key]).max(), np.abs(b[key]).max())
        out[key] = float(np.abs(a[key] - b[key]).max() / scale) if scale > 0 else 0.0
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("a", type=Path)
    parser.add_argument("b", type=Path)
    parser.add_argument("--rtol", type=float, default=1e-12)
    args = parser.parse_args(argv)
    a, b = read(args.a), read(args.b)
    if list(a) != list(b) or len(a["step"]) != len(b["step"]):
        print("different columns or steps")
        return 1
    diff = differences(a, b)
    worst = max(diff, key=diff.get)
    for key, value in diff.items():
        print(f"  {key}: {value:.3g}")
    print(f"{len(a['step'])} steps, {len(diff)} columns; largest relative difference "
          f"{diff[worst]:.3g} ({worst}); rtol {args.rtol:g}")  # fmt: skip
    return int(diff[worst] > args.rtol)


if __name__ == "__main__":
    sys.exit(main())
