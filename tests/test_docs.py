"""The documentation names only what ships and defines what the code writes (issue 21).

- No file of the repository refers to the model spec the project once had outside the
  repository; the model's reference is docs/model.md, cited as "docs/model.md section N".
- Every column the code can write into summary.csv, cells.csv, compare.csv and sweep.csv, and
  every field of ``output.fields`` and of a micro run, has a row in the tables of
  docs/outputs.md. The columns are collected from the code (the column lists and the models'
  ``measures``), never from a copy here, so a new column without a definition fails.

Each check is a function of text; the ``*_finds_*`` tests plant a defect and show that it fails.
"""

from __future__ import annotations

import ast
import re
import subprocess
from pathlib import Path

import pytest

from plantgrowth.base.tensors import VOIGT_NAMES
from plantgrowth.models.micro.outlines import CELL_COLUMNS, FIBRE_CELL_COLUMNS, WATER_CELL_COLUMNS
from plantgrowth.models.micro.water import WATER_COLUMNS
from plantgrowth.runner import timeloop
from plantgrowth.scene.limits import OUTPUT_FIELDS
from plantgrowth.studies import compare
from plantgrowth.studies.sweep_file import NUMBERS, load_sweep

REPO = Path(__file__).resolve().parents[1]
OUTPUTS = REPO / "docs" / "outputs.md"
OLD_SPEC = "MODEL" + ".md"
"""The old name, spelt in two pieces so that this file does not name it."""
NOT_SOURCES = {".git", ".venv", "results", "__pycache__", ".pytest_cache", ".ruff_cache"}
"""Directories skipped when the tree is walked instead of listed by git."""


def repository_files() -> list[Path]:
    """The tracked files (``git ls-files``); without git, every file but NOT_SOURCES."""
    try:
        listed = subprocess.run(
            ["git", "ls-files", "-z"], cwd=REPO, capture_output=True, check=True
        ).stdout.decode()
        return [REPO / name for name in listed.split("\0") if name]
    except (OSError, subprocess.CalledProcessError):
        return [
            p for p in REPO.rglob("*")
            if p.is_file() and not NOT_SOURCES & set(p.relative_to(REPO).parts)
            and not p.relative_to(REPO).parts[0].endswith(".egg-info")
        ]  # fmt: skip


def spec_references(text: str, in_docs: bool) -> list[str]:
    """Every name of a file called model.md (any case, any path) that is not ``docs/model.md``;
    inside docs/ the relative ``model.md`` of a link is docs/model.md too."""
    bad = []
    for match in re.finditer(r"[\w./-]*model\.md", text, flags=re.IGNORECASE):
        name = match.group(0)
        if name.endswith("docs/model.md") or (in_docs and name in ("model.md", "./model.md")):
            continue
        line = text.count("\n", 0, match.start()) + 1
        bad.append(f"line {line}: {name}")
    return bad


def test_the_model_reference_ships():
    model = (REPO / "docs" / "model.md").read_text()
    numbered = re.findall(r"^## (\d+)\. ", model, flags=re.MULTILINE)
    assert numbered == [str(n) for n in range(1, 12)]  # sections cited by number elsewhere


def test_no_file_names_the_old_spec():
    """No tracked file names the old spec: every reference reads docs/model.md."""
    found = {}
    for path in repository_files():
        if path == Path(__file__).resolve():
            continue  # this file plants the names it looks for
        try:
            text = path.read_text(encoding="utf-8")
        except (UnicodeDecodeError, FileNotFoundError, IsADirectoryError):
            continue  # binary files (figures, meshes) and files deleted but not yet staged
        relative = path.relative_to(REPO)
        if bad := spec_references(text, in_docs=relative.parts[0] == "docs"):
            found[str(relative)] = bad
    assert not found, f"files naming {OLD_SPEC} (cite docs/model.md section N): {found}"


def test_the_spec_check_finds_a_reference():
    assert spec_references(f"defaults: the reference scene of {OLD_SPEC} 9", False)
    assert spec_references("see ../shared/spec/" + OLD_SPEC, True)
    assert spec_references("see docs/" + OLD_SPEC, False)  # the case matters
    assert spec_references("the [model](model.md)", in_docs=False)  # outside docs/: a bare name
    assert not spec_references("docs/model.md section 4; [model.md](model.md)", in_docs=True)


