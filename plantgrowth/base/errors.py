"""User-facing errors: every foreseeable bad input or failure ends in one of these.

The CLI turns them into a one-line message on stderr and exit code 2 (bad input) or 3
(a run that failed numerically), never a traceback.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TypeVar

from plantgrowth.meshes.geometry_error import GeometryError


class InputError(ValueError):
    """Bad user input; the message names the field and its valid range."""


class SceneError(InputError):
    """Bad scene input; the message starts with the dotted key (or the file name)."""


class RunError(RuntimeError):
    """A run that failed numerically; the message names the step, time, place and cause."""


class Interrupted(KeyboardInterrupt):
    """SIGINT stopped a run cleanly after a completed step (every completed step is saved). A
    KeyboardInterrupt, so that ``except Exception`` in a loop over runs does not go on after
    Ctrl-C (the CLI's exit code 130)."""

    def __init__(self, step: int, t: float) -> None:
        super().__init__(
            f"interrupted after step {step} (t = {t:g}); every completed step is saved"
        )
        self.step, self.t = step, t


USER_ERRORS = (InputError, GeometryError)
T = TypeVar("T")


def check_number(
    name: str, value: object, low: float, high: float, low_open: bool = True, high_open: bool = True
) -> float:
    """Return ``value`` as a float if it is finite and inside the interval, else raise.

    The interval is (low, high) with each end open or closed as asked; use +-inf for no bound.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{name} must be a number, got {value!r}")
    v = float(value)
    below = v <= low if low_open else v < low
    above = v >= high if high_open else v > high
    if not math.isfinite(v) or below or above:
        lo = ("(" if low_open else "[") + f"{low:g}"
        hi = f"{high:g}" + (")" if high_open else "]")
        raise InputError(f"{name} = {value!r} is out of range: it must be finite and in {lo}, {hi}")
    return v


def check_wall_material(E: object, nu: object) -> tuple[float, float]:
    """Young modulus E > 0 and Poisson ratio nu in (-1, 0.5) (plane-stress walls)."""
    return check_number("E", E, 0.0, math.inf), check_number("nu", nu, -1.0, 0.5)


def check_growth_tensor(name: str, Fg: object) -> list[list[float]]:
    """A finite 2x2 growth tensor with det Fg > 0."""
    try:
        rows = [[float(x) for x in row] for row in Fg]  # type: ignore[union-attr]
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a 2x2 array of numbers, got {Fg!r}") from None
    if len(rows) != 2 or any(len(r) != 2 for r in rows):
        raise InputError(f"{name} must be a 2x2 array of numbers, got {Fg!r}")
    if not all(math.isfinite(x) for r in rows for x in r):
        raise InputError(f"{name} = {rows} is invalid: all entries must be finite")
    det = rows[0][0] * rows[1][1] - rows[0][1] * rows[1][0]
    if det <= 0.0:
        raise InputError(f"{name} = {rows} is invalid: det {name} = {det:g} must be > 0")
    return rows


def on_rank_zero(comm, action: Callable[[], T]) -> T | None:
    """Collective: rank 0 runs ``action`` and gets its result (the other ranks get None); an
    InputError it raises is raised on every rank, so all fail the same way."""
    result, error = None, None
    if comm.rank == 0:
        try:
            result = action()
        except InputError as err:
            error = str(err)
    error = comm.bcast(error, root=0)
    if error:
        raise InputError(error)
    return result
