"""The "did you mean" of an unknown field name (``[output] fields``, ``render --field``): the
names a biologist reaches for first, and the valid names spelled alike."""

from __future__ import annotations

import difflib
from collections.abc import Sequence

SYNONYMS = {
    "stress": ("sigma_hom",),
    "sigma": ("sigma_hom",),
    "strain": ("eps_hom", "elastic_strain"),
    "eps": ("eps_hom", "elastic_strain"),
    "growth": ("G",),
    "growth_rate": ("G", "trG"),
    "displacement": ("u",),
    "fibres": ("fibre_direction",),
    "fibers": ("fibre_direction",),
    "director": ("fibre_direction",),
}
"""Words for a field (lower case) -> the fields they mean (docs/outputs.md)."""


def close_fields(name: object, valid: Sequence[str]) -> list[str]:
    """The fields of ``valid`` that ``name`` may mean: its synonyms first, then the names
    ``difflib.get_close_matches`` finds alike (ratio >= 0.6), without repeats."""
    if not isinstance(name, str):
        return []
    meant = [f for f in SYNONYMS.get(name.lower(), ()) if f in valid]
    alike = difflib.get_close_matches(name, list(valid), n=3, cutoff=0.6)
    return list(dict.fromkeys(meant + alike))
