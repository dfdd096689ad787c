"""The :class:`Scene` and how one is read: TOML text or parsed data in, a validated scene out
(presets filled in, relative mesh paths resolved); the key reference is :mod:`plantgrowth.scene`."""

from __future__ import annotations

import copy
import os
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from plantgrowth.base.errors import InputError, SceneError
from plantgrowth.meshes.honeycomb import GeometryError
from plantgrowth.meshes.tissue import TissueLayout, wall_mesh_size
from plantgrowth.meshes.unit_cell import mesh_size
from plantgrowth.scene import hydraulics as water
from plantgrowth.scene import loads as edge_loads
from plantgrowth.scene import walls as fibre_walls
from plantgrowth.scene.cells_spec import ImportedCells, cells_table
from plantgrowth.scene.field_syntax import parse_field
from plantgrowth.scene.fields import AnyField, Field
from plantgrowth.scene.limits import (
    KINEMATICS,
    LAWS,
    MAX_LENGTH,
    MAX_NX,
    MAX_RESOLUTION,
    MODELS,
    RANGES,
    REFERENCE_WIDTH,
)
from plantgrowth.scene.load_balance import unbalanced_load
from plantgrowth.scene.parameters import parse_parameters
from plantgrowth.scene.parts import (
    Accuracy,
    CellGeometry,
    Growth,
    Material,
    Numerics,
    Output,
    Solver,
    Time,
    Tissue,
    check_edge,
    edge_load,
    held_edge,
)
from plantgrowth.scene.presets import DEFAULT_PRESET, PRESETS
from plantgrowth.scene.regions import Region, parse_regions
from plantgrowth.scene.shapes import mesh_shape, outline_points, outline_shape
from plantgrowth.scene.toml_text import dict_to_toml
from plantgrowth.scene.values import (
    TABLES,
    check_keys,
    choice,
    in_range,
    integer,
    set_fields,
    show,
)
from plantgrowth.scene.walls import Feedback, Walls


