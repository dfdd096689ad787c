"""A sweep file read and checked: the base scene, the mode, the varied keys and every run's
validated scene (the format: :mod:`plantgrowth.studies.sweep`)."""

from __future__ import annotations

import difflib
import itertools
import math
import tomllib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from plantgrowth.base.errors import InputError
from plantgrowth.models.regions import region_columns
from plantgrowth.scene import Scene, load_scene, parse_scene
from plantgrowth.scene.limits import EDGES
from plantgrowth.scene.schema import with_values
from plantgrowth.scene.toml_text import dict_to_toml
from plantgrowth.scene.values import TABLES

MODES = ("grid", "one-at-a-time", "zip")
SWEEP_KEYS = ("base", "mode", "vary")
MAX_RUNS = 100_000
NUMBERS = ("t", "area", "growth_rate_11", "growth_rate_22", "growth_rate_area")

RunScene = Callable[..., None]
"""``run_scene(scene, outdir, comm, what, resume)``: the run path of ``plantgrowth run``."""


def cell(value: Any) -> str:
    """A value as shown in sweep.csv and messages: a string as is, anything else as TOML."""
    if isinstance(value, str):
        return value
    text = dict_to_toml({"v": [value]})  # "v = [<value>]\n": the inline form of any value
    return text[len("v = [") : -len("]\n")]


@dataclass(frozen=True)
class Run:
    """One run of a sweep: its number, the values it varies and its validated scene."""

    index: int
    values: dict[str, Any]
    scene: Scene

    @property
    def name(self) -> str:
        return f"run_{self.index:04d}"

    @property
    def label(self) -> str:
        """``run_0002 (material.nu = 0.3, time.t_max = 10.0)``."""
        return _label(self.index, self.values)


def _label(index: int, values: dict[str, Any]) -> str:
    return f"run_{index:04d} ({', '.join(f'{k} = {cell(v)}' for k, v in values.items())})"


@dataclass(frozen=True)
class Sweep:
    """A validated sweep: the resolved sweep file and its runs."""

    path: Path
    base: Path  # absolute
    mode: str
    vary: dict[str, list]
    runs: list[Run]
    base_cells: dict[str, str]  # the base scene's value of each varied key ("" if it has none)

    def resolved(self) -> dict[str, Any]:
        return {"base": str(self.base), "mode": self.mode, "vary": self.vary}

    def to_toml(self) -> str:
        header = f"# plantgrowth sweep, resolved from {self.path.resolve()}\n"
        return header + dict_to_toml(self.resolved())

    def cells(self, run: Run) -> dict[str, str]:
        """The varied-value columns of a run's row (one-at-a-time: the others at base)."""
        return {
            k: cell(run.values[k]) if k in run.values else self.base_cells[k] for k in self.vary
        }

    def numbers(self) -> list[str]:
        """The summary.csv columns a row takes from each run's last step: NUMBERS and the
        regions' columns of any run (in run order)."""
        regions = (c for run in self.runs for c in region_columns(run.scene.regions))
        return [*NUMBERS, *dict.fromkeys(regions)]

    def columns(self) -> list[str]:
        numbers = self.numbers()
        micro = [f"micro_{n}" for n in numbers] if self._has_both() else []
        return ["run", *self.vary, "status", *numbers, *micro, "seconds", "error"]

    def _has_both(self) -> bool:
        return any(run.scene.model == "both" for run in self.runs)


class SweepError(InputError):
    """Bad sweep file; the message names the key and ends with the file."""


def load_sweep(path: Path) -> Sweep:
    """Read and check a sweep file, its base scene and the scene of every run.

    Raises:
        InputError: one line naming the key (or the run and its values) and the file.
    """
    data = _read_toml(path)
    _check_top_keys(data, path)
    base = _base_path(data, path)
    base_scene = load_scene(base)  # its errors name the base file
    base_data = tomllib.loads(base.read_text(encoding="utf-8"))  # load_scene read it already
    keys = _scene_keys(base_scene)
    mode = _mode(data, path)
    vary = _vary(data, keys, mode, path)
    runs = [
        _run(i, values, base_data, path, base.parent)
        for i, values in enumerate(_combinations(vary, mode))
    ]
    flat = base_scene.dotted()
    base_cells = {k: cell(flat[k]) if k in flat else "" for k in vary}
    return Sweep(path, base, mode, vary, runs, base_cells)


def _fail(path: Path, message: str) -> SweepError:
    return SweepError(f"{message} (in {path})")


def _read_toml(path: Path) -> dict:
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SweepError(f"{path}: sweep file not found") from None
    except IsADirectoryError:
        raise SweepError(f"{path}: is a directory, not a sweep file") from None
    except UnicodeDecodeError as e:
        raise SweepError(
            f"{path}: not UTF-8 text (bad byte at {e.start}): a binary file?"
        ) from None
    except OSError as e:
        raise SweepError(f"{path}: cannot read the sweep file: {e.strerror or e}") from None
    except ValueError as e:  # TOMLDecodeError
        raise SweepError(f"{path}: invalid TOML: {e}") from None


