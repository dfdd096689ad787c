"""CITATION.cff (Citation File Format 1.2.0) parses, has the keys the format requires, and
names the version pyproject.toml gives and the licence LICENSE holds."""

from __future__ import annotations

import datetime
import re
import tomllib
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parent.parent
REQUIRED = ("cff-version", "message", "title", "authors")  # CFF 1.2.0's required keys
REFERENCE_REQUIRED = ("type", "title", "authors")  # those of a reference


def citation() -> dict:
    return yaml.safe_load((ROOT / "CITATION.cff").read_text())


def test_citation_has_the_required_keys():
    cff = citation()
    assert cff["cff-version"] == "1.2.0"
    assert all(cff.get(key) for key in REQUIRED), [k for k in REQUIRED if not cff.get(k)]
    for author in cff["authors"]:  # a person (family-names) or an entity (name)
        assert author.get("name") or author.get("family-names"), author
    reference = cff["preferred-citation"]
    assert all(reference.get(key) for key in REFERENCE_REQUIRED), reference
    assert re.fullmatch(r"10\.\d{4,9}/\S+", reference["doi"])
    datetime.date.fromisoformat(cff["date-released"])  # a string YYYY-MM-DD, as CFF asks


def test_citation_version_and_licence_match_the_package():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    cff = citation()
    assert cff["version"] == project["version"]
    assert cff["license"] == project["license"]["text"]
    assert (ROOT / "LICENSE").read_text().startswith(f"{cff['license']} License\n")
