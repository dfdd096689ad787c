"""Checks of single scene values shared by the dataclasses and the loader: each raises
SceneError naming the dotted key."""

from __future__ import annotations

import difflib
from collections.abc import Sequence

from plantgrowth.base.errors import InputError, SceneError, check_number
from plantgrowth.scene.limits import EDGES

TABLES = {
    "tissue": ("width", "height", "h", "H", "outline", "mesh", "cells", "pixel_size"),
    "cell": ("l1", "l2", "theta", "w"),
    "material": ("E", "nu"),
    "pressure": ("P1",),
    "growth": ("law", "eta", "tau", "clamp", "Fg0"),
    "time": ("t_max", "dt", "integrator", "tolerance"),
    "loads": EDGES,
    "supports": (*EDGES, "bottom"),
    "output": ("fields", "every", "precision"),
    "accuracy": (
        "preset", "cell_resolution", "key_tolerance", "cell_tolerance", "cell_interpolant",
    ),
    "micro": ("nx", "resolution"),
    "solver": ("macro", "macro_threshold", "macro_rtol", "macro_spare_iterations"),
    "numerics": ("on_instability",),
    "walls": ("fibre_stiffness", "fibre_angle"),
    "feedback": ("cue", "rate", "walls"),
    "hydraulics": ("osmotic", "conductivity", "initial_potential", "supply"),
}

# --- checks shared by the dataclasses and the loader ----------------------------------------------


def show(value: object) -> str:
    kind = {dict: "a table ", list: "an array ", tuple: "an array "}.get(type(value), "")
    text = repr(value)
    return kind + (text if len(text) <= 60 else text[:57] + "...")


def number(key: str, value: object) -> float:
    """``value`` as a float (ints accepted), else SceneError naming ``key``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"{key}: expected a number, got {show(value)}")
    try:
        return float(value)
    except OverflowError:  # a TOML integer beyond the float range
        raise SceneError(f"{key} = {str(value)[:12]}... is out of range: far too large") from None


def in_range(key: str, value: object, low: float, high: float, lo_open=True, hi_open=True) -> float:
    """A finite number in the interval (open or closed ends), else SceneError naming ``key``."""
    number(key, value)  # the type and float-range check, with the key
    try:  # the user's own value (e.g. 0, not 0.0) in the message
        return check_number(key, value, low, high, lo_open, hi_open)
    except InputError as e:
        raise SceneError(str(e)) from None


def integer(key: str, value: object, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise SceneError(f"{key}: expected an integer, got {show(value)}")
    if not low <= value <= high:
        raise SceneError(
            f"{key} = {value} is out of range: it must be an integer in [{low}, {high}]"
        )
    return value


def choice(key: str, value: object, choices: tuple[str, ...], close: Sequence[str] = ()) -> str:
    """``value`` if it is one of ``choices``, else SceneError naming ``key``, the choices and
    the ``close`` ones it may mean ("did you mean")."""
    options = ", ".join(map(repr, choices))
    if not isinstance(value, str):
        raise SceneError(f"{key}: expected a string (one of {options}), got {show(value)}")
    if value not in choices:
        hint = f"; did you mean {' or '.join(map(repr, close))}?" if close else ""
        raise SceneError(f"{key} = {value!r} is invalid: it must be one of {options}{hint}")
    return value


def array(key: str, value: object, n: int) -> list | tuple:
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise SceneError(f"{key}: expected an array of {n} items, got {show(value)}")
    return value


def set_fields(obj: object, **values: object) -> None:
    """Store normalised values in a frozen dataclass."""
    for name, value in values.items():
        object.__setattr__(obj, name, value)


def check_keys(table: dict, path: str, valid: tuple[str, ...]) -> None:
    for key in table:
        if key not in valid:
            elsewhere = [f"{t}.{key}" for t, keys in TABLES.items() if key in keys]  # wrong table
            close = elsewhere if path.count(".") <= 1 else []
            close = close or difflib.get_close_matches(key, valid, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            raise SceneError(f"unknown key '{path}{key}' (valid keys: {', '.join(valid)}){hint}")
