"""Seeded generator of malformed inputs for the ``plantgrowth`` CLI (not a test module).

``generate(seed, n)`` returns ``n`` :class:`Case` objects mixing the classes of :data:`CLASSES` at
random: malformed scene files (wrong types, missing or unknown keys, NaN/inf, sizes <= 0, nu out of
(-1, 0.5), walls too thick for the cell, bad angles and time steps, empty/binary/invalid TOML, huge
numbers, bad {from, to} fields and loads, bad expressions, expression fields out of range inside the
tissue, bad micro scenes, bad held edges, bad regions (malformed, empty or undefined on the mesh)
and named parameters (undefined, shadowing x1, x2, s, pi or a function), bad water fluxes
([hydraulics]: bad values and supplies, P1 given as well, models that cannot take it), bad fibre
walls and feedback (and valid micro ones, which the runner refuses), a ``feedback.walls`` neither
"around" nor "own", output fields named by a word or a typo (the error says which field it may
mean), zip sweeps whose lists differ in length), bad command lines (``render`` and ``export`` of
runs that are not there, into files they must not write) and output paths that cannot be written.
Every case must end with exit code 2 and a one-line ``plantgrowth: error: ...`` naming the field
(``Case.expect``), before anything is written.

A case is materialized in its own empty directory: ``files`` are written there and ``{dir}`` in
``argv`` and ``expect`` stands for that directory. Cases with ``isolate = True`` could run for
minutes if the input is not rejected (huge mesh resolutions): run those in a subprocess with a
time limit, never in-process.
"""

from __future__ import annotations

import json
import math
import os
import random
import signal
import string
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plantgrowth.meshes.honeycomb import HoneycombCell

SCENE = "scene.toml"  # the scene file of scene cases, in {dir}


@dataclass(frozen=True)
class Case:
    """One malformed input and what the CLI must answer.

    Attributes:
        name: unique, readable id (class, index, short description).
        cls: the class of error (a key of :data:`CLASSES`).
        kind: "scene" (a scene file), "argv" (a command line) or "setup" (an output path that
            cannot be written).
        argv: the command line, ``{dir}`` standing for the case's directory.
        expect: fragments the one-line error message must all contain (``{dir}`` likewise).
        files: (relative path, content) written into the case's directory before the call.
        code: the expected exit code.
        isolate: run only in a subprocess with a time limit (a bug could mean minutes of work).
    """

    name: str
    cls: str
    kind: str
    argv: tuple[str, ...]
    expect: tuple[str, ...]
    files: tuple[tuple[str, str | bytes], ...] = ()
    code: int = 2
    isolate: bool = False

    def materialize(self, directory: Path) -> list[str]:
        """Write the case's files into ``directory``; return the argv to call ``main`` with."""
        for rel, content in self.files:
            path = directory / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            if isinstance(content, bytes):
                path.write_bytes(content)
            else:
                path.write_text(content)
        return [a.replace("{dir}", str(directory)) for a in self.argv]

    def fragments(self, directory: Path) -> list[str]:
        return [e.replace("{dir}", str(directory)) for e in self.expect]


# --- scene schema and a random valid base scene -----------------------------------------------


class Raw(str):
    """A TOML value written verbatim (nan, 10**400 digits, dates, broken arrays...)."""


FLOAT_KEYS = {  # plain numbers
    "tissue": ("width", "height", "h", "H"),
    "growth": ("clamp",),
    "time": ("t_max", "dt"),
    "accuracy": ("key_tolerance",),
    "solver": ("macro_rtol",),
}
FIELD_KEYS = {  # number or {from, to}
    "cell": ("l1", "l2", "theta", "w"),
    "material": ("E", "nu"),
    "pressure": ("P1",),
    "growth": ("eta", "tau"),
}
INT_KEYS = {"accuracy": ("cell_resolution",), "micro": ("nx", "resolution"), "output": ("every",),
            "solver": ("macro_threshold", "macro_spare_iterations")}  # fmt: skip
CHOICE_KEYS = {("", "model"), ("growth", "law"), ("time", "integrator"), ("accuracy", "preset"),
               ("output", "precision"), ("solver", "macro")}  # fmt: skip
TABLES = ("tissue", "cell", "material", "pressure", "growth", "time", "loads", "output",
          "accuracy", "micro", "solver")  # fmt: skip
SCHEMA = {
    "tissue": ("width", "height", "h", "H"),
    "cell": ("l1", "l2", "theta", "w"),
    "material": ("E", "nu"),
    "pressure": ("P1",),
    "growth": ("law", "eta", "tau", "clamp", "Fg0"),
    "time": ("t_max", "dt", "integrator"),
    "loads": ("left", "right", "top"),
    "output": ("fields", "every", "precision"),
    "accuracy": ("preset", "cell_resolution", "key_tolerance", "cell_tolerance"),
    "micro": ("nx", "resolution"),
    "solver": ("macro", "macro_threshold", "macro_rtol", "macro_spare_iterations"),
}
OUTPUT_FIELDS = ("u", "Fg", "G", "sigma_hom", "E_hom", "eps_hom", "trG", "growth_anisotropy",
                 "growth_direction", "stress_direction")  # fmt: skip


def _pairs(table: dict[str, tuple[str, ...]]) -> list[tuple[str, str]]:
    return [(t, k) for t, keys in table.items() for k in keys]


