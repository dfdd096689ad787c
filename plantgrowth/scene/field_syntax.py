"""The syntax of a field value in a scene: a number, a linear field ``{from = a, to = b[, along =
"x1" | "x2"]}`` or an expression ``{expr = "..."}`` of x1, x2 and the named parameters."""

from __future__ import annotations

from plantgrowth.base.errors import SceneError
from plantgrowth.scene.expression import parse_expression
from plantgrowth.scene.fields import AXES, AnyField, ExprField, Field
from plantgrowth.scene.values import check_keys, choice, number, show


def parse_field(
    key: str, raw: object, width: float, height: float, constants: dict[str, float]
) -> AnyField:
    """A field value: a number, {from = a, to = b[, along = "x1" | "x2"]} or {expr = "..."} (of
    x1, x2 and the named parameters ``constants``)."""
    if isinstance(raw, dict):
        check_keys(raw, f"{key}.", ("from", "to", "along", "expr"))
        if "expr" in raw:
            if len(raw) != 1:
                raise SceneError(f'{key}: an expression field is {{expr = "..."}} alone')
            return ExprField(parse_expression(f"{key}.expr", raw["expr"], AXES, constants))
        if "from" not in raw or "to" not in raw:
            raise SceneError(f"{key}: a linear field needs both ends, {{from = a, to = b}}")
        along = choice(f"{key}.along", raw.get("along", "x1"), AXES)
        start, end = number(f"{key}.from", raw["from"]), number(f"{key}.to", raw["to"])
        return Field(start, end, width, height, along)
    if isinstance(raw, bool) or not isinstance(raw, (int, float)):
        raise SceneError(
            f'{key}: expected a number, {{from = a, to = b}} or {{expr = "..."}}, got '
            f"{show(raw)}"
        )
    return Field(number(key, raw), number(key, raw), width, height)
