"""The mutation study's mutants still apply (scripts/studies/mutation_study.py, issue 33): each
replacement's old text occurs exactly once in its file, so a refactor that moves the code a
mutant changes fails here, in CI, instead of stopping the next study run (or, were the check
lost, silently shrinking it)."""

from __future__ import annotations

import runpy
from pathlib import Path
from types import SimpleNamespace

import pytest

REPO = Path(__file__).resolve().parents[1]
STUDY = SimpleNamespace(  # the script's MUTANTS and CATEGORIES
    **runpy.run_path(str(REPO / "scripts" / "studies" / "mutation_study.py"))
)


@pytest.mark.parametrize("mutant", STUDY.MUTANTS, ids=lambda m: m.name)
def test_every_replacement_matches_its_file_exactly_once(mutant):
    text = (REPO / mutant.file).read_text()
    assert mutant.replacements, f"{mutant.name} changes nothing"
    for old, new in mutant.replacements:
        assert old != new, f"{mutant.name}: a replacement that changes nothing"
        count = text.count(old)
        assert count == 1, f"{mutant.name}: {old!r} occurs {count} times in {mutant.file}"


def test_names_are_unique_and_categories_known():
    names = [m.name for m in STUDY.MUTANTS]
    assert len(set(names)) == len(names)
    assert {m.category for m in STUDY.MUTANTS} <= set(STUDY.CATEGORIES)