def _toml(value: object) -> str:
    if isinstance(value, Raw):
        return str(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value + '"'
    if isinstance(value, float):
        return repr(value)  # round-trips; nan/inf are valid TOML
    if isinstance(value, int):
        return str(value)
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    raise TypeError(value)


def to_toml(scene: dict) -> str:
    """TOML text of a scene dict (top-level scalars first, then one [table] each)."""
    lines = [f"{k} = {_toml(v)}" for k, v in scene.items() if not isinstance(v, dict)]
    for name, table in scene.items():
        if isinstance(table, dict):
            lines += ["", f"[{name}]"] + [f"{k} = {_toml(v)}" for k, v in table.items()]
    return "\n".join(lines) + "\n"


def _w_max(l1: float, l2: float, theta: float) -> float:
    return HoneycombCell(l1, l2, theta, 1e-12).w_max


def base_scene(rng: random.Random, micro: bool = False) -> dict:
    """A random *valid* scene dict; macro with optional loads unless ``micro``."""
    width, height = rng.uniform(2.0, 10.0), rng.uniform(1.0, 5.0)
    h = rng.choice([0.1, 0.2, 0.25, 0.5])
    l1, l2, theta = rng.uniform(0.5, 2.0), rng.uniform(0.5, 2.0), rng.uniform(15.0, 60.0)
    w = rng.uniform(0.05, 0.5) * _w_max(l1, l2, theta)
    dt = rng.choice([0.5, 1.0, 2.0])
    scene: dict = {"model": rng.choice(["micro", "both"]) if micro else "macro"}
    options = {
        "tissue": {"h": h, "H": rng.uniform(h, 2.0)}
        | ({} if micro else {"width": width, "height": height}),  # micro: its own tissue
        "cell": {"l1": l1, "l2": l2, "theta": theta, "w": w},
        "material": {"E": rng.uniform(0.1, 10.0), "nu": rng.uniform(-0.5, 0.45)},
        "pressure": {"P1": rng.uniform(0.0, 0.01)},
        "growth": {"eta": rng.uniform(0.0, 2.0), "tau": rng.uniform(0.0, 0.01),
                   "clamp": rng.uniform(0.1, 2.0), "Fg0": [[1.0, 0.0], [0.0, 1.0]]},
        "time": {"t_max": dt * rng.randint(1, 80), "dt": dt,
                 "integrator": rng.choice(["exp", "euler"])},
        "loads": {} if micro else rng.choice([{"left": [-0.001, 0.0], "right": [0.001, 0.0]},
                                              {"top": [0.0, 0.001]}, {"right": [0.0, 0.001]}]),
        "output": {"fields": rng.sample(OUTPUT_FIELDS, rng.randint(1, len(OUTPUT_FIELDS))),
                   "every": rng.randint(1, 10), "precision": rng.choice(["float32", "float64"])},
        "accuracy": {"cell_resolution": rng.randint(1, 4), "key_tolerance": 1e-6},
        "micro": {"nx": 2 * rng.randint(1, 16), "resolution": rng.randint(1, 4)},
        "solver": {"macro": rng.choice(["auto", "direct", "iterative"]),
                   "macro_threshold": rng.randint(0, 10**6),
                   "macro_rtol": rng.choice([1e-12, 1e-10, 1e-7, 1e-5]),
                   "macro_spare_iterations": rng.randint(0, 10)},
    }  # fmt: skip
    for name in TABLES:  # a random subset of the keys (cell, time: all or none), growth.law
        whole = name in ("cell", "time")  # a default w or t_max may not fit the others
        keep = rng.random() < 0.5
        chosen = {k: v for k, v in options[name].items() if (keep if whole else rng.random() < 0.5)}
        if name == "growth":
            chosen = {"law": rng.choice(["stress", "strain", "none"]), **chosen}
        if chosen or rng.random() < 0.3:
            scene[name] = chosen
    return scene


def _set(scene: dict, table: str, key: str, value: object) -> None:
    if table:
        scene.setdefault(table, {})[key] = value
    else:
        scene[key] = value


def _magnitude(rng: random.Random, low: float = -6.0, high: float = 6.0) -> float:
    return 10.0 ** rng.uniform(low, high)


def _name(rng: random.Random, valid: tuple[str, ...] = ()) -> str:
    while True:
        first = rng.choice(string.ascii_letters)
        rest = "".join(
            rng.choices(string.ascii_letters + string.digits + "_-", k=rng.randint(0, 9))
        )
        if first + rest not in valid:
            return first + rest


def square_msh(groups: dict[str, tuple[int, ...]]) -> str:
    """A gmsh 2.2 .msh text of the square [0, 2]^2 (nodes 1-4 counter-clockwise from the origin,
    two triangles in the surface group "tissue") with the named groups: name -> its node
    numbers, one node for a point group, two for a curve group (one line)."""
    names, elements = ['2 1 "tissue"'], []
    for tag, (name, nodes) in enumerate(groups.items(), start=1):
        dim = len(nodes) - 1
        names.append(f'{dim} {tag} "{name}"')
        elements.append(f"{(15, 1)[dim]} 2 {tag} {tag} {' '.join(map(str, nodes))}")
    elements += ["2 2 1 1 1 2 3", "2 2 1 1 1 3 4"]
    numbered = [f"{i} {e}" for i, e in enumerate(elements, start=1)]
    return "\n".join([
        "$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$PhysicalNames", str(len(names)), *names,
        "$EndPhysicalNames", "$Nodes", "4", "1 0 0 0", "2 2 0 0", "3 2 2 0", "4 0 2 0",
        "$EndNodes", "$Elements", str(len(numbered)), *numbered, "$EndElements", "",
    ])  # fmt: skip


# --- the classes --------------------------------------------------------------------------------
# Each maker returns (kind, files, argv, expect) or, for scene classes, (scene dict or text, key).

WRONG_FOR_NUMBER = ['"abc"', '"1.0"', "true", "false", "[1, 2]", "[]", "1979-05-27",
                    "12:30:00", '""']  # fmt: skip


def _wrong_type(rng: random.Random, scene: dict):
    what = rng.choice(["float", "field", "int", "choice", "table", "fields", "Fg0", "field_tbl"])
    if what == "float":
        table, key = rng.choice(_pairs(FLOAT_KEYS))
        value = Raw(rng.choice(WRONG_FOR_NUMBER + ["{ a = 1 }", "{ from = 1, to = 2 }"]))
    elif what in ("field", "field_tbl"):
        table, key = rng.choice(_pairs(FIELD_KEYS))
        value = Raw(rng.choice(WRONG_FOR_NUMBER) if what == "field" else f"{{ {_name(rng)} = 1 }}")
    elif what == "int":
        table, key = rng.choice(_pairs(INT_KEYS))
        value = Raw(rng.choice(WRONG_FOR_NUMBER + ["2.0", "4.5", "1e1", "{ a = 1 }"]))
    elif what == "choice":
        table, key = rng.choice(sorted(CHOICE_KEYS))
        value = Raw(rng.choice(["1", "0.5", "true", '["stress"]', "{ a = 1 }", "1979-05-27"]))
    elif what == "table":
        table, key = "", rng.choice(TABLES)
        scene.pop(key, None)
        value = Raw(rng.choice(["3", '"x"', "[1, 2]", "true", "1.5"]))
        _set(scene, table, key, value)
        return scene, key
    elif what == "fields":
        table, key = "output", "fields"
        value = Raw(rng.choice(['"u"', "3", "{ u = 1 }", "[1]", '["u", 2]', '[["u"]]']))
    else:
        table, key = "growth", "Fg0"
        value = Raw(rng.choice(["1.0", '"I"', "[1, 0, 0, 1]", "[[1, 0], [0]]", '[["a", 0], [0, 1]]',
                                "[[1, 0], [0, 1], [0, 0]]", "[[true, 0], [0, 1]]"]))  # fmt: skip
    _set(scene, table, key, value)
    return scene, f"{table}.{key}" if table else key


def _missing_required(rng: random.Random, scene: dict):
    if rng.random() < 0.5:
        scene.pop("growth", None)
    else:
        scene.setdefault("growth", {}).pop("law", None)
    return scene, "growth.law"


def _unknown_key(rng: random.Random, scene: dict):
    level = rng.choice(["top", "top_table", "table", "field", "loads"])
    if level in ("top", "top_table"):
        name = _name(rng, ("model", *TABLES))
        value = rng.choice([1, "x", 0.5]) if level == "top" else {"a": 1}
        scene[name] = value
        return scene, f"'{name}'"
    if level == "loads":
        name = _name(rng, SCHEMA["loads"] + ("bottom",))
        scene.setdefault("loads", {})[name] = [0.0, 0.0]
        return scene, f"'loads.{name}'"
    if level == "table":
        table = rng.choice(TABLES)
        name = _name(rng, SCHEMA[table])
        scene.setdefault(table, {})[name] = rng.choice([1, 1.5, "x", True])
        return scene, f"'{table}.{name}'"
    table, key = rng.choice(_pairs(FIELD_KEYS))
    name = _name(rng, ("from", "to"))
    _set(scene, table, key, {"from": 0.01, "to": 0.02, name: 1.0})
    return scene, f"'{table}.{key}.{name}'"


NONFINITE = ["nan", "+nan", "-nan", "inf", "+inf", "-inf"]


def _nonfinite(rng: random.Random, scene: dict):
    bad = Raw(rng.choice(NONFINITE))
    where = rng.choice(["float", "field", "field_end", "int", "loads", "Fg0"])
    if where == "float":
        table, key = rng.choice(_pairs(FLOAT_KEYS))
        value = bad
    elif where in ("field", "field_end"):
        table, key = rng.choice(_pairs(FIELD_KEYS))
        ok = _valid_value(table, key, scene)
        value = bad if where == "field" else _one_end(rng, ok, bad)
    elif where == "int":
        table, key = rng.choice(_pairs(INT_KEYS))
        value = bad
    elif where == "loads":
        scene.pop("model", None)
        table, key = "loads", rng.choice(SCHEMA["loads"])
        value = Raw(f"[{bad}, 0.0]" if rng.random() < 0.5 else f"[0.0, {bad}]")
    else:
        table, key = "growth", "Fg0"
        value = Raw(f"[[{bad}, 0.0], [0.0, 1.0]]")
    _set(scene, table, key, value)
    return scene, f"{table}.{key}"


def _valid_value(table: str, key: str, scene: dict) -> float:
    """A value of a field key that is valid with the scene's cell (used for the good end)."""
    current = scene.get(table, {}).get(key)
    if isinstance(current, float) and not isinstance(current, Raw):
        return current
    return {"l1": 1.0, "l2": 1.0, "theta": 30.0, "w": 0.05, "E": 1.0, "nu": 0.3, "P1": 0.001,
            "eta": 1.0, "tau": 0.0}[key]  # fmt: skip


def _one_end(rng: random.Random, good: object, bad: object) -> dict:
    return {"from": good, "to": bad} if rng.random() < 0.5 else {"from": bad, "to": good}


def _nonpositive_size(rng: random.Random, scene: dict):
    bad = rng.choice([0, 0.0, -0.0, -1, -_magnitude(rng), -_magnitude(rng, -12, -6)])
    choices = [("tissue", k) for k in SCHEMA["tissue"]] + [("cell", k) for k in ("l1", "l2", "w")]
    table, key = rng.choice(choices + [("time", "dt")])
    if table == "cell" and rng.random() < 0.3:
        _set(scene, table, key, _one_end(rng, _valid_value(table, key, scene), bad))
    else:
        _set(scene, table, key, bad)
    return scene, f"{table}.{key}"


def _poisson_ratio(rng: random.Random, scene: dict):
    bad = rng.choice([0.5, 1, 0.5 + _magnitude(rng, -9, 0), 0.5 + _magnitude(rng), -1, -1.0,
                      -1 - _magnitude(rng, -9, 0), -_magnitude(rng, 0.01, 6)])  # fmt: skip
    if rng.random() < 0.3:
        _set(scene, "material", "nu", _one_end(rng, 0.3, bad))
    else:
        _set(scene, "material", "nu", bad)
    return scene, "material.nu"


def _wall_too_thick(rng: random.Random, scene: dict):
    l1, l2 = _magnitude(rng, -1, 0.7), _magnitude(rng, -1, 0.7)
    theta = rng.uniform(2.0, 88.0)
    w_max = _w_max(l1, l2, theta)
    w = w_max * rng.choice([1.0, 1.0 + _magnitude(rng, -9, -1), 1.0 + rng.random(), 3.0])
    scene["cell"] = {"l1": l1, "l2": l2, "theta": theta, "w": w}
    if rng.random() < 0.3 and w_max > 0.02:  # a w field, thick enough at one end only
        scene["cell"]["w"] = _one_end(rng, 0.5 * w_max, w)
    return scene, "cell.w"


def _angle(rng: random.Random, scene: dict):
    bad = rng.choice([0, 0.0, -_magnitude(rng, -6, 3), 90, 90.0, 90 + _magnitude(rng, -6, 3),
                      180, 360.0, -90])  # fmt: skip
    value = bad if rng.random() < 0.7 else _one_end(rng, 30.0, bad)
    _set(scene, "cell", "theta", value)
    return scene, "cell.theta"


def _time_steps(rng: random.Random, scene: dict):
    dt = rng.choice([_magnitude(rng, -3, 2), rng.choice([0.1, 0.25, 0.5, 1, 2, 3])])
    what = rng.choice(["short", "fraction", "zero", "too_many"])
    if what == "short":
        t_max = dt * rng.uniform(0.01, 0.99)
    elif what == "fraction":
        t_max = dt * (rng.randint(1, 100) + rng.uniform(0.05, 0.95))
    elif what == "zero":
        t_max = rng.choice([0, 0.0, -dt])
    else:
        t_max = dt * rng.uniform(1.01e6, 1e9)
    scene["time"] = {"t_max": t_max, "dt": dt}
    return scene, "time.t_max"


def _out_of_range(rng: random.Random, scene: dict):
    what = rng.choice(["E", "P1", "eta", "tau", "clamp", "key_tolerance", "cell_resolution",
                       "Fg0", "h_big", "H_small", "h_tiny", "micro_resolution",
                       "every", "macro_threshold", "macro_rtol"])  # fmt: skip
    table, key, value = {
        "E": ("material", "E", rng.choice([0, -_magnitude(rng), 1e13])),
        "P1": ("pressure", "P1", -_magnitude(rng)),
        "eta": ("growth", "eta", -_magnitude(rng)),
        "tau": ("growth", "tau", -_magnitude(rng)),
        "clamp": ("growth", "clamp", rng.choice([0, -_magnitude(rng), 2e12])),
        "key_tolerance": ("accuracy", "key_tolerance", rng.choice([0, 0.5, -1e-6, 1.0])),
        "cell_resolution": ("accuracy", "cell_resolution", rng.choice([0, -1, 65, 1000])),
        "Fg0": ("growth", "Fg0", rng.choice([[[0, 0], [0, 0]], [[1, 0], [0, -1]],
                                             [[1, 2], [1, 2]], [[2e6, 0], [0, 1]]])),
        "h_big": ("tissue", "h", 20.0),  # > min(width, height) / 2 with the fixed tissue below
        "H_small": ("tissue", "H", 0.05),  # < h
        "h_tiny": ("tissue", "h", 1e-4),  # far more than 4e6 triangles
        "micro_resolution": ("micro", "resolution", rng.choice([0, -2, 65])),
        "every": ("output", "every", rng.choice([0, -1, 10**6 + 1])),
        "macro_threshold": ("solver", "macro_threshold", rng.choice([-1, -200000, 10**9 + 1])),
        "macro_rtol": ("solver", "macro_rtol", rng.choice([0, -1e-7, 1e-15, 1e-3, 1.0])),
    }[what]  # fmt: skip
    if table == "tissue":
        scene["tissue"] = {"width": 8.0, "height": 4.0, "h": 0.1, "H": 1.0}
    _set(scene, table, key, value)
    return scene, f"{table}.{key}"


def _huge(rng: random.Random, scene: dict):
    big = rng.choice([Raw("1e300"), Raw("-1e300"), Raw("1.7976931348623157e308"),
                      Raw("1" + "0" * 400), Raw("-1" + "0" * 400), Raw("1e309"),
                      Raw(str(rng.randint(10**20, 10**30)))])  # fmt: skip
    where = rng.choice(["float", "field", "int", "loads", "Fg0"])
    if where == "float":
        table, key = rng.choice(_pairs(FLOAT_KEYS))
        value = big
    elif where == "field":
        table, key = rng.choice(_pairs(FIELD_KEYS))
        value = big if rng.random() < 0.7 else Raw(f"{{from = {big}, to = 1}}")
    elif where == "int":
        table, key = rng.choice(_pairs(INT_KEYS))
        value = big
    elif where == "loads":
        scene.pop("model", None)
        table, key = "loads", rng.choice(SCHEMA["loads"])
        value = Raw(f"[{big}, 0]")
    else:
        table, key = "growth", "Fg0"
        value = Raw(f"[[{big}, 0], [0, 1]]")
    _set(scene, table, key, value)
    return scene, f"{table}.{key}"


def _bad_field(rng: random.Random, scene: dict):
    table, key = rng.choice(_pairs(FIELD_KEYS))
    good = _valid_value(table, key, scene)
    value = rng.choice([
        Raw("{}"), Raw(f"{{from = {good!r}}}"), Raw(f"{{to = {good!r}}}"),
        Raw(f'{{from = "a", to = {good!r}}}'), Raw(f"{{from = {good!r}, to = [1]}}"),
        Raw(f"{{from = {good!r}, to = true}}"), Raw(f"{{from = {good!r}, to = {{x = 1}}}}"),
        Raw("{from = 1, to = 2, by = 3}"), Raw(f"{{start = {good!r}, end = {good!r}}}"),
    ])  # fmt: skip
    if rng.random() < 0.2:  # a field where only numbers are allowed
        table, key = rng.choice(_pairs(FLOAT_KEYS))
        value = Raw("{from = 1, to = 2}")
    _set(scene, table, key, value)
    return scene, f"{table}.{key}"


def _bad_loads(rng: random.Random, scene: dict):
    scene["model"] = "macro"
    what = rng.choice(["bottom", "unknown", "shape", "type"])
    loads = scene.setdefault("loads", {})
    if not isinstance(loads, dict):
        loads = scene["loads"] = {}
    if what == "bottom":
        loads["bottom"] = [rng.uniform(-1, 1), rng.uniform(-1, 1)]
        return scene, "loads.bottom"
    if what == "unknown":
        name = _name(rng, SCHEMA["loads"] + ("bottom",))
        loads[name] = [0.0, 0.001]
        return scene, f"loads.{name}"
    edge = rng.choice(SCHEMA["loads"])
    loads[edge] = Raw(rng.choice(["[1.0]", "[1, 2, 3]", "[]"]) if what == "shape" else
                      rng.choice(["1.0", '"up"', '["a", 1]', "{x = 1}", "[true, 0]"]))  # fmt: skip
    return scene, f"loads.{edge}"


BAD_SYNTAX = [  # malformed expressions: each a named error with its position
    "x1 +", "(x1", "x1)", "x1 + y", "__import__('os')", "x1.real", "2x1", "sin(x1, x2)",
    "where(x1, 1)", "max(x1)", "1 < x1 < 2", "", "  ", "exp", "lambda: 0", "x1 = 1",
    "open('f')", "[x1]", "1 +* 2", "x1 ** ", "x1 $ 2", "1" * 1001, "(" * 80 + "x1" + ")" * 80,
    "-" * 80 + "x1", "s + 1", "os.system('true')", "x1 if x2 else 1", "{x1}",
]  # fmt: skip
INTERIOR = [  # valid expressions whose values leave the key's range inside the tissue
    ("material", "nu", "where(x1 > 0.5, 0.6, 0.3)"),
    ("material", "E", "1 - x1"),
    ("pressure", "P1", "0.001 * log(x1 - 0.5)"),
    ("growth", "eta", "where(x2 > 0.2, -1, 1)"),
    ("growth", "tau", "0.001 / (x1 - x1)"),
    ("cell", "w", "where(x1 > 0.5, 5, 0.02)"),
    ("cell", "theta", "30 + 100 * x1"),
]


def _bad_expression(rng: random.Random, scene: dict):
    """Expression fields, Fg0 entries and loads: malformed, or valid but out of range at some
    place the run uses (coarse node, fine cell, cell centre), or unbalanced along an edge."""
    what = rng.choice(["syntax", "syntax", "not_string", "mixed", "interior", "interior",
                       "Fg0", "load_syntax", "load_unbalanced", "load_nan"])  # fmt: skip
    if what == "interior":
        scene.pop("loads", None)  # so that compare reaches the field check
        table, key, text = rng.choice(INTERIOR)
        _set(scene, table, key, {"expr": text})
        return scene, f"{table}.{key}"
    if what == "Fg0":
        scene.pop("loads", None)
        scene.setdefault("growth", {})["Fg0"] = [[{"expr": "where(x1 > 0.5, -1, 1)"}, 0], [0, 1]]
        return scene, "growth.Fg0"
    if what.startswith("load"):
        scene["model"] = "macro"
        edge, i, pair = rng.choice(SCHEMA["loads"]), rng.randint(0, 1), [0.0, 0.0]
        if what == "load_unbalanced":
            pair[0] = {"expr": "1e-4 * (1 + s)"}
            scene["loads"] = {edge: pair}
            return scene, "loads: net x1 force"
        pair[i] = {"expr": rng.choice(BAD_SYNTAX[:12] + ["x1 + s"])}
        if what == "load_nan":
            pair[i] = {"expr": "log(s - 1)"}
        scene["loads"] = {edge: pair}
        return scene, f"loads.{edge}[{i}]"
    table, key = rng.choice(_pairs(FIELD_KEYS))
    value = {
        "syntax": {"expr": rng.choice(BAD_SYNTAX)},
        "not_string": {"expr": rng.choice([1.5, True, [1]])},
        "mixed": {"expr": "1", "from": 1},
    }[what]
    _set(scene, table, key, value)
    return scene, f"{table}.{key}" + (".expr" if what != "mixed" else "")


def _micro_scene(rng: random.Random, scene: dict):
    scene = base_scene(rng, micro=True)
    what = rng.choice(["field", "field", "loads", "nx_odd", "nx_range", "resolution", "size"])
    if what == "size":  # the micro tissue is micro.nx cells wide: width and height are not used
        key = rng.choice(["width", "height"])
        scene.setdefault("tissue", {})[key] = rng.uniform(1.0, 10.0)
        return scene, f"tissue.{key}"
    if what == "field":
        key = rng.choice(["l1", "l2", "theta", "w"])
        scene["cell"] = {"l1": 1.0, "l2": 1.0, "theta": 30.0, "w": 0.05}
        ends = {"l1": (0.8, 1.5), "l2": (0.8, 1.5), "theta": (20.0, 40.0), "w": (0.03, 0.08)}
        lo, hi = ends[key]
        scene["cell"][key] = {"from": rng.uniform(lo, hi), "to": rng.uniform(lo, hi) + 1e-3}
        return scene, f"cell.{key}"
    if what == "loads":
        scene["loads"] = {rng.choice(SCHEMA["loads"]): [0.001, rng.uniform(-1, 1)]}
        return scene, "loads"
    scene.setdefault("micro", {})
    if what == "nx_odd":
        scene["micro"]["nx"] = 2 * rng.randint(0, 500) + 1
        return scene, "micro.nx"
    if what == "nx_range":
        scene["micro"]["nx"] = rng.choice([0, -2, 1026, 2048, 10**6])
        return scene, "micro.nx"
    scene["micro"]["resolution"] = rng.choice([0, -1, 65, 2.0])
    return scene, "micro.resolution"


def _bad_choice(rng: random.Random, scene: dict):
    what = rng.choice(["model", "law", "integrator", "preset", "precision", "solver", "fields",
                       "fields_dup"])  # fmt: skip
    if what == "model":
        scene["model"] = rng.choice(["mezzo", "Macro", "", _name(rng, ("macro", "micro", "both"))])
        return scene, "model ="
    if what == "law":
        scene.setdefault("growth", {})["law"] = rng.choice(["Stress", "", "linear", _name(rng)])
        return scene, "growth.law"
    if what == "integrator":
        scene.setdefault("time", {})["integrator"] = rng.choice(["rk4", "Exp", "", _name(rng)])
        return scene, "time.integrator"
    if what == "preset":
        scene.setdefault("accuracy", {})["preset"] = rng.choice(
            ["fast", "Fine", "", _name(rng, ("draft", "balanced", "fine"))]
        )
        return scene, "accuracy.preset"
    if what == "precision":
        bad = rng.choice(["double", "Float32", "float16", "", _name(rng, ("float32", "float64"))])
        scene.setdefault("output", {})["precision"] = bad
        return scene, "output.precision"
    if what == "solver":
        bad = rng.choice(["LU", "cg", "Auto", "", _name(rng, ("auto", "direct", "iterative"))])
        scene.setdefault("solver", {})["macro"] = bad
        return scene, "solver.macro"
    name = rng.choice(OUTPUT_FIELDS)
    typos = ["p", "U", "sigma", "E", "trg", "tr_G", "anisotropy", "growth_dir", "direction"]
    bad = [name, name] if what == "fields_dup" else [name, rng.choice(typos)]
    scene["output"] = {"fields": bad}
    return scene, "output.fields"


OUTLINE = [[0.0, 0.0], [6.0, 0.0], [6.0, 2.0], [3.0, 4.0], [0.0, 2.0]]
"""A valid outline whose box (6 x 4) fits every base scene's h and H."""
SQUARE_GROUPS = {"pinned": (1,), "symmetry": (1, 2), "top": (3, 4)}
"""The groups of a valid :func:`square_msh` (2 x 2: fits every base scene's h and H)."""


def _on_shape(scene: dict, **shape: object) -> dict:
    """The macro scene on a tissue shape: no width, height or (rectangle) loads."""
    tissue = scene.get("tissue") if isinstance(scene.get("tissue"), dict) else {}
    scene["tissue"] = {k: v for k, v in tissue.items() if k in ("h", "H")} | shape
    scene.pop("loads", None)
    scene["model"] = "macro"
    return scene


def _bad_outline(rng: random.Random, scene: dict):
    what = rng.choice(["bow_tie", "no_bottom", "below", "few", "type", "point", "nonfinite",
                       "repeat", "with_size", "symmetry_load", "unknown", "micro"])  # fmt: skip
    points = [list(p) for p in OUTLINE]
    scene = _on_shape(scene, outline=points)
    k = rng.randrange(len(points))
    if what == "bow_tie":
        a, b = rng.uniform(2.0, 8.0), rng.uniform(2.0, 8.0)
        scene["tissue"]["outline"] = [[0.0, 0.0], [a, 0.0], [0.0, b], [a, b]]
        return scene, ("tissue.outline: edges", "intersect")
    if what == "no_bottom":
        lift = rng.choice([1e-9, 0.5, 3.0])
        scene["tissue"]["outline"] = [[x, y + lift] for x, y in points]
        return scene, ("tissue.outline: no edge lies on x2 = 0",)
    if what == "below":
        points[k][rng.randrange(2)] = -rng.choice([1e-9, 0.5, _magnitude(rng)])
        return scene, ("tissue.outline[",)
    if what == "few":
        scene["tissue"]["outline"] = points[: rng.randint(0, 2)]
        return scene, ("tissue.outline: expected an array",)
    if what == "type":
        scene["tissue"]["outline"] = Raw(rng.choice(['"abc"', "3", "{x = 1}", "true"]))
        return scene, ("tissue.outline: expected an array",)
    if what == "point":
        points[k] = Raw(rng.choice(["[1.0]", "[1, 2, 3]", '"a"', "{x = 1}"]))
        return scene, (f"tissue.outline[{k}]",)
    if what == "nonfinite":
        points[k][1] = Raw(rng.choice(["nan", "inf", "-inf", "1e400"]))
        return scene, (f"tissue.outline[{k}][1]",)
    if what == "repeat":
        points.insert(k, list(points[k]))
        return scene, ("tissue.outline[", "are the same point")
    if what == "with_size":
        key = rng.choice(["width", "height"])
        scene["tissue"][key] = rng.uniform(1.0, 5.0)
        return scene, (f"tissue.{key}: not with tissue.outline",)
    if what == "symmetry_load":
        scene["loads"] = {"edge0": [0.0, 0.001]}
        return scene, ("loads.edge0", "symmetry plane")
    if what == "unknown":
        edge = rng.choice(["left", "right", "top", "bottom", "edge5", "edge-1", _name(rng)])
        scene["loads"] = {edge: [0.0, 0.001]}
        return scene, (f"loads.{edge}",)
    scene["model"] = rng.choice(["micro", "both"])
    return scene, ("tissue.outline: the micro model",)


def _bad_mesh(rng: random.Random, scene: dict):
    what = rng.choice(["missing", "suffix", "garbage", "no_pinned", "no_symmetry", "off_axis",
                       "type", "with_outline", "symmetry_load", "micro"])  # fmt: skip
    scene = _on_shape(scene, mesh="tissue.msh")
    valid = [("tissue.msh", square_msh(SQUARE_GROUPS))]
    if what == "missing":
        return scene, ("tissue.mesh = ", "file not found"), []
    if what == "suffix":
        scene["tissue"]["mesh"] = "tissue.stl"
        return scene, ("tissue.mesh = ", "not a .msh file"), [("tissue.stl", "solid\n")]
    if what == "garbage":
        text = "".join(rng.choices(string.ascii_letters + " \n$", k=rng.randint(0, 300)))
        return (
            scene,
            ("tissue.mesh = ", "gmsh"),
            [("tissue.msh", rng.choice(["", "$Nodes\n"]) + text)],
        )
    groups = dict(SQUARE_GROUPS)
    if what in ("no_pinned", "no_symmetry", "off_axis"):
        expect = {"no_pinned": "no point group 'pinned'", "no_symmetry": "no curve group",
                  "off_axis": "is not on x2 = 0"}[what]  # fmt: skip
        if what == "off_axis":
            groups["symmetry"] = rng.choice([(3, 4), (2, 3), (4, 1)])
        else:
            groups.pop(what[3:])
        return scene, ("tissue.mesh = ", expect), [("tissue.msh", square_msh(groups))]
    if what == "type":
        scene["tissue"]["mesh"] = Raw(rng.choice(["3", "true", "[1]", "{x = 1}"]))
        return scene, ("tissue.mesh: expected a string",), valid
    if what == "with_outline":
        scene["tissue"]["outline"] = OUTLINE
        return scene, ("tissue.mesh: not with tissue.outline",), valid
    if what == "symmetry_load":
        scene["loads"] = {"symmetry": [0.0, 0.001]}
        return scene, ("loads.symmetry", "symmetry plane"), valid
    scene["model"] = rng.choice(["micro", "both"])
    return scene, ("tissue.mesh: the micro model",), valid


RESERVED_NAMES = ("x1", "x2", "s", "pi", "exp", "log", "sqrt", "sin", "cos", "tanh", "abs",
                  "min", "max", "where")  # fmt: skip
BAD_NAMES = ("2x", "a-b", "-x", "9", "x" * 65)  # TOML bare keys, not names an expression reads


def _bad_region(rng: random.Random, scene: dict):
    """``[regions]``: malformed conditions, not a {expr} table, a bad name, a condition that is 0
    everywhere, or one that is empty or undefined (NaN) at every growth unit of the mesh."""
    what = rng.choice(["syntax", "syntax", "not_table", "extra_key", "name", "zero", "empty",
                       "empty", "nan", "not_string"])  # fmt: skip
    name = rng.choice(["disc", "band", "r1", "_inner"])
    if what in ("empty", "nan"):  # found on the mesh: the scene must reach its place checks
        scene.pop("loads", None)
        text = "x1 > 1e7" if what == "empty" else "log(x1 - 1e7)"
        scene["regions"] = {name: {"expr": text}}
        fragment = "the region is empty" if what == "empty" else "expr = nan at x1 ="
        return scene, (f"regions.{name}", fragment)
    value: object = {
        "syntax": {"expr": rng.choice(BAD_SYNTAX)},
        "not_table": rng.choice(["x1 < 1", 1.0, True, [1]]),
        "extra_key": {"expr": "x1 < 1", rng.choice(["from", "to", "where"]): 1},
        "zero": {"expr": rng.choice(["0", "2 < 1", "0 * pi", "1 - 1"])},
        "not_string": {"expr": rng.choice([1.5, True, [1]])},
        "name": {"expr": "x1 < 1"},
    }[what]
    if what == "name":
        name = rng.choice(BAD_NAMES)
    scene["regions"] = {name: value}
    return scene, f"regions.{name}"


def _bad_parameter(rng: random.Random, scene: dict):
    """``[parameters]``: a name an expression uses that no parameter defines (in a field, a load
    or a region), a parameter shadowing x1, x2, s, pi or a function, a bad name or value."""
    what = rng.choice(["undefined", "undefined", "undefined_load", "undefined_region",
                       "shadow", "shadow", "name", "value", "nonfinite", "not_table"])  # fmt: skip
    scene["parameters"] = {"E_in": rng.uniform(0.2, 0.9)}
    unknown = rng.choice(["E_out", "e_in", "Ein", _name(rng, ("E_in",)).replace("-", "_")])
    if what == "undefined":
        table, key = rng.choice(_pairs(FIELD_KEYS))
        _set(scene, table, key, {"expr": f"where(x1 < 1, E_in, {unknown})"})
        return scene, (f"{table}.{key}.expr", f"unknown name '{unknown}'")
    if what == "undefined_load":
        scene["model"] = "macro"
        scene["loads"] = {"left": [{"expr": f"-{unknown} * s"}, 0.0]}
        return scene, ("loads.left[0].expr", f"unknown name '{unknown}'")
    if what == "undefined_region":
        scene["regions"] = {"disc": {"expr": f"x1 < {unknown}"}}
        return scene, ("regions.disc.expr", f"unknown name '{unknown}'")
    if what == "shadow":
        name = rng.choice(RESERVED_NAMES)
        scene["parameters"][name] = 1.0
        return scene, (f"parameters.{name}", "reserved")
    if what == "name":
        name = rng.choice(BAD_NAMES)
        scene["parameters"][name] = 1.0
        return scene, f"parameters.{name}"
    if what == "value":
        scene["parameters"]["E_in"] = rng.choice(["0.3", True, [0.3], {"expr": "1"}])
        return scene, "parameters.E_in"
    if what == "nonfinite":
        scene["parameters"]["E_in"] = rng.choice([math.nan, math.inf, -math.inf, 1e13])
        return scene, "parameters.E_in ="
    scene["parameters"] = rng.choice([1.0, "E_in = 1", [1.0]])
    return scene, "parameters: expected a table"


def _bad_supports(rng: random.Random, scene: dict):
    """``[supports]``: an edge the tissue does not have, an edge also loaded, an unknown kind, a
    roller on an inclined outline edge, supports in a micro scene."""
    what = rng.choice(["edge", "edge", "loaded", "loaded", "kind", "kind", "inclined", "micro"])
    scene["model"] = "macro"
    sides = ("left", "right", "top", "bottom")
    if what == "edge":
        edge = rng.choice(["front", "Left", "edge0", "symmetry", _name(rng, sides)])
        scene["supports"] = {edge: rng.choice(["clamped", "roller"])}
        return scene, f"'supports.{edge}'"
    if what == "loaded":
        edge = rng.choice(SCHEMA["loads"])
        scene["loads"] = {edge: [0.0, rng.choice([0.0, 0.001])]}  # x2 only: balanced
        scene["supports"] = {edge: rng.choice(["clamped", "roller"])}
        return scene, (f"supports.{edge}", "is also loaded")
    if what == "kind":
        edge = rng.choice(sides)
        scene["supports"] = {edge: rng.choice(
            ["fixed", "Clamped", "pinned", "", "free", _name(rng, ("clamped", "roller")),
             Raw("1"), Raw("true"), Raw('["clamped"]'), Raw("{kind = 'roller'}")]
        )}  # fmt: skip
        return scene, f"supports.{edge}"
    if what == "inclined":  # OUTLINE's edges 2 and 3 are inclined
        scene = _on_shape(scene, outline=[list(p) for p in OUTLINE])
        edge = rng.choice(["edge2", "edge3"])
        scene["supports"] = {edge: "roller"}
        return scene, (f"supports.{edge}", "parallel to neither")
    scene = base_scene(rng, micro=True)
    scene["supports"] = {rng.choice(sides): "clamped"}
    return scene, ("supports: the micro model",)


FIBRE_INTERIOR = [  # valid expressions whose values leave the key's range inside the tissue
    ("fibre_stiffness", "x1 - 1e7"),
    ("fibre_stiffness", "where(x2 > 0.2, -1, 1)"),
    ("fibre_angle", "1e7 * (x1 + 1)"),
    ("fibre_angle", "log(x1 - 1e7)"),
]
CUE_TYPOS = ["Stress", "stresses", "curvature", "", "strain ", Raw("1"), Raw("true"),
             Raw('["stress"]')]  # fmt: skip


def _bad_fibres(rng: random.Random, scene: dict):
    """``[walls]`` and ``[feedback]``: wrong types, NaN/inf, a negative fibre_stiffness, an
    angle beyond 1e6 degrees, an unknown cue, a bad rate, missing keys, feedback without fibres,
    a fibre angle without fibre_stiffness (or the reverse), an expression out of range inside
    the tissue and the output field fibre_direction without a director."""
    what = rng.choice(["wrong_type", "nonfinite", "negative", "huge_angle", "cue", "rate",
                       "missing", "no_fibres", "angle_alone", "stiffness_alone", "interior",
                       "field_alone"])  # fmt: skip
    scene.pop("loads", None)  # so that compare reaches the fibre checks
    walls: dict = {"fibre_stiffness": rng.uniform(0.1, 5.0), "fibre_angle": rng.uniform(-90, 90)}
    feedback: dict = {"cue": rng.choice(["stress", "strain"]), "rate": rng.uniform(0.0, 2.0)}
    key = rng.choice(("fibre_stiffness", "fibre_angle"))
    expect: tuple[str, ...] = (f"walls.{key}",)
    if what == "wrong_type":
        walls[key] = Raw(rng.choice(WRONG_FOR_NUMBER))
    elif what == "nonfinite":
        walls[key] = Raw(rng.choice(NONFINITE))
        expect = (f"walls.{key} =", "finite")
    elif what == "negative":
        bad = rng.choice([-1e-12, -1.0, -_magnitude(rng)])
        walls["fibre_stiffness"] = rng.choice([bad, _one_end(rng, 1.0, bad)])
        expect = ("walls.fibre_stiffness", "[0, ")
    elif what == "huge_angle":
        walls["fibre_angle"] = rng.choice([1, -1]) * rng.uniform(1.0001e6, 1e12)
        expect = ("walls.fibre_angle =", "[-1e+06, 1e+06]")
    elif what == "interior":
        key, text = rng.choice(FIBRE_INTERIOR)
        walls[key] = {"expr": text}
        expect = (f"walls.{key} =", "at x1 =")
    elif what == "angle_alone":
        walls.pop("fibre_stiffness")
        expect = ("walls.fibre_stiffness is required",)
    elif what == "stiffness_alone":
        walls.pop("fibre_angle")
        expect = ("walls.fibre_angle is required",)
    if what in ("cue", "rate", "missing", "no_fibres"):
        scene["feedback"] = feedback
    if what == "cue":
        feedback["cue"] = rng.choice(CUE_TYPOS)
        expect = ("feedback.cue",)
    elif what == "rate":
        feedback["rate"] = rng.choice([-1e-9, -1.0, Raw("nan"), Raw("-inf"), Raw('"fast"'),
                                       {"from": 0.0, "to": 1.0}, Raw("[1]")])  # fmt: skip
        expect = ("feedback.rate",)
    elif what == "missing":
        name = rng.choice(["cue", "rate"])
        feedback.pop(name)
        expect = (f"feedback.{name} is required",)
    elif what == "no_fibres":
        walls = rng.choice([{}, {"fibre_stiffness": 0.0}])
        expect = ("feedback:", "no fibres")
    elif what == "field_alone":
        walls = rng.choice([{}, {"fibre_stiffness": 0.0, "fibre_angle": walls["fibre_angle"]}])
        scene.setdefault("output", {})["fields"] = ["u", "fibre_direction"]
        expect = ("output.fields", "fibre_direction")
    if walls:
        scene["walls"] = walls
    return scene, expect


FIELD_WORDS = {  # an [output] field as a new user names it -> the field the error suggests
    "stress": "sigma_hom", "Stress": "sigma_hom", "strain": "eps_hom", "growth": "G",
    "displacement": "u", "fibres": "fibre_direction", "sigma_hm": "sigma_hom", "trg": "trG",
    "fibre_directon": "fibre_direction", "growth_anisotropie": "growth_anisotropy",
    "elastic_strian": "elastic_strain",
}  # fmt: skip


def _field_name(rng: random.Random, scene: dict):
    """An [output] field named by a synonym or a near miss (the error suggests the field it
    may mean), or cue_anisotropy in a scene without [feedback]."""
    if rng.random() < 0.2:
        scene["output"] = {"fields": ["u", "cue_anisotropy"]}
        return scene, ("output.fields", "cue_anisotropy", "no [feedback]")
    word, meant = rng.choice(list(FIELD_WORDS.items()))
    scene["output"] = {"fields": ["u", word]}
    return scene, ("output.fields[1]", "did you mean", f"'{meant}'")


FEEDBACK_WALLS_TYPOS = ["Around", "own ", "both", "halves", "", Raw("1"), Raw("true"),
                        Raw('["around"]'), Raw('{walls = "own"}')]  # fmt: skip


def _bad_feedback_walls(rng: random.Random, scene: dict):
    """``feedback.walls`` (which walls the micro cue averages) neither "around" nor "own": a
    named error listing both, in any scene with valid fibres and feedback."""
    scene.pop("loads", None)  # so that compare reaches the feedback checks
    scene["walls"] = {"fibre_stiffness": rng.uniform(0.1, 5.0), "fibre_angle": rng.uniform(-90, 90)}
    scene["feedback"] = {"cue": rng.choice(["stress", "strain"]), "rate": rng.uniform(0.0, 2.0),
                         "walls": rng.choice(FEEDBACK_WALLS_TYPOS)}  # fmt: skip
    return scene, ("feedback.walls", "'around', 'own'")


def _bad_hydraulics(rng: random.Random, scene: dict):
    """``[hydraulics]`` (docs/model.md, water fluxes): wrong types, NaN/inf, a negative osmotic
    pressure or conductivity, a missing conductivity, pressure.P1 given as well, a supply on the
    symmetry plane, on an edge or region the scene does not have, twice, without or with a
    non-positive conductance, a bad potential in time, a valid table with the adaptive
    integrator at a tolerance out of range (every model and integrator takes water fluxes), the
    macro model's water fields asked of the micro model, and a bad micro.nx (the cells' size)
    in a macro water scene."""
    what = rng.choice(["wrong_type", "nonfinite", "negative", "missing", "P1", "bottom", "edge",
                       "region", "twice", "conductance", "times", "fields",
                       "cell_size", "adaptive"])  # fmt: skip
    scene = base_scene(rng, micro=True)
    scene["model"] = "micro"
    scene.pop("pressure", None)
    table: dict = {"osmotic": rng.uniform(0.0, 0.01), "conductivity": rng.uniform(0.0, 10.0)}
    supply: dict = {"edge": rng.choice(["left", "right", "top"]),
                    "conductance": rng.uniform(0.1, 10.0)}  # fmt: skip
    expect: tuple[str, ...]
    if what in ("wrong_type", "nonfinite", "negative"):
        key = rng.choice(["osmotic", "conductivity"])
        table[key] = Raw(rng.choice(
            {"wrong_type": WRONG_FOR_NUMBER, "nonfinite": NONFINITE,
             "negative": ["-1e-9", "-1.0", "{from = 1.0, to = -1.0}"]}[what]
        ))  # fmt: skip
        expect = (f"hydraulics.{key}",)
    elif what == "missing":
        table.pop("conductivity")
        expect = ("hydraulics.conductivity is required",)
    elif what == "P1":
        scene["pressure"] = {"P1": rng.uniform(0.0, 0.01)}
        expect = ("pressure.P1: not with [hydraulics]",)
    elif what == "bottom":
        supply["edge"] = "bottom"
        expect = ("hydraulics.supply[0].edge = 'bottom'", "symmetry plane")
    elif what == "edge":
        supply["edge"] = rng.choice(
            ["Left", "front", "edge0", _name(rng, ("left", "right", "top", "bottom"))]
        )
        expect = (f"hydraulics.supply[0].edge = {supply['edge']!r}",)
    elif what == "region":
        supply = {"region": rng.choice(["strand", "disc"]), "conductance": 1.0}
        expect = ("hydraulics.supply[0].region",)
    elif what == "twice":
        table["supply"] = [supply, dict(supply)]
        expect = ("hydraulics.supply[1].edge", "supplied twice")
    elif what == "conductance":
        supply["conductance"] = Raw(rng.choice(["0", "-1.0", "nan", '"high"']))
        expect = ("hydraulics.supply[0].conductance",)
    elif what == "times":
        supply["potential"] = rng.choice([
            {"times": [0.0, 10.0]}, {"times": [0.0, 10.0], "values": [0.0]},
            {"times": [10.0, 0.0], "values": [0.0, -1e-3]},
            {"times": [0.0, 10.0], "values": [0.0, -1e-3], "interpolation": "cubic"},
        ])  # fmt: skip
        expect = ("hydraulics.supply[0].potential",)
    elif what == "cell_size":  # a macro water scene's cells are micro.nx's (4 / nx x [cell])
        scene["model"], scene["kinematics"] = "macro", "linear"
        scene["time"] = {"t_max": 2.0, "dt": 1.0}
        scene.setdefault("micro", {})["nx"] = rng.choice([0, 3, 17, 258, 1024, -2])
        expect = ("micro.nx",)
    elif what == "fields":  # the water fields are the macro model's
        scene["output"] = {"fields": ["u", rng.choice(["P", "psi", "water_flux"])]}
        expect = ("output.fields", "macro model's water fields")
    else:
        tolerance = rng.choice([0.0, -1e-3, 0.5])
        scene["time"] = {"t_max": 2.0, "dt": 1.0, "integrator": "adaptive", "tolerance": tolerance}
        expect = ("time.tolerance",)
    table.setdefault("supply", [supply])
    scene["hydraulics"] = table
    return scene, expect


# --- [tissue] cells: the generator's key, label images and polygon tables (issue 34) ------------


def label_grid(rows: int = 3, cols: int = 4, size: int = 8, margin: int = 2) -> np.ndarray:
    """A valid label image: rows x cols square cells of size x size pixels, labels 1.. row by
    row, background ``margin`` pixels wide around them."""
    out = np.zeros((rows * size + 2 * margin, cols * size + 2 * margin), dtype=np.int32)
    for r in range(rows):
        for c in range(cols):
            out[margin + r * size : margin + (r + 1) * size,
                margin + c * size : margin + (c + 1) * size] = 1 + r * cols + c  # fmt: skip
    return out


def _with(image: np.ndarray, where: tuple, value: object) -> np.ndarray:
    image = image.copy()
    image[where] = value
    return image


BAD_IMAGES = {  # name -> (image, a fragment of the error); the grid's cell 1 is at rows 2-9
    "3D": (np.stack([label_grid(), label_grid()]), "a 3D image of shape"),
    "RGB": (np.stack([label_grid()] * 3, axis=-1).astype(np.uint8), "an RGB(A) image"),
    "mask": (label_grid() > 0, "a binary mask"),
    "fraction": (_with(label_grid().astype(np.float32), (5, 5), 2.5), "a non-integer label 2.5"),
    "negative": (_with(label_grid(), (5, 5), -3), "a negative label -3 at column 5, row 5"),
    "no_background": (label_grid(margin=0), "no background"),
    "no_cells": (np.zeros((20, 20), np.uint8), "no cells"),
    "split": (_with(label_grid(), (slice(18, 26), slice(18, 26)), 2), "label 2 is split into 2"),
    "one_pixel": (_with(label_grid(), (1, 5), 99), "cell 99 has 1 pixels"),  # in the margin
    "small": (_with(label_grid(), (slice(0, 3), slice(4, 7)), 99), "cell 99 has 9 pixels"),
    "hole": (_with(label_grid(), (slice(4, 6), slice(4, 6)), 0), "cell 1 has a hole (background"),
    "island": (_with(label_grid(), (slice(3, 8), slice(3, 8)), 99), "cell 1 has a hole (cell 99"),
    "enclosed": (_with(label_grid(), (slice(9, 11), slice(9, 11)), 0), "enclosed by the tissue"),
}
SQUARE = [[0, 0], [1, 0], [1, 1], [0, 1]]
AROUND = [(0, 0), (1, 0), (2, 0), (2, 1), (2, 2), (1, 2), (0, 2), (0, 1)]  # squares round (1, 1)
BAD_TABLES = {  # name -> (JSON table, a fragment of the error)
    "few": ({"cells": [{"id": 1, "vertices": [[0, 0], [1, 0]]}]}, "cell 1: 2 vertices"),
    "nan": ({"cells": [{"id": 1, "vertices": [[0, 0], [1, math.nan], [0, 1]]}]},
            "cell 1: a vertex is not finite"),
    "text": ({"cells": [{"id": 1, "vertices": [[0, 0], [1, "a"], [0, 1]]}]}, "pairs of numbers"),
    "ids": ({"cells": [{"id": 1, "vertices": SQUARE}, {"id": 1, "vertices": SQUARE}]},
            "cell id 1 is repeated"),
    "id_type": ({"cells": [{"id": "a", "vertices": SQUARE}]}, "ids must be integers"),
    "bow_tie": ({"cells": [{"id": 1, "vertices": [[0, 0], [1, 1], [1, 0], [0, 1]]}]},
                "cell 1: its polygon intersects itself"),
    "repeat": ({"cells": [{"id": 1, "vertices": [[0, 0], [1, 0], [1, 0], [0, 1]]}]},
               "cell 1: a vertex is repeated"),
    "overlap": ({"cells": [{"id": 1, "vertices": SQUARE},
                           {"id": 2, "vertices": [[0.5, 0], [1.5, 0], [1.5, 1], [0.5, 1]]}]},
                "cells 1 and 2 overlap"),
    "hole": ({"cells": [{"id": k, "vertices": [[x + i, y + j] for x, y in SQUARE]}
                        for k, (i, j) in enumerate(AROUND)]}, "background enclosed by the tissue"),
    "below": ({"cells": [{"id": 4, "vertices": [[0, -1], [1, 0], [0, 1]]}]},
              "cell 4 reaches x2 = -1 < 0"),
    "unknown_key": ({"cells": [], "units": "um"}, "unknown key 'units'"),
    "empty": ({"cells": []}, "no cells"),
    "pixel_size": ({"cells": [{"id": 1, "vertices": SQUARE}], "pixel_size": -1},
                   "pixel_size = -1 must be a number > 0"),
}  # fmt: skip
BAD_CSV = {  # name -> (CSV text, a fragment of the error)
    "header": ("id,x,y\n1,0,0\n", "expected the header cell_id,x,y"),
    "row": ("cell_id,x,y\n1,0,0\n1,1,zero\n", "line 3: expected cell_id,x,y"),
    "ids": ("cell_id,x,y\n1,0,0\n1,1,0\n1,1,1\n2,2,0\n2,3,0\n2,3,1\n1,0,1\n",
            "cell id 1 is repeated"),
}


def _image_bytes(image: np.ndarray, suffix: str) -> bytes:
    import io

    buffer = io.BytesIO()
    if suffix == ".png":
        from skimage import io as skio

        skio.imsave(buffer, image, format="png", check_contrast=False)
    else:
        import tifffile

        tifffile.imwrite(buffer, image)
    return buffer.getvalue()


def _on_cells(scene: dict, cells: object, **keys: object) -> dict:
    """The scene with ``tissue.cells`` (no width, height or micro.nx, no loads or supports)."""
    tissue = scene.get("tissue") if isinstance(scene.get("tissue"), dict) else {}
    scene["tissue"] = {k: v for k, v in tissue.items() if k in ("h", "H")} | {"cells": cells} | keys
    if isinstance(scene.get("micro"), dict):
        scene["micro"].pop("nx", None)
    scene.pop("loads", None)
    scene.pop("supports", None)
    return scene


def _bad_cells_key(rng: random.Random, scene: dict):
    """``tissue.cells = {voronoi = N, seed = S, regularity = r}`` and its neighbours: N not
    Nx^2/2, r outside [0, 1], a bad seed, an unknown key, another shape or size given too, a
    micro.nx that is not the tissue's, a missing or foreign file, a bad or missing pixel_size."""
    what = rng.choice(["voronoi", "regularity", "seed", "unknown", "type", "with", "nx",
                       "missing", "suffix", "no_pixel_size", "pixel_size"])  # fmt: skip
    good = {"voronoi": rng.choice([2, 8, 32, 72]), "seed": rng.randint(0, 99),
            "regularity": rng.uniform(0.0, 1.0)}  # fmt: skip
    if what in ("voronoi", "regularity", "seed"):
        bad = {"voronoi": [0, 3, 33, 1000, -8, 2.5, True, "32", 2 * 258**2],
               "regularity": [-0.1, 1.5, Raw("nan"), Raw("inf"), "half", True],
               "seed": [-1, 1.5, "one", True, Raw("[1]")]}[what]  # fmt: skip
        return _on_cells(scene, good | {what: rng.choice(bad)}), (f"tissue.cells.{what}",)
    if what == "unknown":
        key = rng.choice(["irregularity", "n", "cells", "Nx"])
        return _on_cells(scene, good | {key: 1}), (f"unknown key 'tissue.cells.{key}'",)
    if what == "type":
        return _on_cells(scene, Raw(rng.choice(["3", "true", "[1, 2]"]))), ("tissue.cells:",)
    if what == "with":
        key = rng.choice(["width", "height", "outline", "mesh"])
        value = {"outline": OUTLINE, "mesh": "tissue.msh"}.get(key, 4.0)
        return _on_cells(scene, good, **{key: value}), (f"tissue.{key}: not with tissue.cells",)
    if what == "nx":
        scene = _on_cells(scene, good)
        nx = math.isqrt(2 * good["voronoi"])
        scene.setdefault("micro", {})["nx"] = rng.choice([n for n in (2, 4, 8, 12, 16) if n != nx])
        return scene, ("micro.nx = ", f"Nx = {nx}")
    if what == "missing":
        name = rng.choice(["cells.tif", "labels.png", "cells.json", "sub/cells.csv"])
        return _on_cells(scene, name, pixel_size=0.1), ("tissue.cells = ", "file not found")
    if what == "suffix":
        name = rng.choice(["cells.jpg", "cells.txt", "cells", "cells.npy"])
        return _on_cells(scene, name), ("tissue.cells = ", "not a label image"), [(name, "x\n")]
    valid = [("cells.tif", _image_bytes(label_grid().astype(np.uint16), ".tif"))]
    if what == "no_pixel_size":
        return _on_cells(scene, "cells.tif"), ("tissue.pixel_size is required",), valid
    size = rng.choice([0, -0.5, Raw("nan"), "1 um", True])
    return _on_cells(scene, "cells.tif", pixel_size=size), ("tissue.pixel_size",), valid


def _bad_label_image(rng: random.Random, scene: dict):
    """A label image (TIFF, or PNG where PNG can hold it) that cannot be a tissue of cells."""
    kind = rng.choice(sorted(BAD_IMAGES))
    image, fragment = BAD_IMAGES[kind]
    integers = image.dtype in (np.uint8, np.uint16, np.int32)
    pngable = image.ndim == 2 and integers and image.min() >= 0  # a grey 16-bit PNG holds it
    suffix = ".png" if pngable and rng.random() < 0.5 else ".tif"
    if suffix == ".png":
        image = image.astype(np.uint16)
    name = f"labels{suffix}"
    scene = _on_cells(scene, name, pixel_size=rng.choice([0.01, 0.1, 0.5]))
    return scene, ("tissue.cells = ", fragment), [(name, _image_bytes(image, suffix))]


def _bad_polygon_table(rng: random.Random, scene: dict):
    """A polygon table (JSON or CSV) that cannot be a tissue of cells."""
    if rng.random() < 0.25:
        text, fragment = BAD_CSV[rng.choice(sorted(BAD_CSV))]
        return _on_cells(scene, "cells.csv"), ("tissue.cells = ", fragment), [("cells.csv", text)]
    table, fragment = BAD_TABLES[rng.choice(sorted(BAD_TABLES))]
    text = json.dumps(table)
    return _on_cells(scene, "cells.json"), ("tissue.cells = ", fragment), [("cells.json", text)]


SCENE_MAKERS = {
    "wrong_type": _wrong_type,
    "missing_required": _missing_required,
    "unknown_key": _unknown_key,
    "nonfinite": _nonfinite,
    "nonpositive_size": _nonpositive_size,
    "poisson_ratio": _poisson_ratio,
    "wall_too_thick": _wall_too_thick,
    "angle": _angle,
    "time_steps": _time_steps,
    "out_of_range": _out_of_range,
    "huge_number": _huge,
    "bad_field": _bad_field,
    "bad_loads": _bad_loads,
    "bad_expression": _bad_expression,
    "micro_scene": _micro_scene,
    "bad_choice": _bad_choice,
    "bad_outline": _bad_outline,
    "bad_mesh": _bad_mesh,
    "bad_region": _bad_region,
    "bad_parameter": _bad_parameter,
    "bad_supports": _bad_supports,
    "bad_fibres": _bad_fibres,
    "field_name": _field_name,
    "bad_feedback_walls": _bad_feedback_walls,
    "bad_hydraulics": _bad_hydraulics,
    "bad_cells_key": _bad_cells_key,
    "bad_label_image": _bad_label_image,
    "bad_polygon_table": _bad_polygon_table,
}

TOML_ERRORS = [
    "[tissue\nh = 0.1\n", '[growth]\nlaw = "stress\n', "[growth]\nlaw = \n",
    "[growth]\nlaw = 'stress'\nlaw = 'strain'\n", "[growth]\nlaw = 'stress'\n[growth]\neta = 1\n",
    "[growth]\nlaw = stress\n", "[cell]\nw = {from = 0.1, to = }\n", "[cell]\nw = 0.05.1\n",
    "= 3\n", "[time]\ndt = 1,\n", "[[growth]\n", "[growth]\nlaw = 'stress'\neta = 1 2\n",
    "[growth]\nlaw = 'stress'\n[cell]\nw = {from = 0.1,\nto = 0.2}\n", "[tissue]]\n",
    "[growth]\nlaw = 'none'\n[micro]\nnx = " + "1" * 5000 + "\n", "model = 'macro\n",
    "[growth]\nlaw = 'stress'\neta = 01\n", "[growth]\nlaw = 'stress'\ntau = .5\n",
    "[growth]\nlaw = 'stress'\n[time]\ndt = 1e\n", "[growth]\nlaw = 'stress'\n[time]\ndt = 0x\n",
]  # fmt: skip


def _file_case(rng: random.Random, cls: str) -> tuple[str | bytes, tuple[str, ...]]:
    if cls == "empty_file":
        content = rng.choice(["", "".join(rng.choices(" \t\n\r", k=rng.randint(1, 200)))])
        return content, (SCENE, "empty")
    if cls == "binary_garbage":
        data = bytearray(rng.randbytes(rng.randint(1, 2000)))
        data.insert(rng.randint(0, len(data)), rng.choice([0x00, 0xFF, 0xC3, 0x80]))
        if rng.random() < 0.3:  # garbage after a valid start
            data = bytearray(b'[growth]\nlaw = "stress"\n') + data
        return bytes(data), (SCENE,)
    # toml_syntax: a fixed broken snippet, or a valid random scene with one line broken
    if rng.random() < 0.5:
        return rng.choice(TOML_ERRORS), (SCENE, "invalid TOML")
    lines = to_toml(base_scene(rng)).splitlines()
    i = rng.choice([k for k, line in enumerate(lines) if "=" in line])
    lines[i] = rng.choice([
        lines[i].replace("=", ""), lines[i] + " }", lines[i] + " = 1", lines[i] + ",",
        "[" + lines[i], lines[i].replace("=", "= = "), lines[i] + ' "', "= " + lines[i],
    ])  # fmt: skip
    return "\n".join(lines) + "\n", (SCENE, "invalid TOML")


TINY = '[growth]\nlaw = "none"\n[tissue]\nh = 0.5\n[accuracy]\ncell_resolution = 1\n'
"""A valid scene that would run in a second: the run behind a bad output path or command line."""
COMPARE = (
    '[tissue]\nh = 0.1\n[growth]\nlaw = "stress"\n[time]\nt_max = 1\ndt = 1\n'
    "[accuracy]\ncell_resolution = 1\n[micro]\nnx = 4\nresolution = 1\n"
)
"""A valid scene for ``compare`` (constant cell, no loads) that runs in about 2 s."""
CELL_OPTIONS = ("--l1", "--l2", "--theta", "--w", "--E", "--nu", "--Fg", "--resolution", "--json")


def _cli_cell(rng: random.Random):
    what = rng.choice(["nu", "Fg_count", "Fg_det", "Fg_text", "w", "w_thick", "theta", "resolution",
                       "E", "l", "nonfinite", "fibre_stiffness", "fibre_angle"])  # fmt: skip
    if what == "nu":
        v = rng.choice([0.5, 0.7, 1.0, 0.5 + _magnitude(rng, -6, 2), -1.0, -1 - _magnitude(rng)])
        return ["--nu", repr(v)], ("nu = ",)
    if what == "Fg_count":
        k = rng.choice([1, 2, 3, 5, 6, 9])
        return ["--Fg", ",".join(repr(round(rng.uniform(-2, 2), 3)) for _ in range(k))], ("--Fg",)
    if what == "Fg_det":
        a, b, c = (round(rng.uniform(0.1, 2), 3) for _ in range(3))
        Fg = rng.choice([[0, 0, 0, 0], [a, b, 2 * a, 2 * b], [a, 0, 0, -c], [-a, 0, 0, c]])
        return ["--Fg", ",".join(map(repr, Fg))], ("Fg = ",)
    if what == "Fg_text":
        return ["--Fg", rng.choice(["a,b,c,d", "1;0;0;1", "", "1,,0,1", "[1,0,0,1]"])], ("--Fg",)
    if what == "w":
        return ["--w", repr(rng.choice([0.0, -1.0, -_magnitude(rng)]))], ("w = ",)
    if what == "w_thick":
        l1, l2, theta = (round(rng.uniform(*r), 3) for r in ((0.3, 3), (0.3, 3), (5, 85)))
        w = _w_max(l1, l2, theta) * rng.uniform(1.0, 3.0)
        argv = ["--l1", repr(l1), "--l2", repr(l2), "--theta", repr(theta), "--w", repr(w)]
        return argv, ("w = ", "no void")
    if what == "theta":
        v = rng.choice([95.0, 90.0, 0.0, -30.0, 90 + _magnitude(rng, -6, 3)])
        return ["--theta", repr(v)], ("theta = ",)
    if what == "resolution":
        return ["--resolution", str(rng.choice([0, -1, -rng.randint(2, 10**6)]))], ("resolution",)
    if what == "E":
        return ["--E", repr(rng.choice([0.0, -1.0, -_magnitude(rng)]))], ("E = ",)
    if what == "fibre_stiffness":  # E_f / E: finite and >= 0
        v = rng.choice([-1.0, -_magnitude(rng), "nan", "inf", "-inf"])
        return ["--fibre-stiffness", str(v)], ("--fibre-stiffness = ",)
    if what == "fibre_angle":  # the director angle: any finite number of degrees
        return ["--fibre-angle", rng.choice(["nan", "inf", "-inf"])], ("--fibre-angle = ",)
    if what == "l":
        opt = rng.choice(["--l1", "--l2"])
        return [opt, repr(rng.choice([0.0, -_magnitude(rng)]))], (opt[2:] + " = ",)
    opt = rng.choice(["--l1", "--l2", "--w", "--E", "--nu", "--theta"])
    return [opt, rng.choice(["nan", "inf", "-inf"])], (opt[2:] + " = ",)


def _cli_case(rng: random.Random, cls: str):
    """(files, argv, expect) of a command-line class."""
    if cls == "cli_cell":
        pairs, expect = _cli_cell(rng)
        argv = ["cell"]
        for opt, value in zip(pairs[::2], pairs[1::2], strict=True):
            # "--w=-1e-05": argparse takes a lone "-1e-05" for an option
            split = not value.startswith("-") and rng.random() < 0.7
            argv += [opt, value] if split else [f"{opt}={value}"]
        return (), argv, expect
    if cls == "cli_compare":
        what = rng.choice(["nx_odd", "nx_odd", "nx_small", "nx_text", "nx_missing", "loads",
                           "resolution", "size"])  # fmt: skip
        files = (("compare.toml", COMPARE),)
        base = ["compare", "{dir}/compare.toml", "--first-step-only", "-o", "{dir}/cmp"]
        if what == "nx_odd":
            nx = [str(2 * rng.randint(1, 4))] * rng.randint(0, 2) + [
                str(2 * rng.randint(0, 50) + 1)
            ]
            return files, [*base, "--nx", *nx], ("--nx",)
        if what == "nx_small":
            return files, [*base, "--nx", str(rng.choice([0, -2, -4]))], ("--nx",)
        if what == "nx_text":
            return files, [*base, "--nx", rng.choice(["4.0", "four", "4,8"])], ("--nx",)
        if what == "nx_missing":
            return files, base, ("--nx",)
        if what == "loads":
            scene = COMPARE + "[loads]\nright = [0.001, 0.0]\n"
            return (("compare.toml", scene),), [*base, "--nx", "4"], ("loads",)
        if what == "size":  # compare builds --nx cells per row: a width would be ignored
            key = rng.choice(["width", "height"])
            scene = COMPARE.replace("[tissue]\n", f"[tissue]\n{key} = {rng.uniform(1, 9)}\n")
            return (("compare.toml", scene),), [*base, "--nx", "4"], (f"tissue.{key}",)
        return (
            files,
            [*base, "--nx", "4", "--resolution", str(rng.choice([0, -1]))],
            ("--resolution",),
        )
    if cls == "cli_run":
        what = rng.choice(["missing", "directory", "resume_empty", "resume_missing", "two_dirs"])
        files = (("tiny.toml", TINY),)
        if what == "missing":
            name = f"{_name(rng)}.toml"
            return (), [rng.choice(["run", "validate"]), f"{{dir}}/{name}"], (name, "not found")
        if what == "directory":
            return (("sub/keep.txt", "x"),), ["run", "{dir}/sub"], ("sub", "directory")
        if what == "resume_empty":
            return (
                (*files, ("old/keep.txt", "x")),
                ["run", "{dir}/tiny.toml", "--resume", "{dir}/old"],
                ("--resume", "scene.toml"),
            )
        if what == "resume_missing":
            return files, ["run", "{dir}/tiny.toml", "--resume", "{dir}/none"], ("--resume",)
        return (
            files,
            ["run", "{dir}/tiny.toml", "-o", "{dir}/a", "--resume", "{dir}/b"],
            ("--resume",),
        )
    if cls == "cli_render":
        return _cli_render(rng)
    if cls == "cli_export":
        return _cli_export(rng)
    if cls == "cli_sweep_zip":
        return _cli_sweep_zip(rng)
    # cli_parse: unknown sub-commands and flags, missing or malformed option values
    what = rng.choice(["command", "flag", "value", "int", "none", "positional"])
    if what == "command":
        name = rng.choice(["grow", "Run", "simulate", "help", _name(rng).lower()])
        if name in ("cell", "run", "compare", "validate", "sweep", "render"):
            name = "x" + name
        return (), [name, "x"], (name,)
    if what == "flag":
        flag = "--" + _name(rng).lower().strip("-_") + "-" + str(rng.randint(0, 99))
        command = rng.choice([["cell"], ["run", "{dir}/s.toml"], ["validate", "{dir}/s.toml"],
                              ["compare", "{dir}/s.toml", "--nx", "4"]])  # fmt: skip
        return (), [*command, flag, "1"], (flag,)
    if what == "value":
        opt = rng.choice(CELL_OPTIONS[:-1])
        return (), ["cell", opt], (opt,)
    if what == "int":
        opt = rng.choice(["--l1", "--nu", "--theta", "--resolution", "--E"])
        return (), ["cell", opt, rng.choice(["abc", "1,5", "", "0x"])], (opt,)
    if what == "none":
        return (), [], ("command",)
    command = rng.choice(["run", "validate", "compare"])
    return (), [command], ("scene",)


def _cli_sweep_zip(rng: random.Random):
    """A ``mode = "zip"`` sweep whose lists differ in length, or repeat a run, or vary a
    parameter the base scene does not define."""
    what = rng.choice(["lengths", "lengths", "same_runs", "undefined_parameter"])
    n = rng.randint(1, 4)
    first = [round(0.1 * (i + 1), 3) for i in range(n)]
    second = [float(i + 1) for i in range(n + rng.choice([-1, 1, 2]) if n > 1 else n + 1)]
    key = "parameters.E_in"
    if what == "same_runs":
        first, second = [0.2, 0.3, 0.2], [1.0, 2.0, 1.0]
    if what == "undefined_parameter":
        key, second = "parameters.E_out", first
    sweep = (f'base = "base.toml"\nmode = "zip"\n[vary]\n"{key}" = {first}\n'
             f'"growth.eta" = {second}\n')  # fmt: skip
    base = TINY + "[parameters]\nE_in = 0.5\n"
    files = (("base.toml", base), ("sweep.toml", sweep))
    argv = ["sweep", "{dir}/sweep.toml", "-o", "{dir}/out", *rng.choice([[], ["--dry-run"]])]
    expect = {"lengths": ("vary", "zip", "equal lengths"), "same_runs": ("vary", "the same"),
              "undefined_parameter": ("'parameters.E_out' is not a scene key",)}[what]  # fmt: skip
    return files, argv, expect


def _cli_render(rng: random.Random):
    """``plantgrowth render`` asked for what it cannot do, checked before any run is read: a
    missing or non-run DIR, a picture that exists (no --force), is not a .png, .pdf or .svg (a
    .gif without --time all, or --time all into a picture) or lies inside DIR, a malformed
    --time or --dpi, --vmin/--vmax not finite or not in order, no --field (an existing picture
    is refused after the run is read: the run's own error comes first)."""
    what = rng.choice(["no_dir", "not_a_run", "exists", "suffix", "inside", "time", "dpi",
                       "no_field", "limits", "animation"])  # fmt: skip
    field = rng.choice(["trG", "G", "u", "growth_direction", _name(rng)])
    base = ["render", "{dir}/run", "--field", field]
    if what == "no_dir":
        return (), [*base, "-o", "{dir}/pic.png"], ("DIR", "no such directory")
    run = (("run/keep.txt", "a user's file\n"),)
    if what == "not_a_run":
        return run, [*base, "-o", "{dir}/pic.png"], ("DIR", "not a run directory")
    if what == "exists":  # refused once the run and its field are read (not a run here)
        files = (*run, ("pic.png", b"\x89PNG not really"))
        return files, [*base, "-o", "{dir}/pic.png"], ("DIR", "not a run directory")
    if what == "suffix":
        name = rng.choice(["pic.jpg", "pic", "pic.png.txt", "pic.GIF", "pic.eps"])
        return run, [*base, "-o", f"{{dir}}/{name}"], ("-o", ".png")
    if what == "inside":
        return run, [*base, "-o", "{dir}/run/pic.png"], ("-o", "inside the run directory")
    if what == "time":
        value = rng.choice(["abc", "1,5", "", "t=1"])
        return run, [*base, "--time", value, "-o", "{dir}/pic.png"], ("--time",)
    if what == "dpi":
        value = rng.choice(["0", "-5", "100000", "1.5", "high"])
        return run, [*base, "--dpi", value, "-o", "{dir}/pic.png"], ("--dpi",)
    if what == "limits":
        low, high = rng.choice([("nan", None), (None, "inf"), ("-inf", "1"), ("1", "1"),
                                ("2", "-3"), (None, "nan")])  # fmt: skip
        limits = [*(["--vmin", low] if low else []), *(["--vmax", high] if high else [])]
        bad = "--vmin" if low in ("nan", "-inf", "1", "2") else "--vmax"
        return run, [*base, *limits, "-o", "{dir}/pic.png"], (bad,)
    if what == "animation":
        name = rng.choice(["pic.png", "pic.svg", "pic"])
        return run, [*base, "--time", "all", "-o", f"{{dir}}/{name}"], ("-o", ".gif")
    return run, ["render", "{dir}/run", "-o", "{dir}/pic.png"], ("--field",)


def _cli_export(rng: random.Random):
    """``plantgrowth export`` asked for what it cannot do, checked before any run is read: a
    missing or non-run DIR, a table that exists (no --overwrite), is not a .csv, lies inside DIR
    or in a directory that does not exist, a malformed --time, no --field."""
    what = rng.choice(["no_dir", "not_a_run", "exists", "suffix", "inside", "no_parent",
                       "time", "no_field"])  # fmt: skip
    field = rng.choice(["G", "u", "Fg", "trG", _name(rng)])
    base = ["export", "{dir}/run", "--field", field]
    if what == "no_dir":
        return (), [*base, "-o", "{dir}/t.csv"], ("{dir}/run", "no such directory")
    run = (("run/keep.txt", "a user's file\n"),)
    if what == "not_a_run":
        return run, [*base, "-o", "{dir}/t.csv"], ("not a plantgrowth run directory",)
    if what == "exists":
        files = (*run, ("t.csv", "x1,x2\n0,0\n"))
        return files, [*base, "-o", "{dir}/t.csv"], ("-o", "exists", "--overwrite")
    if what == "suffix":
        name = rng.choice(["t.txt", "t", "t.csv.gz", "t.png", "t.tsv"])
        return run, [*base, "-o", f"{{dir}}/{name}"], ("-o", ".csv")
    if what == "inside":
        return run, [*base, "-o", "{dir}/run/t.csv"], ("-o", "inside the run directory")
    if what == "no_parent":
        out = "{dir}/" + "/".join(_name(rng) for _ in range(rng.randint(1, 3))) + "/t.csv"
        return run, [*base, "-o", out], ("-o", "does not exist")
    if what == "time":
        value = rng.choice(["abc", "1,5", "", "t=1", "last", "ALL"])
        return run, [*base, "--time", value, "-o", "{dir}/t.csv"], ("--time",)
    return run, ["export", "{dir}/run", "-o", "{dir}/t.csv"], ("--field",)


def _setup_case(rng: random.Random):
    """An output directory that cannot be written: under a regular file, the file itself, /proc."""
    what = rng.choice(["under_file", "under_file", "is_file", "proc", "compare_under_file"])
    files = (("tiny.toml", TINY), ("afile", "not a directory\n"))
    if what == "under_file":
        out = "{dir}/afile/" + "/".join(_name(rng) for _ in range(rng.randint(1, 3)))
        return files, ["run", "{dir}/tiny.toml", "-o", out], ("cannot write", "afile")
    if what == "is_file":
        return files, ["run", "{dir}/tiny.toml", "-o", "{dir}/afile"], ("cannot write", "afile")
    if what == "proc":
        out = f"/proc/plantgrowth_{_name(rng)}/out"
        return files, ["run", "{dir}/tiny.toml", "-o", out], ("cannot write", out)
    files = (("compare.toml", COMPARE), ("afile", "x"))
    argv = ["compare", "{dir}/compare.toml", "--nx", "4", "--first-step-only",
            "-o", "{dir}/afile/cmp"]  # fmt: skip
    return files, argv, ("cannot write", "afile")


def _unbounded_case(rng: random.Random):
    """Sizes without an upper bound: they must be refused at once, not tried (``isolate``)."""
    files = (("compare.toml", COMPARE),)
    what = rng.choice(["cell", "compare_nx", "compare_resolution"])
    if what == "cell":
        return (), ["cell", "--resolution", str(rng.choice([100, 1000, 10**6]))], ("resolution",)
    base = ["compare", "{dir}/compare.toml", "--first-step-only", "-o", "{dir}/cmp"]
    if what == "compare_nx":
        return files, [*base, "--nx", str(rng.choice([2048, 10**5, 10**6]))], ("--nx",)
    return (
        files,
        [*base, "--nx", "4", "--resolution", str(rng.choice([1000, 10**5]))],
        ("--resolution",),
    )


CLASSES = {  # class -> relative weight
    **{name: 4.0 for name in SCENE_MAKERS},
    "empty_file": 1.5,
    "binary_garbage": 2.0,
    "toml_syntax": 3.0,
    "cli_cell": 4.0,
    "cli_compare": 1.5,
    "cli_run": 2.0,
    "cli_render": 2.0,
    "cli_export": 1.5,
    "cli_sweep_zip": 1.5,
    "cli_parse": 3.0,
    "output_dir": 2.0,
    "unbounded_size": 0.25,
}
FILE_CLASSES = ("empty_file", "binary_garbage", "toml_syntax")
CLI_CLASSES = ("cli_cell", "cli_compare", "cli_run", "cli_render", "cli_export", "cli_sweep_zip",
               "cli_parse")  # fmt: skip


def _scene_argv(rng: random.Random, files: list) -> list[str]:
    """Every command that reads a scene; ``run`` with -o, into an existing directory, or with
    the default (results/<name> in the working directory)."""
    command = rng.choice(["validate", "run", "run", "run_existing", "run_default", "compare"])
    if command == "validate":
        return ["validate", f"{{dir}}/{SCENE}"]
    if command == "compare":
        return ["compare", f"{{dir}}/{SCENE}", "--nx", "4", "--first-step-only", "-o", "{dir}/c"]
    if command == "run_existing":
        files.append(("out/keep.txt", "an earlier run's file\n"))
    if command == "run_default":
        return ["run", f"{{dir}}/{SCENE}"]
    return ["run", f"{{dir}}/{SCENE}", "-o", "{dir}/out"]


def make_case(rng: random.Random, cls: str, index: int) -> Case:
    """One case of class ``cls``."""
    name = f"{cls}-{index:04d}"
    if cls in SCENE_MAKERS:
        # (scene, key) or (scene, message fragments, extra files such as a tissue.mesh)
        scene, key, *extra = SCENE_MAKERS[cls](rng, base_scene(rng))
        expect = key if isinstance(key, tuple) else (key,)
        files: list = [(SCENE, to_toml(scene)), *(extra[0] if extra else [])]
        argv = _scene_argv(rng, files)
        label = key.strip("'=. ") if isinstance(key, str) else expect[0].split(" ")[0].split("[")[0]
        return Case(f"{name}-{label}", cls, "scene", tuple(argv), expect, tuple(files))
    if cls in FILE_CLASSES:
        content, expect = _file_case(rng, cls)
        files = [(SCENE, content)]
        argv = _scene_argv(rng, files)
        return Case(name, cls, "scene", tuple(argv), expect, tuple(files))
    if cls in CLI_CLASSES:
        files, argv, expect = _cli_case(rng, cls)
        return Case(f"{name}-{'_'.join(argv[:1]) or 'none'}", cls, "argv", tuple(argv),
                    tuple(expect), tuple(files))  # fmt: skip
    if cls == "output_dir":
        files, argv, expect = _setup_case(rng)
        return Case(name, cls, "setup", tuple(argv), expect, tuple(files))
    if cls == "unbounded_size":
        files, argv, expect = _unbounded_case(rng)
        return Case(name, cls, "argv", tuple(argv), expect, tuple(files), isolate=True)
    raise ValueError(f"unknown class {cls!r}")


def generate(seed: int, n: int, classes: dict[str, float] | None = None) -> list[Case]:
    """``n`` malformed inputs of the classes (name -> weight), mixed at random with ``seed``."""
    rng = random.Random(seed)
    weights = CLASSES if classes is None else classes
    names = list(weights)
    chosen = rng.choices(names, weights=[weights[c] for c in names], k=n)
    return [make_case(rng, cls, i) for i, cls in enumerate(chosen)]


def one_per_class(seed: int, classes: tuple[str, ...] | None = None) -> list[Case]:
    """One case of each class (default: all classes), e.g. for the subprocess checks."""
    rng = random.Random(seed)
    return [make_case(rng, cls, i) for i, cls in enumerate(classes or CLASSES)]


def unbounded_cases() -> list[Case]:
    """The three sizes without an upper bound, one case each (``isolate``)."""
    files = (("compare.toml", COMPARE),)
    base = ("compare", "{dir}/compare.toml", "--first-step-only", "-o", "{dir}/cmp")
    return [
        Case("cell-resolution-1000", "unbounded_size", "argv",
             ("cell", "--resolution", "1000"), ("resolution",), isolate=True),
        Case("compare-nx-100000", "unbounded_size", "argv", (*base, "--nx", "100000"),
             ("--nx",), files, isolate=True),
        Case("compare-resolution-100000", "unbounded_size", "argv",
             (*base, "--nx", "4", "--resolution", "100000"), ("--resolution",), files,
             isolate=True),
    ]  # fmt: skip


# --- checking an outcome ------------------------------------------------------------------------


def snapshot(directory: Path) -> dict[str, bytes | None]:
    """Every path under ``directory`` with its content (None for a directory)."""
    return {
        str(p.relative_to(directory)): p.read_bytes() if p.is_file() else None
        for p in sorted(directory.rglob("*"))
    }


def problems(
    case: Case, directory: Path, code: int | None, stdout: str, stderr: str,
    before: dict[str, bytes | None],
) -> list[str]:  # fmt: skip
    """What is wrong with an outcome (empty: exit code, one named message, no traceback, and
    nothing written or changed in the case's directory)."""
    found = []
    if code != case.code:
        found.append(f"exit code {code}, expected {case.code}")
    if "Traceback" in stdout + stderr:
        found.append("a traceback")
    lines = stderr.splitlines()
    if len(lines) != 1 or not lines[0].startswith("plantgrowth: error: "):
        found.append(f"stderr is not one 'plantgrowth: error:' line: {stderr[-400:]!r}")
    else:
        missing = [f for f in case.fragments(directory) if f not in lines[0]]
        if missing:
            found.append(f"the message does not contain {missing}: {lines[0][:400]!r}")
    after = snapshot(directory)
    common = after.keys() & before.keys()
    changed = sorted((after.keys() ^ before.keys()) | {k for k in common if after[k] != before[k]})
    if changed:
        found.append(f"files written or changed: {changed[:8]}")
    return found


PLANTGROWTH = str(Path(sys.executable).parent / "plantgrowth")


def run_cli(argv: list[str], cwd: Path, timeout: float) -> tuple[int | None, str, str]:
    """The CLI as a process in its own session (killed with its children after ``timeout``);
    returns (exit code or None if killed, stdout, stderr)."""
    proc = subprocess.Popen(
        [PLANTGROWTH, *argv], cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, start_new_session=True,
    )  # fmt: skip
    try:
        out, err = proc.communicate(timeout=timeout)
        return proc.returncode, out, err
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        return None, out, err + f"\n(killed: still running after {timeout:g} s)"