@dataclass(frozen=True)
class Scene:
    """One fully validated simulation; build it with :func:`load_scene` or :func:`parse_scene`."""

    model: str
    tissue: Tissue
    cell: CellGeometry
    material: Material
    P1: AnyField
    growth: Growth
    time: Time
    loads: dict[str, edge_loads.Load] = field(default_factory=dict)
    output: Output = Output()
    accuracy: Accuracy = Accuracy()
    micro_nx: int = 16
    micro_resolution: int = 2
    solver: Solver = Solver()
    numerics: Numerics = Numerics()
    kinematics: str = "linear"
    parameters: dict[str, float] = field(default_factory=dict)  # named numbers of expressions
    regions: dict[str, Region] = field(default_factory=dict)  # reported in summary.csv
    supports: dict[str, str] = field(default_factory=dict)
    walls: Walls | None = None  # fibre-reinforced walls; None: the paper's isotropic walls
    feedback: Feedback | None = None  # the fibre director's mechanical feedback
    hydraulics: water.Hydraulics | None = None  # water fluxes; None: turgor given by P1

    def __post_init__(self) -> None:
        choice("model", self.model, MODELS)
        choice("kinematics", self.kinematics, KINEMATICS)
        if (osmotic := water.turgor_input(self)) is not None:  # Pi (docs/model.md, water fluxes)
            set_fields(self, P1=osmotic)
        if self.feedback is not None and (self.walls is None or self.walls.fibre_angle is None):
            raise SceneError(
                "feedback: [feedback] turns the fibre director, but the scene has no fibres: give "
                "walls.fibre_stiffness (E_f / E, >= 0) and walls.fibre_angle (the director at "
                "t = 0, degrees from x1), or remove [feedback]"
            )
        fibre_walls.check_outputs(self.output.fields, self.walls, self.feedback)
        self.P1.check("pressure.P1", *RANGES["pressure.P1"])  # Pi: its own key checked it
        for key, f in (self.parameter_fields() | self.growth.Fg0_fields()).items():
            if isinstance(f, Field) and f.width != self.tissue.width:
                raise SceneError(f"{key}: field width {f.width!r} != tissue.width")
            if isinstance(f, Field) and f.height != self.tissue.height:
                raise SceneError(f"{key}: field height {f.height!r} != tissue.height")
        loads = {}
        lengths = self.tissue.edge_lengths()
        for edge, f in self.loads.items():
            check_edge(edge, self.tissue.shape)
            load = edge_load(edge, f, lengths[edge][0], self.parameters)
            if load not in ((0.0, 0.0), edge_loads.EdgeForce((0.0, 0.0))):  # non-zero loads only
                loads[edge] = load
        if not isinstance(self.supports, dict):
            raise SceneError(f"supports: expected a table [supports], got {show(self.supports)}")
        for edge, kind in self.supports.items():
            held_edge(edge, kind, self.tissue, self.loads)  # every load given, zero ones too
        set_fields(self, loads=loads, supports=dict(self.supports))
        if integer("micro.nx", self.micro_nx, 2, MAX_NX) % 2:
            raise SceneError(f"micro.nx = {self.micro_nx} is invalid: it must be even")
        integer("micro.resolution", self.micro_resolution, 1, MAX_RESOLUTION)
        try:  # the unit-cell meshes at the corners must be affordable (expressions: scene.places)
            for x1, x2 in [] if self.cell.by_expression else self.corners():
                mesh_size(
                    self.cell.at(x1, x2), self.accuracy.cell_resolution, "accuracy.cell_resolution"
                )
        except GeometryError as e:
            raise SceneError(str(e)) from None
        if self.model != "macro":
            self.check_micro()
        # suggest balancing on the rectangle's left edge, else on an edge not loaded yet
        fix = "left" if "left" in lengths else next((e for e in lengths if e not in loads), "")
        fix = fix or next(iter(loads), "")
        if (
            loads
            and self.pinned
            and (unbalanced := unbalanced_load(loads, lengths, self.tissue.pin, fix))
        ):
            raise SceneError(unbalanced)

    def held_components(self) -> dict[str, tuple[int, ...]]:
        """Each held edge (``[supports]``) -> the components of u held at zero there (0: u1, 1:
        u2; docs/model.md section 4)."""
        return {e: held_edge(e, kind, self.tissue, self.loads) for e, kind in self.supports.items()}

    @property
    def has_director(self) -> bool:
        """Whether the run carries a fibre director (docs/fibres.md): fibred walls
        (``walls.fibre_stiffness`` other than the constant 0), or ``[feedback]`` turning one."""
        return fibre_walls.carries_director(self.walls, self.feedback)

    @property
    def pinned(self) -> bool:
        """True if only the pinned point holds the tissue along x1 (no held edge holds u1): it
        carries the loads' net x1 force, so they must balance (plantgrowth/scene/load_balance.py);
        a held edge that holds u1 replaces the pin and carries the net force."""
        return not any(0 in held for held in self.held_components().values())

    def corners(self) -> list[tuple[float, float]]:
        """The tissue rectangle's corners (x1, x2)."""
        return [(x1, x2) for x1 in (0.0, self.tissue.width) for x2 in (0.0, self.tissue.height)]

    def check_micro(self) -> None:
        """The micro model needs a constant cell geometry (a gradient of w, l1, l2 or theta has no
        well-defined cellular tissue: docs/model.md section 7, paper section 5.3), builds its own
        tissue (no outline or mesh) and has no loads."""
        if self.tissue.shape is not None:
            raise SceneError(
                f"{self.tissue.shape.key}: the micro model builds its own honeycomb tissue "
                f'(docs/model.md section 7); use model = "macro"'
            )
        for key in ("l1", "l2", "theta", "w"):
            if not getattr(self.cell, key).is_constant:
                raise SceneError(
                    f"cell.{key} is a field, but model = {self.model!r} needs a constant cell "
                    "geometry: geometric gradients are defined for the macro model only"
                )
        if self.loads:
            raise SceneError(
                f"loads are not supported by model = {self.model!r}: the cellular tissue has no "
                "straight left/right/top edges; use model = 'macro'"
            )
        if self.supports:
            raise SceneError(
                "supports: the micro model (model = 'micro' or 'both', plantgrowth compare) has "
                "no held edges: the cellular tissue has no straight side to hold; hold edges with "
                "model = 'macro'"
            )
        try:  # the walls mesh must be affordable
            wall_mesh_size(
                TissueLayout(self.cell.at(0.0, 0.0), self.micro_nx), self.micro_resolution
            )
        except GeometryError as e:
            raise SceneError(str(e)) from None

    def check_cellular_extent(self, command: str = "", nx: int | None = None) -> None:
        """A scene whose tissue is cellular (model micro or both, ``plantgrowth compare``) gives
        no tissue.width or tissue.height but the defaults: its tissue is Nx cells per row, the
        size the cells make (a width the run would silently ignore is an error). ``command``,
        ``nx``: a command that builds its own ``--nx`` tissues (e.g. "plantgrowth compare" and
        its first Nx); default: the scene's model and micro.nx."""
        tissue, cells = self.tissue, f"micro.nx = {self.micro_nx}" if nx is None else f"--nx {nx}"
        for key, default in (("width", REFERENCE_WIDTH), ("height", Tissue.height)):
            if getattr(tissue, key) != default:
                layout = TissueLayout(self.cell.at(0.0, 0.0), self.micro_nx if nx is None else nx)
                box = " x ".join(f"{x:.4g}" for x in layout.bounding_box)
                raise SceneError(
                    f"tissue.{key} = {getattr(tissue, key):g} is not used by "
                    f"{command or f'model = {self.model!r}'}: it builds a cellular tissue of "
                    f"{cells} cells per row, here {box} (width x height, set by the cell count "
                    "and the cell geometry); remove tissue.width and tissue.height"
                )

    def over_extent(self, width: float, height: float) -> Scene:
        """This scene on a tissue of extent [0, width] x [0, height] (a micro tissue, or the
        macro side of a micro-macro comparison): every linear field runs from its ``from`` value
        at 0 to its ``to`` value at the extent along its axis, never extrapolated
        (docs/model.md section 7); expressions are unchanged. Revalidated."""
        if (width, height) == (self.tissue.width, self.tissue.height):
            return self

        def over(f: AnyField) -> AnyField:
            return f.over(width, height)

        cell = CellGeometry(*(over(f) for f in self.cell.fields()))
        material = Material(over(self.material.E), over(self.material.nu))
        walls = None if self.walls is None else self.walls.over(width, height)
        return replace(
            self, tissue=replace(self.tissue, width=width, height=height), cell=cell,
            material=material, P1=over(self.P1), growth=self.growth.over(width, height),
            walls=walls, hydraulics=self.hydraulics and self.hydraulics.over(width, height),
        )  # fmt: skip

    def parameter_fields(self) -> dict[str, AnyField]:
        """All spatially varying parameters by dotted key (the fibre fields when given)."""
        cell, mat, g = self.cell, self.material, self.growth
        out = {f"cell.{k}": getattr(cell, k) for k in ("l1", "l2", "theta", "w")}
        out |= {"material.E": mat.E, "material.nu": mat.nu, "pressure.P1": self.P1,
                "growth.eta": g.eta, "growth.tau": g.tau}  # fmt: skip
        out |= {} if self.walls is None else self.walls.fields()
        if self.hydraulics is None:
            return out  # else the turgor input is the osmotic pressure, one of the hydraulics'
        return {k: f for k, f in out.items() if k != "pressure.P1"} | self.hydraulics.fields()

    @classmethod
    def from_dict(cls, data: dict, directory: str | os.PathLike | None = None) -> Scene:
        """A scene from TOML data (tables as dicts), checked as :func:`load_scene` checks a
        file; a relative ``tissue.mesh`` is relative to ``directory`` (default: the current
        directory)."""
        return parse_scene(data, directory=directory)

    def replace(self, **changes: Any) -> Scene:
        """This scene with dotted keys changed, e.g. ``replace(**{"material.E": 2.0})`` or
        ``replace(**{"growth.eta": {"from": 0.5, "to": 2.0}})``, checked as the TOML is. The
        change applies to the scene as written, so keys it left to its preset still follow
        ``accuracy.preset``."""
        data, directory = getattr(self, "_source", (self.to_dict(), None))
        return parse_scene(with_values(data, changes), directory=directory)

    def to_dict(self) -> dict[str, Any]:
        """The fully resolved scene as plain TOML/JSON data (fields as numbers or tables)."""
        out: dict[str, Any] = {"model": self.model, "kinematics": self.kinematics}
        out["tissue"] = self.tissue.to_toml()
        for key, f in self.parameter_fields().items():
            section, name = key.split(".")
            out.setdefault(section, {})[name] = f.to_toml()
        g, t = self.growth, self.time
        Fg0 = [[x if isinstance(x, float) else x.to_toml() for x in row] for row in g.Fg0]
        out["growth"] = {"law": g.law, **out["growth"], "clamp": g.clamp, "Fg0": Fg0}
        out["time"] = {
            "t_max": t.t_max, "dt": t.dt, "integrator": t.integrator, "tolerance": t.tolerance
        }  # fmt: skip
        out["loads"] = {edge: edge_loads.to_toml(load) for edge, load in self.loads.items()}
        out["output"] = {f.name: getattr(self.output, f.name) for f in fields(self.output)}
        out["accuracy"] = {f.name: getattr(self.accuracy, f.name) for f in fields(self.accuracy)}
        nx = {} if isinstance(self.tissue.cells, ImportedCells) else {"nx": self.micro_nx}
        out["micro"] = nx | {"resolution": self.micro_resolution}  # a file's cells: no Nx
        out["solver"] = {f.name: getattr(self.solver, f.name) for f in fields(self.solver)}
        out["numerics"] = {"on_instability": self.numerics.on_instability}
        if self.parameters:  # written only when given, so older runs' scene.toml compare equal
            out["parameters"] = dict(self.parameters)
        if self.regions:
            out["regions"] = {name: r.to_toml() for name, r in self.regions.items()}
        if self.supports:
            out["supports"] = dict(self.supports)
        if self.feedback is not None:  # the walls are among the parameter fields
            feedback = self.feedback
            out["feedback"] = {"cue": feedback.cue, "rate": feedback.rate, "walls": feedback.walls}
        out |= {} if self.hydraulics is None else {"hydraulics": self.hydraulics.to_toml()}
        return out

    def dotted(self) -> dict[str, Any]:
        """The resolved scene by dotted key (``model``, ``material.nu``, ``loads.right``, ...)."""
        out: dict[str, Any] = {}
        for key, value in self.to_dict().items():
            if isinstance(value, dict):
                out.update({f"{key}.{k}": v for k, v in value.items()})
            else:
                out[key] = value
        return out

    def to_toml(self) -> str:
        """The fully resolved scene (all defaults filled) as TOML that load_scene reads back."""
        header = "# plantgrowth scene, fully resolved (keys: see plantgrowth/scene/__init__.py)\n"
        return header + dict_to_toml(self.to_dict())


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
    if name not in ("loads", "supports"):  # the edges depend on the tissue: Scene checks them
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


