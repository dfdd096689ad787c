"""Scene parameter fields: constant, linear along x1 or x2, or an expression of (x1, x2).

Every field evaluates at points, ``f(x1, x2)``, and gives its gradient there,
``f.gradient(x1, x2)`` of shape ``(..., 2)`` (docs/model.md section 6 uses grad P1). A linear field
runs from ``start`` at 0 to ``end`` at the tissue's extent along its axis (``width`` for x1,
``height`` for x2: the tissue actually simulated, docs/model.md section 7); its gradient is exact.
An expression's gradient is its symbolic derivative
(:meth:`plantgrowth.scene.expression.Expression.derivative`), also exact, so an expression equal to
a linear field gives the same values and gradient to round-off.

Range checks name the key: :meth:`Field.check` checks a linear field's ends (its extremes);
expressions are checked where they are used (:mod:`plantgrowth.scene.places`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from plantgrowth.base.errors import InputError, SceneError, check_number
from plantgrowth.scene.expression import Expression

AXES = ("x1", "x2")
"""The coordinates, and the names a field expression may use."""


def check_value(
    key: str, value: float, low: float, high: float, lo_open=True, hi_open=True, place: str = ""
) -> None:
    """SceneError naming ``key`` (and ``place``, e.g. "at x1 = 1, x2 = 0") unless ``value`` is
    finite and inside the interval."""
    try:
        check_number(key, value, low, high, lo_open, hi_open)
    except InputError as e:
        text = str(e) if not place else str(e).replace(" is out", f" {place} is out", 1)
        raise SceneError(text) from None


@dataclass(frozen=True)
class Field:
    """Constant (``start == end``) or linear along ``along`` across the tissue."""

    start: float  # value at 0
    end: float  # value at the tissue's extent along the axis (== start for a constant)
    width: float  # tissue extent along x1
    height: float  # tissue extent along x2
    along: str = "x1"

    def __post_init__(self) -> None:
        for name in ("start", "end", "width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise SceneError(f"field.{name}: expected a number, got {value!r}")
            object.__setattr__(self, name, float(value))
        if not (self.width > 0.0 and self.height > 0.0):
            raise SceneError(f"field extent {self.width!r} x {self.height!r} must be positive")
        if self.along not in AXES:
            raise SceneError(f"field.along = {self.along!r} is invalid: it must be 'x1' or 'x2'")

    @property
    def is_constant(self) -> bool:
        return self.start == self.end

    @property
    def slope(self) -> float:
        """d/d(along) = (end - start) / extent."""
        extent = self.width if self.along == "x1" else self.height
        return (self.end - self.start) / extent

    def __call__(self, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
        """Values at the points (x1, x2) (vectorised): start + slope * x_along."""
        x1, x2 = np.broadcast_arrays(np.asarray(x1, dtype=float), np.asarray(x2, dtype=float))
        return self.start + self.slope * (x1 if self.along == "x1" else x2)

    def gradient(self, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
        """(..., 2) gradient at the points: the constant slope along the field's axis."""
        shape = np.broadcast_shapes(np.shape(x1), np.shape(x2))
        axis = AXES.index(self.along)
        return np.broadcast_to(np.eye(2)[axis] * self.slope, (*shape, 2)).copy()

    def over(self, width: float, height: float) -> Field:
        """The same ends across a tissue of another extent (docs/model.md section 7)."""
        return replace(self, width=width, height=height)

    def to_toml(self) -> float | dict[str, float | str]:
        """A number for a constant, else {from = start, to = end} (with ``along`` if x2)."""
        if self.is_constant:
            return self.start
        out: dict[str, float | str] = {"from": self.start, "to": self.end}
        return out | ({"along": self.along} if self.along != "x1" else {})

    def check(self, key: str, low: float, high: float, lo_open=True, hi_open=True) -> None:
        """SceneError unless both ends lie in the interval (the extremes of a linear field)."""
        same = self.is_constant or (math.isnan(self.start) and math.isnan(self.end))
        ends = (
            [(key, self.start)] if same else [(f"{key}.from", self.start), (f"{key}.to", self.end)]
        )
        for name, value in ends:
            check_value(name, value, low, high, lo_open, hi_open)


@dataclass(frozen=True)
class ExprField:
    """A field given as an expression of x1 and x2 (:mod:`plantgrowth.scene.expression`)."""

    expression: Expression

    @property
    def is_constant(self) -> bool:
        return self.expression.is_constant

    def __call__(self, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
        """Values at the points (x1, x2), NaN or inf where the expression is undefined."""
        return self.expression(x1=x1, x2=x2)

    def gradient(self, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
        """(..., 2) symbolic gradient at the points."""
        parts = [self.expression.derivative(x)(x1=x1, x2=x2) for x in AXES]
        return np.stack(parts, axis=-1)

    def over(self, width: float, height: float) -> ExprField:
        """Itself: an expression is written in absolute coordinates."""
        return self

    def to_toml(self) -> dict[str, str]:
        return {"expr": self.expression.text}

    def check(self, key: str, low: float, high: float, lo_open=True, hi_open=True) -> None:
        """A constant expression's value; any other is checked at the places used."""
        if self.is_constant:
            check_value(key, float(self(0.0, 0.0)), low, high, lo_open, hi_open)


AnyField = Field | ExprField
