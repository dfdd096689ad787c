"""Named parameters of a scene (``[parameters]``): numbers that every expression may use by name
(``E_in = 0.3``, then ``{expr = "where(x1 < 2, E_in, 1)"}``), each replaced by its value when the
expression is parsed (:func:`plantgrowth.scene.expression.parse_expression`), so a parameter and
its literal give the same run; a sweep varies one as ``"parameters.E_in"``."""

from __future__ import annotations

import re
from collections.abc import Iterator

from plantgrowth.base.errors import SceneError
from plantgrowth.scene.expression import FUNCTIONS
from plantgrowth.scene.fields import AXES
from plantgrowth.scene.limits import BIG
from plantgrowth.scene.loads import VARIABLES
from plantgrowth.scene.values import in_range, show

NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,63}")
"""A parameter's (and a region's) name: an ASCII identifier of at most 64 characters."""
RESERVED = (*AXES, *VARIABLES, "pi", *FUNCTIONS)
"""Names an expression already gives a meaning: the coordinates, s, pi and the functions."""


def named_entries(table: object, section: str) -> Iterator[tuple[str, str, object]]:
    """(dotted key, name, value) of a table of named entries (``[parameters]``, ``[regions]``);
    SceneError unless it is a table and each name an identifier an expression can name."""
    if not isinstance(table, dict):
        raise SceneError(f"{section}: expected a table [{section}], got {show(table)}")
    for name, value in table.items():
        key = f"{section}.{name}"
        if not NAME.fullmatch(name):
            raise SceneError(
                f"{key}: {name!r} is not a valid name: letters, digits and _, starting with a "
                "letter or _, at most 64 characters"
            )
        yield key, name, value


def parse_parameters(table: object) -> dict[str, float]:
    """``[parameters]`` as name -> number; SceneError naming ``parameters.<name>`` for a bad
    name, a name an expression already uses (x1, x2, s, pi, a function) or a value that is not
    a finite number of magnitude at most 1e12."""
    out = {}
    for key, name, value in named_entries(table, "parameters"):
        if name in RESERVED:
            raise SceneError(
                f"{key}: the name {name!r} is taken in expressions (reserved: "
                f"{', '.join(RESERVED)}); choose another"
            )
        out[name] = in_range(key, value, -BIG, BIG, False, False)
    return out
