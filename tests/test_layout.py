"""The package's layout (issue 19): subpackages whose imports point only down, no import circle,
modules of one job each (at most MAX_LINES lines), and every subpackage installed.

The graph is read from the source with ``ast`` (nothing is imported), counting every import
statement, including those inside functions and under ``TYPE_CHECKING``: a lazy import is a
dependency all the same.
"""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "plantgrowth"
LAYERS = {
    "forms": 0, "meshes": 0, "base": 1, "scene": 2, "unitcell": 3, "models": 4, "runner": 5,
    "results": 5, "studies": 6, "api": 7, "cli": 8, "": 9,
}  # fmt: skip
"""The dependency direction: a module may import from a lower layer, or from its own subpackage
(``runner`` and ``results`` share a layer but not each other; ``""`` is plantgrowth/__init__)."""
MAX_LINES = 500
"""Issue 19: no module over about 500 lines (split by job, not by size)."""


def package_modules() -> dict[str, Path]:
    """Dotted name -> file of every module of plantgrowth (forms/ and meshes/ included)."""
    out = {}
    roots = {"plantgrowth": PACKAGE, "plantgrowth.forms": REPO / "forms",
             "plantgrowth.meshes": REPO / "meshes"}  # fmt: skip
    for prefix, root in roots.items():
        for path in root.rglob("*.py"):
            parts = list(path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            out[".".join([prefix, *parts])] = path
    return out


MODULES = package_modules()


def imports_of(name: str) -> set[str]:
    """The plantgrowth modules that module ``name`` imports: ``from package import submodule``
    names the submodule, ``from package import name`` the package's ``__init__``."""
    tree = ast.parse(MODULES[name].read_text())
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            targets = [
                f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in MODULES else node.module
                for a in node.names
            ]
        else:
            continue
        out |= {t for t in targets if t in MODULES and t != name}
    return out


def layer(name: str) -> tuple[int, str]:
    """(layer, subpackage) of a module."""
    parts = name.split(".")
    sub = parts[1] if len(parts) > 1 else ""
    return LAYERS[sub], sub


def test_every_subpackage_has_a_layer():
    subs = {(name.split(".")[1:2] or [""])[0] for name in MODULES}
    assert subs <= set(LAYERS), f"subpackages without a layer: {subs - set(LAYERS)}"


@pytest.mark.parametrize("name", sorted(MODULES))
def test_imports_point_down(name):
    rank, sub = layer(name)
    bad = []
    for target in sorted(imports_of(name)):
        t_rank, t_sub = layer(target)
        if t_rank > rank or (t_rank == rank and t_sub != sub):
            bad.append(target)
    assert not bad, f"{name} imports {bad}, which are not below it ({LAYERS})"


def test_no_import_circle():
    graph = {name: imports_of(name) for name in MODULES}
    state: dict[str, int] = {}  # 1: on the current path, 2: done

    def visit(node: str, path: list[str]) -> list[str] | None:
        state[node] = 1
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return [*path[path.index(nxt) :], nxt] if nxt in path else [*path, nxt]
            if nxt not in state and (circle := visit(nxt, [*path, nxt])):
                return circle
        state[node] = 2
        return None

    for name in sorted(graph):
        if name not in state and (circle := visit(name, [name])):
            pytest.fail("import circle: " + " -> ".join(circle))


def test_the_circle_detector_finds_a_circle(monkeypatch):
    """The test above can fail: a module importing its importer is reported."""
    fake = {"a": {"b"}, "b": {"c"}, "c": {"a"}}
    monkeypatch.setitem(globals(), "imports_of", lambda name: fake[name])
    monkeypatch.setitem(globals(), "MODULES", dict.fromkeys(fake, Path()))
    with pytest.raises(pytest.fail.Exception, match="a -> b -> c -> a"):
        test_no_import_circle()


@pytest.mark.parametrize("name", sorted(MODULES))
def test_modules_are_small(name):
    lines = len(MODULES[name].read_text().splitlines())
    assert lines <= MAX_LINES, f"{MODULES[name]} has {lines} lines (at most {MAX_LINES})"


def test_every_subpackage_is_installed():
    """pyproject.toml lists each package explicitly (a missing one is absent from a wheel)."""
    listed = set(
        tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    )
    packages = {n for n, p in MODULES.items() if p.name == "__init__.py"}
    assert packages == listed
