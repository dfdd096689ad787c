"""Render one run for a figure: ``plantgrowth render`` with a field given as NAME[:COMPONENT]
and the scene's name in the title.

Reads ``RESULT_DIR`` written by ``plantgrowth run`` (never re-solves, never writes into it) and
draws the field on the grown tissue x + u(t) at the last written time, the initial outline
dashed (plantgrowth/results/render.py). ``--field NAME[:COMPONENT]``: e.g. ``G:tr`` (the default,
the areal growth rate tr G), ``trG``, ``growth_direction``, ``E1111``. Replaces ``--out``.

    python scripts/figures/render_tissue.py results/reference_stress --out PNG [--field G:tr]
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from plantgrowth.results.picture import render


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("result_dir", type=Path, metavar="RESULT_DIR")
    parser.add_argument("--out", type=Path, required=True, help="the PNG (outside RESULT_DIR)")
    parser.add_argument(
        "--field", default="G:tr", help="NAME[:COMPONENT], COMPONENT in 11,12,21,22,tr,det"
    )
    parser.add_argument("--dpi", type=int, default=150)
    return parser.parse_args(argv)


def scene_name(result_dir: Path) -> str:
    """The scene file's stem from ``run.log`` (its first line names it), else the directory name."""
    try:
        first = (result_dir / "run.log").read_text().splitlines()[0]
        match = re.search(r"plantgrowth run (\S+) ->", first)
        if match:
            return Path(match.group(1)).stem
    except (OSError, IndexError):
        pass
    return result_dir.name


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    name, _, component = args.field.partition(":")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    title = f"{scene_name(args.result_dir)}: {args.field}"
    written = render(args.result_dir, name, args.out, component=component or None, force=True,
                     title=title, dpi=args.dpi)  # fmt: skip
    print(f"wrote {written}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
