"""The mutation study's mutants still apply (scripts/studies/mutation_study.py, issue 33): each
replacement's old text occurs exactly once in its file, so a refactor that moves the code a
mutant changes fails here, in CI, instead of stopping the next study run (or, were the check
lost, silently shrinking it)."""

from __future__ import annotations

import runpy
from pathlib import Path
from types import SimpleNamespace

REPO = Path(__file__).resolve().parents[1]
STUDY = SimpleNamespace(  # the script's MUTANTS and CATEGORIES
    **runpy.run_path(str(REPO / "scripts" / "studies" / "mutation_study.py"))
)


def test_every_replacement_matches_its_file_exactly_once():
    problems = []
    for m in STUDY.MUTANTS:
        text = (REPO / m.file).read_text()
        if not m.replacements or any(old == new for old, new in m.replacements):
            problems.append(f"{m.name}: a replacement that changes nothing")
        for old, _ in m.replacements:
            if (count := text.count(old)) != 1:
                problems.append(f"{m.name}: {old!r} occurs {count} times in {m.file}")
    assert not problems, "mutant patterns out of date:\n  " + "\n  ".join(problems)


def test_names_are_unique_and_categories_known():
    names = [m.name for m in STUDY.MUTANTS]
    assert len(set(names)) == len(names)
    assert {m.category for m in STUDY.MUTANTS} <= set(STUDY.CATEGORIES)
