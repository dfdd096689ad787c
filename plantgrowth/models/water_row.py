"""summary.csv's water columns of a step (docs/outputs.md), the same for the micro and the macro
model: their names are :data:`plantgrowth.models.micro.water.WATER_COLUMNS` and one
``inflow.<label>`` per supply (:func:`plantgrowth.models.micro.water.water_columns`); and the
ledger that sums a step's sub-steps into them (:class:`WaterLedger`)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

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


class WaterLedger:
    """The water a step brings in when it is taken in sub-steps (the adaptive integrator), each
    advancing the water by backward Euler over its own dt_k:

        balance error = sum_k dt_k sum_s inflow_s,k - (water - water at the step's start)
        rate          = sum_k dt_k rate_k / sum_k dt_k     (one sub-step: its own rate)

    :meth:`record` takes each solve's rates, :meth:`keep` keeps the last as a sub-step (a
    rejected one is not kept), :meth:`close` ends the step."""

    def __init__(self) -> None:
        self.start: float | None = None  # the water held at the step's start
        self._kept: list[tuple] = []  # (dt, held, supplied, cells) of the step's kept sub-steps
        self._last: tuple | None = None  # the last solve's

    def record(
        self, dt: float | None, held: float, supplied: Mapping[str, float],
        cells: np.ndarray | None = None,
    ) -> tuple[float, dict[str, float], np.ndarray | None]:  # fmt: skip
        """A solve that advanced the water by dt (None: the initial state) to ``held``, with
        each supply's inflow rate (and each cell's, ``cells``): the balance error and the rates
        of the step so far (its kept sub-steps and this solve)."""
        self._last = (dt, held, dict(supplied), cells)
        if dt is None or self.start is None:
            return 0.0, dict(supplied), cells
        steps = [*self._kept, self._last]
        gained = sum(d * sum(s.values()) for d, _, s, _ in steps)
        error = gained - (held - self.start)
        if not self._kept:
            return error, dict(supplied), cells
        span = sum(d for d, *_ in steps)
        mean = {k: sum(d * s[k] for d, _, s, _ in steps) / span for k in supplied}
        flows = None if cells is None else sum(d * c for d, _, _, c in steps) / span
        return error, mean, flows

    def keep(self) -> None:
        """The last solve is a kept sub-step: the step's later solves add to it."""
        self._kept.append(self._last)

    def close(self, held: float | None = None) -> None:
        """The step ends: the last solve's water (or ``held``: a resumed run's) is the next
        step's start."""
        self.start = self._last[1] if held is None else held
        self._kept = []
