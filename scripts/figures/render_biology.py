"""The README gallery of the biology scenes (issue 11, item 5): ``plantgrowth render <run> --field
trG`` at the last step of each run in ``results/biology/<name>/`` into
``docs/figures/biology_<name>.png``.

Reads the runs of ``scripts/studies/run_biology_scenes.py`` (never re-solves): a scene whose run
is missing or has not reached the scene's t_max is an error that names the study command.

    python scripts/figures/render_biology.py [--only NAME ...]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import plantgrowth as pg

REPO = Path(__file__).resolve().parents[2]
PLANTGROWTH = str(Path(sys.executable).parent / "plantgrowth")
STUDY = "python scripts/studies/run_biology_scenes.py"


def reached_t_max(scene: Path, run: Path) -> bool:
    """Whether the run in ``run`` holds the scene's last step (its summary reaches t_max)."""
    try:
        t = pg.read_results(run).summary["t"]
    except (pg.InputError, OSError):
        return False
    t_max = pg.load_scene(scene).time.t_max
    return len(t) > 0 and t[-1] >= t_max - 1e-9 * max(1.0, t_max)


def render(run: Path, picture: Path, *options: str) -> None:
    """``plantgrowth render RUN --field trG [OPTIONS] -o PICTURE --force``."""
    subprocess.run([PLANTGROWTH, "render", str(run), "--field", "trG", *options,
                    "-o", str(picture), "--force"], check=True)  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    # the fibre scenes (fibres_*) are drawn with their director glyphs by render_fibres.py
    scenes = sorted(s for s in (REPO / "scenes" / "biology").glob("*.toml")
                    if not s.stem.startswith("fibres_"))  # fmt: skip
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="*", choices=[s.stem for s in scenes])
    parser.add_argument("--results", type=Path, default=REPO / "results" / "biology")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "figures")
    args = parser.parse_args(argv)
    chosen = [s for s in scenes if not args.only or s.stem in args.only]
    missing = [s.stem for s in chosen if not reached_t_max(s, args.results / s.stem)]
    if missing:
        print(f"no complete run of {', '.join(missing)} in {args.results}: run {STUDY} first",
              file=sys.stderr)  # fmt: skip
        return 1
    args.out.mkdir(parents=True, exist_ok=True)
    for scene in chosen:
        render(args.results / scene.stem, args.out / f"biology_{scene.stem}.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
