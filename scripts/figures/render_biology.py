"""The README gallery of the biology scenes (issue 11, item 5): each scene of scenes/biology/ run
as shipped into ``results/biology/<name>/`` (a run that reached t_max is kept: delete it to
rerun; about 15 s each on one core), then ``plantgrowth render <run> --field trG`` at the last
step into ``docs/figures/biology_<name>.png``.

    python scripts/render_biology.py [--only NAME ...]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

from run_gradient_scenes import is_complete

REPO = Path(__file__).resolve().parents[1]
PLANTGROWTH = str(Path(sys.executable).parent / "plantgrowth")


def main(argv: list[str] | None = None) -> int:
    scenes = sorted((REPO / "scenes" / "biology").glob("*.toml"))
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="*", choices=[s.stem for s in scenes])
    args = parser.parse_args(argv)
    for scene in scenes:
        if args.only and scene.stem not in args.only:
            continue
        run = REPO / "results" / "biology" / scene.stem
        if not is_complete(scene, run):
            command = [PLANTGROWTH, "run", str(scene), "-o", str(run)]
            subprocess.run(command + (["--overwrite"] if run.exists() else []), check=True)
        picture = REPO / "docs" / "figures" / f"biology_{scene.stem}.png"
        subprocess.run(
            [PLANTGROWTH, "render", str(run), "--field", "trG", "-o", str(picture), "--force"],
            check=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
