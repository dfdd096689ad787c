"""Run the example scenes of ``scenes/biology/`` (the README gallery, issue 11, item 5) into
``results/biology/<name>/``.

One ``plantgrowth run`` per scene, as shipped (about 15 s each on one core; the fibre scenes
1-7 minutes on the shared 2-core machine, ``fibres_feedback_primordium`` the longest: its
stress feedback spreads the directors, 9,453 cell solves, docs/fibres.md). A run whose
``summary.csv`` already reaches the scene's last step is skipped unless ``--force``; ``--jobs 2``
runs two scenes at a time. ``scripts/figures/render_biology.py`` then draws the gallery from the
runs. Exits non-zero if any run failed.

    python scripts/studies/run_biology_scenes.py [--jobs 2] [--force] [--only NAME ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from run_gradient_scenes import run_all  # scripts/studies/, next to this file

REPO = Path(__file__).resolve().parents[2]
SCENES = REPO / "scenes" / "biology"
RESULTS = REPO / "results" / "biology"


def main(argv: list[str] | None = None) -> int:
    scenes = sorted(SCENES.glob("*.toml"))
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="*", choices=[s.stem for s in scenes])
    parser.add_argument("--out", type=Path, default=RESULTS, help="result root")
    parser.add_argument("--jobs", type=int, default=1, help="runs at a time (default 1)")
    parser.add_argument("--force", action="store_true", help="rerun complete results too")
    parser.add_argument("--plantgrowth", default=str(Path(sys.executable).with_name("plantgrowth")))
    args = parser.parse_args(argv)
    jobs = [(scene, args.out) for scene in scenes if not args.only or scene.stem in args.only]
    return run_all(args.plantgrowth, jobs, args.jobs, args.force)


if __name__ == "__main__":
    sys.exit(main())
