"""Write the example tissue mesh file ``scenes/shapes/trapezoid.msh`` (docs/shapes.md).

A trapezoid [[0, 0], [6, 0], [4, 3], [0, 3]] meshed by gmsh with edges about h, with the groups
``tissue.mesh`` needs: the curve ``symmetry`` (x2 = 0), the point ``pinned`` (the origin) and the
named loadable curves ``slope``, ``top`` and ``left``.

    python scripts/studies/make_example_mesh.py [--h 0.3] [--out scenes/shapes/trapezoid.msh]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from plantgrowth.meshes.polygon import write_polygon_msh

ROOT = Path(__file__).resolve().parents[2]
POINTS = [[0.0, 0.0], [6.0, 0.0], [4.0, 3.0], [0.0, 3.0]]
GROUPS = {"symmetry": [0], "slope": [1], "top": [2], "left": [3]}  # name -> edge indices


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--h", type=float, default=0.3, help="mesh edge length")
    parser.add_argument("--out", type=Path, default=ROOT / "scenes/shapes/trapezoid.msh")
    args = parser.parse_args(argv)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_polygon_msh(POINTS, args.h, GROUPS, args.out)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