def with_values(data: dict, values: dict[str, Any]) -> dict:
    """A copy of scene data with dotted keys set (``"material.nu"``, ``"loads.right"``)."""
    out = copy.deepcopy(data)
    for key, value in values.items():
        *path, name = key.split(".")
        table = out
        for i, part in enumerate(path):
            table = table.setdefault(part, {})
            if not isinstance(table, dict):
                raise SceneError(f"{key}: {'.'.join(path[: i + 1])} is not a table")
        table[name] = value
    return out


def parse_scene(
    data: dict, source: str = "<scene>", directory: str | os.PathLike | None = None
) -> Scene:
    """Validate parsed TOML data into a Scene; error messages end with ``(in source)``. A
    relative ``tissue.mesh`` is relative to ``directory`` (default: the current directory)."""
    base = Path.cwd() if directory is None else Path(directory)
    try:
        scene = _parse(data, base)
        if scene.model != "macro":
            scene.check_cellular_extent()
    except (InputError, GeometryError) as e:
        suffix = "" if source == "<scene>" else f" (in {source})"
        raise SceneError(f"{e}{suffix}") from None
    set_fields(scene, _source=(copy.deepcopy(data), base))  # what Scene.replace changes
    return scene


def _parse(data: dict, directory: Path) -> Scene:
    if not isinstance(data, dict):
        raise SceneError(f"scene: expected a table of tables, got {show(data)}")
    check_keys(data, "", ("model", *TABLES, "kinematics", "parameters", "regions"))
    constants = parse_parameters(data.get("parameters", {}))
    tables = {name: _table(data, name) for name in TABLES}
    tissue_table = cells_table(tables["tissue"], tables["micro"], directory)  # a file: absolute
    if "mesh" in tissue_table:
        tissue_table = tissue_table | {"mesh": _mesh_path(tissue_table["mesh"], directory)}
    tables["tissue"] = tissue_table
    t = _with_preset(tables)
    tissue = Tissue(**t["tissue"])
    f = {
        section: {
            k: parse_field(
                f"{section}.{k}", t[section].get(k, d), tissue.width, tissue.height, constants
            )
            for k, d in kd.items()
        }
        for section, kd in _FIELD_DEFAULTS.items()
    }
    if "law" not in t["growth"]:
        raise SceneError(f"growth.law is required: one of {', '.join(map(repr, LAWS))}")
    if isinstance(Fg0 := t["growth"].get("Fg0"), list):  # tables in it are fields
        f["growth"]["Fg0"] = [
            [
                parse_field(f"growth.Fg0[{i}][{j}]", x, tissue.width, tissue.height, constants)
                if isinstance(x, dict)
                else x
                for j, x in enumerate(row)
            ]
            if isinstance(row, list)
            else row
            for i, row in enumerate(Fg0)
        ]
    walls = fibre_walls.walls_from(data, t["walls"], tissue, constants)
    feedback = fibre_walls.feedback_from(data, t["feedback"])
    output = {"fields": fibre_walls.default_fields(walls, feedback)} | t["output"]
    regions = parse_regions(data.get("regions", {}), constants)
    return Scene(
        model=data.get("model", "macro"),
        tissue=tissue,
        cell=CellGeometry(**f["cell"]),
        material=Material(**f["material"]),
        P1=f["pressure"]["P1"],
        growth=Growth(**(t["growth"] | f["growth"])),
        time=Time(**t["time"]),
        loads=dict(t["loads"]),
        output=Output(**output),
        accuracy=Accuracy(**t["accuracy"]),
        micro_nx=t["micro"].get("nx", getattr(tissue.cells, "nx", 16)),
        micro_resolution=t["micro"].get("resolution", 2),
        solver=Solver(**t["solver"]),
        numerics=Numerics(**t["numerics"]),
        kinematics=data.get("kinematics", "linear"),
        parameters=constants,
        regions=regions,
        supports=dict(t["supports"]),
        walls=walls,
        feedback=feedback,
        hydraulics=water.hydraulics_from(data, tissue, constants, tuple(regions)),
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
