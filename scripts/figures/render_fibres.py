"""The README pictures of the fibre scenes (issue 22, item 7; docs/fibres.md, "Biology scenes"):
runs ``scenes/biology/fibres_*.toml`` at the ``draft`` preset (about 15 s of CPU in all; the
measured numbers of docs/fibres.md are the shipped ``balanced`` runs of
``scripts/studies/fibre_biology.py``) into ``results/fibres_gallery/<name>/`` and draws each at
its t_max with the director's glyphs, ``plantgrowth render RUN --field trG --fibres``, into
``docs/figures/biology_<name>.png``; the primordium also at t = 0
(``biology_fibres_feedback_primordium_t0.png``: its fibres before they turned).

    python scripts/figures/render_fibres.py [--out DIR]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

from render_biology import render  # scripts/figures/, next to this file

from plantgrowth.scene.toml_text import dict_to_toml

REPO = Path(__file__).resolve().parents[2]
PLANTGROWTH = str(Path(sys.executable).parent / "plantgrowth")
RESULTS = REPO / "results" / "fibres_gallery"
SCENES = sorted((REPO / "scenes" / "biology").glob("fibres_*.toml"))
RENDER_FLAGS = ["--fibres"]
"""The director glyphs (plantgrowth render's headless ``--fibres``)."""
PICTURES = {"fibres_feedback_primordium": {"_t0": ["--time", "0"]}}
"""Pictures besides the one at t_max: name -> {file suffix: extra render arguments}."""


def run_draft(scene: Path, out: Path) -> None:
    """``plantgrowth run`` of the scene at the draft preset (its own keys otherwise) into out."""
    data = tomllib.loads(scene.read_text())
    data["accuracy"] = {"preset": "draft"}
    with tempfile.TemporaryDirectory() as tmp:
        draft = Path(tmp) / scene.name
        draft.write_text(dict_to_toml(data))
        command = [PLANTGROWTH, "run", str(draft), "-o", str(out), "--overwrite", "-q"]
        subprocess.run(command, check=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "figures", help="pictures")
    out = parser.parse_args(argv).out
    out.mkdir(parents=True, exist_ok=True)
    for scene in SCENES:
        run = RESULTS / scene.stem
        run_draft(scene, run)
        for suffix, extra in {"": [], **PICTURES.get(scene.stem, {})}.items():
            render(run, out / f"biology_{scene.stem}{suffix}.png", *RENDER_FLAGS, *extra)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