def defined_names(markdown: str, heading: str) -> set[str]:
    """The names a section defines: every `name` in the first cell of its tables' rows. The
    section is the first heading containing ``heading``, up to the next heading of its level or
    above."""
    lines = markdown.splitlines()
    start = next(
        (i for i, line in enumerate(lines) if line.startswith("#") and heading in line), None
    )
    if start is None:
        return set()
    level = len(lines[start]) - len(lines[start].lstrip("#"))
    names = set()
    for line in lines[start + 1 :]:
        if line.startswith("#") and len(line) - len(line.lstrip("#")) <= level:
            break
        cells = line.split("|")
        if line.startswith("|") and len(cells) > 2 and not set(cells[1].strip()) <= set("-: "):
            names.update(re.findall(r"`([^`]+)`", cells[1]))
    return names


def _section_text(markdown: str, heading: str) -> str:
    lines = markdown.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("#") and heading in line)
    level = len(lines[start]) - len(lines[start].lstrip("#"))
    end = next(
        (j for j in range(start + 1, len(lines))
         if lines[j].startswith("#") and len(lines[j]) - len(lines[j].lstrip("#")) <= level),
        len(lines),
    )  # fmt: skip
    return "\n".join(lines[start:end])


def returned_keys(path: Path, function: str) -> set[str]:
    """The string keys of the dict literals that ``function`` (a method or function of the
    module at ``path``) returns."""
    keys = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.FunctionDef) and node.name == function:
            for ret in ast.walk(node):
                if isinstance(ret, ast.Return) and isinstance(ret.value, ast.Dict):
                    keys |= {k.value for k in ret.value.keys if isinstance(k, ast.Constant)}
    return keys


def function_names(path: Path) -> set[str]:
    """The ``name=`` of every ``fem.Function(...)`` of a module: the fields it writes."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "Function":
            names |= {k.value.value for k in node.keywords
                      if k.arg == "name" and isinstance(k.value, ast.Constant)}  # fmt: skip
    return names


MODELS = REPO / "plantgrowth" / "models"


def summary_columns() -> set[str]:
    """Every column summary.csv can have: the loop's lists and what the models measure."""
    measured = returned_keys(MODELS / "macro" / "model.py", "measures") | returned_keys(
        MODELS / "micro" / "model.py", "measures"
    )
    assert {"area", "growth_rate_area"} <= measured  # the parse found the models' measures
    columns = timeloop.SUMMARY_COLUMNS + timeloop.NEWTON_COLUMNS + timeloop.HELD_COLUMNS
    water = WATER_COLUMNS + ["inflow.<label>"]
    return set(columns + timeloop.LOAD_COLUMNS + water) | measured


def sweep_columns() -> set[str]:
    """sweep.csv's columns but the varied keys (one per key, defined in prose), micro_* too."""
    sweep = load_sweep(REPO / "scenes" / "sweeps" / "nu_strain.toml")
    return (set(sweep.columns()) - set(sweep.vary)) | {f"micro_{n}" for n in NUMBERS}


def written_fields() -> set[str]:
    """``output.fields`` (E_hom: six scalars, next test) and the fields a micro run writes."""
    return set(OUTPUT_FIELDS) - {"E_hom"} | function_names(MODELS / "micro" / "model.py")


TABLES = {
    "`summary.csv`": summary_columns,
    "`cells.csv`": lambda: set(CELL_COLUMNS + FIBRE_CELL_COLUMNS + WATER_CELL_COLUMNS),
    "`compare.csv`": lambda: set(compare.COLUMNS),
    "`sweep.csv`": sweep_columns,
    "Fields:": written_fields,
}


def undefined(markdown: str, heading: str, names: set[str]) -> list[str]:
    return sorted(names - defined_names(markdown, heading))


@pytest.mark.parametrize("heading", TABLES)
def test_every_column_and_field_is_defined(heading):
    """Each column (field) the code can write has its row in docs/outputs.md."""
    missing = undefined(OUTPUTS.read_text(), heading, TABLES[heading]())
    assert not missing, f"docs/outputs.md, section {heading}: no definition of {missing}"


def test_the_E_hom_components_are_named():
    """E_hom is written as six scalars on the coarse grid: the Fields table names each."""
    section = _section_text(OUTPUTS.read_text(), "Fields:")
    assert "`E_hom`" in section and all(f"`{name}`" in section for name in VOIGT_NAMES)


def test_the_column_check_finds_a_missing_column():
    text = OUTPUTS.read_text()
    assert undefined(text, "`summary.csv`", summary_columns() | {"new_column"}) == ["new_column"]
    without_area = text.replace("| `area` |", "| area |", 1)
    assert "area" in undefined(without_area, "`summary.csv`", summary_columns())
    assert undefined("# Outputs\n", "`summary.csv`", {"t"}) == ["t"]  # no such section
