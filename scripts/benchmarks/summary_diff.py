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
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "studies"))
from micro_cells_ranks import SOLVER_COLUMNS, differences, table  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("a", type=Path)
    parser.add_argument("b", type=Path)
    parser.add_argument("--rtol", type=float, default=1e-12)
    args = parser.parse_args(argv)
    a, b = table(args.a, ("step",)), table(args.b, ("step",))
    if list(a) != list(b) or len(a["step"]) != len(b["step"]):
        print("different columns or steps")
        return 1
    diff = {k: v for k, v in differences(a, b).items()
            if not k.startswith("seconds") and k not in SOLVER_COLUMNS}  # fmt: skip
    worst = max(diff, key=diff.get)
    for key, value in diff.items():
        print(f"  {key}: {value:.3g}")
    print(f"{len(a['step'])} steps, {len(diff)} columns; largest relative difference "
          f"{diff[worst]:.3g} ({worst}); rtol {args.rtol:g}")  # fmt: skip
    return int(diff[worst] > args.rtol)


if __name__ == "__main__":
    sys.exit(main())
