"""Reading a scene: TOML text or parsed data in, a validated :class:`Scene` out (presets filled
in, relative mesh paths resolved)."""

from __future__ import annotations

import os
import tomllib
from pathlib import Path

from plantgrowth.base.errors import InputError, SceneError
from plantgrowth.meshes.honeycomb import GeometryError
from plantgrowth.scene.expression import parse_expression
from plantgrowth.scene.fields import AXES, AnyField, ExprField, Field
from plantgrowth.scene.limits import (
    LAWS,
    MAX_LENGTH,
    REFERENCE_WIDTH,
)
from plantgrowth.scene.presets import DEFAULT_PRESET, PRESETS
from plantgrowth.scene.schema import (
    Accuracy,
    CellGeometry,
    Growth,
    Material,
    Output,
    Scene,
    Solver,
    Time,
    Tissue,
)
from plantgrowth.scene.shapes import mesh_shape, outline_points, outline_shape
from plantgrowth.scene.values import (
    TABLES,
    check_keys,
    choice,
    in_range,
    number,
    show,
)

_FIELD_DEFAULTS = {
    "cell": {"l1": 1.0, "l2": 1.0, "theta": 30.0, "w": 0.05},
    "material": {"E": 1.0, "nu": 0.3},
    "pressure": {"P1": 0.001},
    "growth": {"eta": 1.0, "tau": 0.0},
}


def _table(data: dict, name: str) -> dict:
    """The top-level table ``name`` ({} if absent), its keys checked."""
    table = data.get(name, {})
    if not isinstance(table, dict):
        raise SceneError(f"{name}: expected a table [{name}], got {show(table)}")
    if name != "loads":  # the loadable edges depend on the tissue: Scene checks them
        check_keys(table, f"{name}.", TABLES[name])
    return table


def _tissue_box(tissue: dict) -> tuple[float, float]:
    """(width, height) of a tissue table: the rectangle's, or the bounding box of its outline
    or mesh (which may not be given with width or height)."""
    shapes = [key for key in ("outline", "mesh") if key in tissue]
    if not shapes:
        width = tissue.get("width", REFERENCE_WIDTH)
        return (
            in_range("tissue.width", width, 0.0, MAX_LENGTH, hi_open=False),
            in_range("tissue.height", tissue.get("height", 3.0), 0.0, MAX_LENGTH, hi_open=False),
        )
    for key in ("width", "height"):
        if key in tissue:
            raise SceneError(
                f"tissue.{key}: not with tissue.{shapes[0]}: its bounding box "
                "[0, width] x [0, height] sets the tissue's width and height"
            )
    if len(shapes) == 2:
        raise SceneError("tissue.mesh: not with tissue.outline: give one tissue shape")
    if "outline" in tissue:
        shape = outline_shape(outline_points(tissue["outline"]))
    else:
        shape = mesh_shape(tissue["mesh"])
    return shape.width, shape.height


def _mesh_path(value: object, directory: Path) -> str:
    """``tissue.mesh`` as an absolute path (a relative one is relative to ``directory``)."""
    if not isinstance(value, str):
        raise SceneError(f"tissue.mesh: expected a string (a .msh file path), got {show(value)}")
    return os.path.abspath(directory / value)


def _field(key: str, raw: object, width: float, height: float) -> AnyField:
    """A field value: a number, {from = a, to = b[, along = "x1" | "x2"]} or {expr = "..."}."""
    if isinstance(raw, dict):
        check_keys(raw, f"{key}.", ("from", "to", "along", "expr"))
        if "expr" in raw:
            if len(raw) != 1:
                raise SceneError(f'{key}: an expression field is {{expr = "..."}} alone')
            return ExprField(parse_expression(f"{key}.expr", raw["expr"], AXES))
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


