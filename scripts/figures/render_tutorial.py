"""Execute docs/tutorial.ipynb and write its rendered copy docs/tutorial.md with the figures as
docs/figures/tutorial_<n>.png.

    .venv/bin/python scripts/figures/render_tutorial.py

The notebook runs in the Jupyter kernel "plantgrowth" (.venv's python; scripts/install.sh
installs it) in a temporary working directory, so its runs are written there and removed after.
The markdown holds the notebook's text, every code cell as a python block, the text each cell
printed or returned, and each figure; the notebook file itself is left as it is (no outputs).
"""

from __future__ import annotations

import argparse
import base64
import tempfile
from pathlib import Path

import nbformat
from nbclient import NotebookClient

REPO = Path(__file__).resolve().parents[2]
NOTEBOOK = REPO / "docs" / "tutorial.ipynb"
KERNEL = "plantgrowth"
TIMEOUT = 300  # s per cell; the whole notebook takes well under a minute


def executed(notebook: Path) -> nbformat.NotebookNode:
    """The notebook after running every cell, in a temporary working directory."""
    nb = nbformat.read(notebook, as_version=4)
    with tempfile.TemporaryDirectory(prefix="plantgrowth_tutorial_") as work:
        NotebookClient(nb, kernel_name=KERNEL, timeout=TIMEOUT,
                       resources={"metadata": {"path": work}}).execute()  # fmt: skip
    return nb


def text_of(output: nbformat.NotebookNode) -> str | None:
    """What a text output shows: a stream's text, a result's text/plain."""
    if output.output_type == "stream":
        return output.text
    if output.output_type in ("execute_result", "display_data") and "image/png" not in output.data:
        return output.data.get("text/plain")
    return None


def markdown(nb: nbformat.NotebookNode, figures: Path, prefix: str) -> tuple[str, list[Path]]:
    """The rendered notebook and the figures it links (written into ``figures``)."""
    parts = [
        "<!-- Rendered from tutorial.ipynb by scripts/figures/render_tutorial.py: edit the "
        "notebook and run that script, not this file. -->"
    ]
    written = []
    for cell in nb.cells:
        if cell.cell_type == "markdown":
            parts.append(cell.source.rstrip())
            continue
        parts.append(f"```python\n{cell.source}\n```")
        texts = [t for t in (text_of(o) for o in cell.get("outputs", [])) if t]
        if texts:
            parts.append("```text\n" + "".join(t if t.endswith("\n") else t + "\n" for t in texts)
                         + "```")  # fmt: skip
        for output in cell.get("outputs", []):
            if "image/png" in output.get("data", {}):
                path = figures / f"{prefix}{len(written) + 1}.png"
                path.write_bytes(base64.b64decode(output.data["image/png"]))
                written.append(path)
                parts.append(f"![figure {len(written)}](figures/{path.name})")
    return "\n\n".join(parts) + "\n", written


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--notebook", type=Path, default=NOTEBOOK)
    parser.add_argument("--output", type=Path, default=REPO / "docs" / "tutorial.md",
                        help="the markdown file; its figures go to figures/ beside it")  # fmt: skip
    args = parser.parse_args()
    figures = args.output.parent / "figures"
    for old in figures.glob("tutorial_*.png"):
        old.unlink()
    text, written = markdown(executed(args.notebook), figures, "tutorial_")
    args.output.write_text(text)
    print(f"wrote {args.output} and {len(written)} figures in {figures}")


if __name__ == "__main__":
    main()