def _check_top_keys(data: dict, path: Path) -> None:
    for key in data:
        if key not in SWEEP_KEYS:
            close = difflib.get_close_matches(key, SWEEP_KEYS, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            valid = ", ".join(SWEEP_KEYS)
            raise _fail(path, f"unknown key '{key}' (valid keys: {valid}){hint}")


def _base_path(data: dict, path: Path) -> Path:
    if "base" not in data:
        raise _fail(path, "base is required: the path of the base scene")
    raw = data["base"]
    if not isinstance(raw, str) or not raw:
        raise _fail(path, f"base: expected the path of the base scene, got {raw!r}")
    base = (path.parent / raw).resolve()  # an absolute raw path stays as it is
    if not base.is_file():
        raise _fail(path, f"base = {raw!r}: no such scene file ({base})")
    return base


def _mode(data: dict, path: Path) -> str:
    mode = data.get("mode", "grid")
    if mode not in MODES:
        options = ", ".join(map(repr, MODES))
        raise _fail(path, f"mode = {mode!r} is invalid: it must be one of {options}")
    return mode


def _scene_keys(scene: Scene) -> set[str]:
    """Every dotted key a scene has (``model``, ``material.nu``, ..., ``loads.right``,
    ``supports.left``, the keys of the optional tables [walls] and [feedback])."""
    edges = set(EDGES) | set(scene.tissue.edge_lengths())
    held = {f"supports.{edge}" for edge in scene.tissue.normal_axes()}
    optional = {f"{table}.{key}" for table in ("walls", "feedback") for key in TABLES[table]}
    return set(scene.dotted()) | {f"loads.{edge}" for edge in edges} | held | optional


def vary_items(table: dict, keys: set[str], prefix: str = "") -> Iterator[tuple[str, Any]]:
    """(dotted key, value) of a [vary] table, quoted (``"material.nu"``) or dotted
    (``material.nu``) keys alike; a scene key's table value is kept (it is not a list)."""
    for key, value in table.items():
        dotted = prefix + key
        if isinstance(value, dict) and dotted not in keys:
            yield from vary_items(value, keys, dotted + ".")
        else:
            yield dotted, value


def _vary(data: dict, keys: set[str], mode: str, path: Path) -> dict[str, list]:
    table = data.get("vary")
    if not isinstance(table, dict) or not table:
        raise _fail(path, "vary is required: a table of dotted scene keys, each a list of values")
    vary: dict[str, list] = {}
    for key, values in vary_items(table, keys):
        if key not in keys:
            raise _fail(path, f"vary: '{key}' is not a scene key{_suggest(key, keys)}")
        if key in vary:
            raise _fail(path, f"vary: '{key}' is given twice")
        if not isinstance(values, list) or not values:
            raise _fail(path, f"vary.'{key}': expected a non-empty list of values, got {values!r}")
        for i, value in enumerate(values):
            if value in values[:i] and mode != "zip":  # zip: the runs' tuples must differ
                raise _fail(path, f"vary.'{key}' lists {cell(value)} twice")
        vary[key] = values
    sizes = [len(values) for values in vary.values()]
    if mode == "zip":
        _check_zip(vary, path)
    count = {"grid": math.prod(sizes), "one-at-a-time": sum(sizes), "zip": sizes[0]}[mode]
    if count > MAX_RUNS:
        raise _fail(path, f"vary: the sweep has {count} runs (at most {MAX_RUNS})")
    return vary


def _check_zip(vary: dict[str, list], path: Path) -> None:
    """``mode = "zip"``: run i takes the i-th value of every list, so the lists must be of one
    length and no two runs alike."""
    sizes = {key: len(values) for key, values in vary.items()}
    if len(set(sizes.values())) > 1:
        shown = ", ".join(f"'{k}' has {n}" for k, n in sizes.items())
        raise _fail(
            path, f'vary: mode = "zip" takes the i-th value of every list, so the lists must '
            f"have equal lengths: {shown}"
        )  # fmt: skip
    runs = list(zip(*vary.values(), strict=True))
    for i, values in enumerate(runs):
        if values in runs[:i]:
            raise _fail(path, f"vary: runs {runs.index(values)} and {i} of the zip are the same")


def _suggest(key: str, keys: set[str]) -> str:
    last = key.rsplit(".", 1)[-1]
    close = sorted(k for k in keys if k.rsplit(".", 1)[-1] == last)
    close = close or difflib.get_close_matches(key, sorted(keys), n=1)
    return f"; did you mean '{close[0]}'?" if close else ""


def _combinations(vary: dict[str, list], mode: str) -> list[dict[str, Any]]:
    """The varied values of each run, in run order."""
    if mode in ("grid", "zip"):
        combined = itertools.product if mode == "grid" else zip
        return [dict(zip(vary, values, strict=True)) for values in combined(*vary.values())]
    return [{key: value} for key, values in vary.items() for value in values]


def _run(index: int, values: dict[str, Any], base_data: dict, path: Path, directory: Path) -> Run:
    """One run: the base scene with the run's values (a relative tissue.mesh is relative to the
    base scene's directory, ``directory``)."""
    source = f"{path}: {_label(index, values)}"
    scene = parse_scene(with_values(base_data, values), source=source, directory=directory)
    return Run(index, values, scene)
