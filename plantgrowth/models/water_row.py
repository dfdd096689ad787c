"""summary.csv's water columns of a step (docs/outputs.md), the same for the micro and the macro
model: their names are :data:`plantgrowth.models.micro.water.WATER_COLUMNS` and one
``inflow.<label>`` per supply (:func:`plantgrowth.models.micro.water.water_columns`)."""

from __future__ import annotations

from collections.abc import Mapping

from plantgrowth.models.micro.water import WATER_COLUMNS


def water_row(
    turgor: tuple[float, float, float], water: float, balance_error: float,
    inflows: Mapping[str, float],
) -> dict[str, float]:  # fmt: skip
    """The row: turgor (mean, min, max), the water held, the balance error (what came in over
    the step minus the change of the water held) and each supply's inflow rate by label."""
    values = (*turgor, water, balance_error)
    row = {name: float(v) for name, v in zip(WATER_COLUMNS, values, strict=True)}
    return row | {f"inflow.{label}": float(v) for label, v in inflows.items()}
