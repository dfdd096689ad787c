"""Named regions of a scene (``[regions] disc = {expr = "(x1 - 3)**2 + (x2 - 1.5)**2 < 1"}``): a
condition on the reference position (x1, x2), true where the expression is non-zero. The run
reports each region's statistics per step in summary.csv (plantgrowth/models/regions.py); a
growth unit belongs to a region when the condition holds at its reference midpoint (macro: the
fine triangle's midpoint; micro: the cell centre, where the run evaluates the cell's fields).
Whether a region holds any unit, and a finite value at every one, is checked on the mesh
(:func:`plantgrowth.scene.places.check_regions`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from plantgrowth.base.errors import SceneError
from plantgrowth.scene.expression import Expression, parse_expression
from plantgrowth.scene.fields import AXES
from plantgrowth.scene.parameters import named_entries
from plantgrowth.scene.values import check_keys, show


@dataclass(frozen=True)
class Region:
    """A named condition on the reference position."""

    name: str
    expression: Expression

    def values(self, points: np.ndarray) -> np.ndarray:
        """The condition's values at (n, 2) reference points (NaN where undefined)."""
        return self.expression(x1=points[:, 0], x2=points[:, 1])

    def inside(self, points: np.ndarray) -> np.ndarray:
        """(n,) True where the condition is non-zero at the points."""
        return self.values(points) != 0.0

    def to_toml(self) -> dict[str, str]:
        return {"expr": self.expression.text}


def parse_regions(table: object, constants: Mapping[str, float]) -> dict[str, Region]:
    """``[regions]`` as name -> Region: each ``name = {expr = "..."}`` an expression of x1, x2
    and the named parameters; SceneError naming ``regions.<name>`` otherwise, or when the
    condition is the constant 0 (an empty region)."""
    out = {}
    for key, name, raw in named_entries(table, "regions"):
        if not isinstance(raw, dict) or "expr" not in raw:
            raise SceneError(
                f'{key}: a region is {{expr = "..."}}, a condition on x1 and x2 (e.g. '
                f'"(x1 - 3)**2 + (x2 - 1.5)**2 < 1"), got {show(raw)}'
            )
        check_keys(raw, f"{key}.", ("expr",))
        expression = parse_expression(f"{key}.expr", raw["expr"], AXES, constants)
        value = float(expression(x1=0.0, x2=0.0))
        if expression.is_constant and (value == 0.0 or not np.isfinite(value)):
            raise SceneError(
                f"{key}: the condition {expression.text!r} is {value:g} everywhere: a region must "
                "be non-zero (true) somewhere and finite everywhere"
            )
        out[name] = Region(name, expression)
    return out
