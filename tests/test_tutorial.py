"""docs/tutorial.ipynb runs top to bottom in the Jupyter kernel "plantgrowth" (.venv's python,
installed by scripts/install.sh), writes only into its working directory, draws its figures and
shows what its text says; docs/tutorial.md, its rendered copy, has every code cell as it is now.

Serial only: the kernel is a process of its own, which would run once per rank.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import nbformat
import pytest
from jupyter_client.kernelspec import KernelSpecManager, NoSuchKernel
from nbclient import NotebookClient

REPO = Path(__file__).resolve().parents[1]
NOTEBOOK = REPO / "docs" / "tutorial.ipynb"
KERNEL = "plantgrowth"
CELL_TIMEOUT = 120  # s; the whole notebook takes 10-15 s here (draft preset, t_max = 5)


def outputs(nb: nbformat.NotebookNode, kind: str) -> list:
    """Every output of the code cells whose type is ``kind`` (stream, display_data, ...)."""
    return [o for cell in nb.cells if cell.cell_type == "code" for o in cell.outputs
            if o.output_type == kind]  # fmt: skip


def repository_files() -> list[Path]:
    """The repository's files, less the venv, git's and Python's caches."""
    skip = {".venv", ".git", "__pycache__"}
    return sorted(p for p in REPO.rglob("*") if not skip & set(p.relative_to(REPO).parts))


def test_the_kernel_is_this_python():
    try:
        spec = KernelSpecManager().get_kernel_spec(KERNEL)
    except NoSuchKernel:
        pytest.fail(f"no Jupyter kernel {KERNEL!r}: run bash scripts/install.sh")
    assert Path(spec.argv[0]) == Path(sys.executable), spec.argv


@pytest.mark.skip_in_parallel
def test_tutorial_runs_top_to_bottom(tmp_path):
    nb = nbformat.read(NOTEBOOK, as_version=4)
    assert not outputs(nb, "stream"), "commit the notebook without outputs (tutorial.md has them)"
    before = repository_files()
    NotebookClient(nb, kernel_name=KERNEL, timeout=CELL_TIMEOUT,
                   resources={"metadata": {"path": str(tmp_path)}}).execute()  # fmt: skip
    assert (tmp_path / "tutorial_runs" / "soft_disc" / "summary.csv").is_file()
    assert repository_files() == before  # nothing written into the repository
    figures = [o for o in outputs(nb, "display_data") if "image/png" in o.data]
    assert len(figures) == 3
    printed = "".join(o.text for o in outputs(nb, "stream"))
    # section 3: under the strain law the soft disc grows faster than the tissue, every step
    rows = re.findall(r"^ +\d+ +[\d.]+ +([\d.]+) +[\d.]+ +([\d.]+)$", printed, re.M)
    assert len(rows) == 6 and all(float(disc) > float(tissue) for tissue, disc in rows)
    # section 6: the softer the disc, the faster it grows; at E_in = 1 it is ordinary tissue
    sweep = re.findall(r"E_in = ([\d.]+): disc tr G = ([\d.]+), tissue tr G = ([\d.]+)", printed)
    assert [float(e) for e, _, _ in sweep] == [0.3, 0.6, 1.0]
    disc = [float(d) for _, d, _ in sweep]
    assert disc[0] > disc[1] > disc[2] and sweep[-1][1] == sweep[-1][2]


def test_the_rendered_tutorial_has_every_code_cell():
    """docs/tutorial.md is scripts/figures/render_tutorial.py's output of the notebook as it
    is: every code cell appears there verbatim, and every figure it links exists."""
    nb = nbformat.read(NOTEBOOK, as_version=4)
    rendered = (REPO / "docs" / "tutorial.md").read_text()
    for cell in nb.cells:
        if cell.cell_type == "code":
            assert f"```python\n{cell.source}\n```" in rendered, cell.source[:80]
    links = re.findall(r"\]\((figures/tutorial_\d+\.png)\)", rendered)
    assert len(links) == 3 and all((REPO / "docs" / link).is_file() for link in links)