def _with_preset(tables: dict[str, dict]) -> dict[str, dict]:
    """The tables with every knob of ``accuracy.preset`` the scene leaves out filled in; the
    preset's h and H clipped to the tissue (the scene's own values are never changed)."""
    name = choice(
        "accuracy.preset", tables["accuracy"].get("preset", DEFAULT_PRESET), tuple(PRESETS)
    )
    out = {section: dict(table) for section, table in tables.items()}
    for section, knobs in PRESETS[name].items():
        for key, value in knobs.items():
            out[section].setdefault(key, value)
    tissue, given = out["tissue"], tables["tissue"]
    width, height = _tissue_box(tissue)
    if "h" not in given:
        tissue["h"] = min(tissue["h"], min(width, height) / 2)
    if "H" not in given:
        h = in_range("tissue.h", tissue["h"], 0.0, min(width, height) / 2, hi_open=False)
        tissue["H"] = max(h, min(tissue["H"], max(width, height)))
    return out


def parse_scene(
    data: dict, source: str = "<scene>", directory: str | os.PathLike | None = None
) -> Scene:
    """Validate parsed TOML data into a Scene; error messages end with ``(in source)``. A
    relative ``tissue.mesh`` is relative to ``directory`` (default: the current directory)."""
    try:
        return _parse(data, Path.cwd() if directory is None else Path(directory))
    except (InputError, GeometryError) as e:
        suffix = "" if source == "<scene>" else f" (in {source})"
        raise SceneError(f"{e}{suffix}") from None


def _parse(data: dict, directory: Path) -> Scene:
    if not isinstance(data, dict):
        raise SceneError(f"scene: expected a table of tables, got {show(data)}")
    check_keys(data, "", ("model", *TABLES, "kinematics"))
    tables = {name: _table(data, name) for name in TABLES}
    if "mesh" in tables["tissue"]:
        tables["tissue"] = tables["tissue"] | {
            "mesh": _mesh_path(tables["tissue"]["mesh"], directory)
        }
    t = _with_preset(tables)
    tissue = Tissue(**t["tissue"])
    f = {
        section: {
            k: _field(f"{section}.{k}", t[section].get(k, d), tissue.width, tissue.height)
            for k, d in kd.items()
        }
        for section, kd in _FIELD_DEFAULTS.items()
    }
    if "law" not in t["growth"]:
        raise SceneError(f"growth.law is required: one of {', '.join(map(repr, LAWS))}")
    if isinstance(Fg0 := t["growth"].get("Fg0"), list):  # tables in it are fields
        f["growth"]["Fg0"] = [
            [
                _field(f"growth.Fg0[{i}][{j}]", x, tissue.width, tissue.height)
                if isinstance(x, dict)
                else x
                for j, x in enumerate(row)
            ]
            if isinstance(row, list)
            else row
            for i, row in enumerate(Fg0)
        ]
    return Scene(
        model=data.get("model", "macro"),
        tissue=tissue,
        cell=CellGeometry(**f["cell"]),
        material=Material(**f["material"]),
        P1=f["pressure"]["P1"],
        growth=Growth(**(t["growth"] | f["growth"])),
        time=Time(**t["time"]),
        loads=dict(t["loads"]),
        output=Output(**t["output"]),
        accuracy=Accuracy(**t["accuracy"]),
        micro_nx=t["micro"].get("nx", 16),
        micro_resolution=t["micro"].get("resolution", 2),
        solver=Solver(**t["solver"]),
        kinematics=data.get("kinematics", "linear"),
    )


def load_scene(path: str | os.PathLike) -> Scene:
    """Read and validate a scene file; every problem is a SceneError naming the file or key."""
    name = os.fspath(path)
    try:
        raw = Path(name).read_bytes()
    except FileNotFoundError:
        raise SceneError(f"{name}: scene file not found") from None
    except IsADirectoryError:
        raise SceneError(f"{name}: is a directory, not a scene file") from None
    except OSError as e:
        raise SceneError(f"{name}: cannot read the scene file: {e.strerror or e}") from None
    if b"\x00" in raw:
        raise SceneError(f"{name}: not a text file (it contains NUL bytes): a binary file?")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise SceneError(
            f"{name}: not UTF-8 text (bad byte at {e.start}): a binary file?"
        ) from None
    if not text.strip():
        raise SceneError(f"{name}: the scene file is empty (growth.law at least is required)")
    try:
        data = tomllib.loads(text)
    except ValueError as e:  # TOMLDecodeError, or an integer literal of > 4300 digits
        raise SceneError(f"{name}: invalid TOML: {e}") from None
    return parse_scene(data, source=name, directory=Path(name).parent)
