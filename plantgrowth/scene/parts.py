"""The parts of a scene, frozen dataclasses each validated in ``__post_init__``: the tissue, the
cell geometry, the material, growth, time, output, accuracy and solver tables, and the checks of
an edge load (the key reference: :mod:`plantgrowth.scene`; the fibred walls and their feedback:
:mod:`plantgrowth.scene.walls`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from plantgrowth.base.errors import InputError, SceneError, check_growth_tensor
from plantgrowth.meshes.honeycomb import GeometryError, HoneycombCell
from plantgrowth.scene import loads as edge_loads
from plantgrowth.scene.cells_spec import CellsSpec, parse_cells
from plantgrowth.scene.expression import Expression, parse_expression
from plantgrowth.scene.field_names import close_fields
from plantgrowth.scene.fields import AnyField, ExprField, Field
from plantgrowth.scene.limits import (
    BIG,
    CELL_INTERPOLANTS,
    DEFAULT_OUTPUT,
    EDGES,
    FG0_RANGE,
    IDENTITY,
    INTEGRATORS,
    LAWS,
    MACRO_RTOL,
    MACRO_RTOL_RANGE,
    MACRO_SOLVERS,
    MACRO_THRESHOLD,
    MAX_CELLS,
    MAX_LENGTH,
    MAX_RESOLUTION,
    MAX_STEPS,
    OUTPUT_FIELDS,
    RANGES,
    REFERENCE_WIDTH,
    SPARE_ITERATIONS_RANGE,
    SUPPORTS,
)
from plantgrowth.scene.presets import DEFAULT_PRESET, PRESETS, knob
from plantgrowth.scene.shapes import Shape, mesh_shape, outline_points, outline_shape, unloadable
from plantgrowth.scene.values import (
    array,
    check_keys,
    choice,
    in_range,
    integer,
    set_fields,
    show,
)

# --- the scene ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Tissue:
    """The tissue: the rectangle [0, width] x [0, height], or an ``outline`` polygon or a
    ``mesh`` file whose bounding box sets width and height (plantgrowth/scene/shapes.py); the fine
    (h) and coarse (H) mesh sizes."""

    width: float = REFERENCE_WIDTH
    height: float = 3.0
    h: float = knob(DEFAULT_PRESET, "tissue", "h")
    H: float = knob(DEFAULT_PRESET, "tissue", "H")
    outline: tuple[tuple[float, float], ...] | None = None
    mesh: str | None = None
    cells: CellsSpec | None = None  # parsed from a table or a file name: scene/cells_spec.py
    pixel_size: float | None = None
    shape: Shape | None = field(default=None, init=False, compare=False, repr=False)

    def __post_init__(self) -> None:
        set_fields(self, cells=parse_cells(self.cells, self.pixel_size))
        if self.outline is not None and self.mesh is not None:
            raise SceneError("tissue.mesh: not with tissue.outline: give one tissue shape")
        try:
            if self.outline is not None:
                set_fields(self, outline=outline_points(self.outline))
                set_fields(self, shape=outline_shape(self.outline))
            elif self.mesh is not None:
                set_fields(self, shape=mesh_shape(self.mesh))
        except InputError as e:
            raise SceneError(str(e)) from None
        if self.shape is not None:  # the bounding box
            set_fields(self, width=self.shape.width, height=self.shape.height)
        W = in_range("tissue.width", self.width, 0.0, MAX_LENGTH, hi_open=False)
        Ht = in_range("tissue.height", self.height, 0.0, MAX_LENGTH, hi_open=False)
        h = in_range("tissue.h", self.h, 0.0, min(W, Ht) / 2, hi_open=False)
        H = in_range("tissue.H", self.H, h, max(W, Ht), lo_open=False, hi_open=False)
        given = self.shape.triangles if self.shape is not None else None
        cells = 2.0 * math.ceil(W / h) * math.ceil(Ht / h) if given is None else given
        if cells > MAX_CELLS:
            raise SceneError(
                f"tissue.mesh has {cells} triangles (limit {MAX_CELLS:g})"
                if given is not None
                else f"tissue.h = {h!r} is too small: the fine mesh would have about {cells:.3g} "
                f"triangles (limit {MAX_CELLS:g}); use h >= {math.sqrt(2 * W * Ht / MAX_CELLS):.3g}"
            )
        set_fields(self, width=W, height=Ht, h=h, H=H)

    def edge_lengths(self) -> dict[str, tuple[float, str]]:
        """Loadable edge -> (reference length, its name in the load-balance formula)."""
        if self.shape is None:
            return {
                "left": (self.height, "height"), "right": (self.height, "height"),
                "top": (self.width, "width"),
            }  # fmt: skip
        return {edge: (length, f"{length:.6g}") for edge, length in self.shape.edges.items()}

    def normal_axes(self) -> dict[str, int | None]:
        """Every edge, loadable or on x2 = 0 -> the axis its normal points along (0: x1, 1: x2,
        None: an inclined edge of a shape)."""
        if self.shape is None:
            return {"bottom": 1, "left": 0, "right": 0, "top": 1}
        return dict(self.shape.normal_axes)

    @property
    def symmetry_edges(self) -> tuple[str, ...]:
        """The edges on the symmetry plane x2 = 0."""
        return ("bottom",) if self.shape is None else self.shape.symmetry

    @property
    def pin(self) -> tuple[float, float]:
        """The vertex where u1 = 0: the origin of the rectangle, else the shape's."""
        return (0.0, 0.0) if self.shape is None else self.shape.pin

    def to_toml(self) -> dict[str, Any]:
        """The keys that reproduce this tissue (the bounding box is not written for a shape)."""
        if self.outline is not None:
            return {"outline": [list(p) for p in self.outline], "h": self.h, "H": self.H}
        if self.mesh is not None:
            return {"mesh": self.mesh, "h": self.h, "H": self.H}
        if self.cells is not None:
            size = {} if self.pixel_size is None else {"pixel_size": self.pixel_size}
            return {"cells": self.cells.to_toml(), **size, "h": self.h, "H": self.H}
        return {"width": self.width, "height": self.height, "h": self.h, "H": self.H}


@dataclass(frozen=True)
class CellGeometry:
    """Honeycomb cell parameters (docs/model.md section 2); theta in degrees."""

    l1: AnyField
    l2: AnyField
    theta: AnyField
    w: AnyField

    def __post_init__(self) -> None:
        for key in ("l1", "l2", "theta", "w"):
            getattr(self, key).check(f"cell.{key}", *RANGES[f"cell.{key}"])
        if self.by_expression:
            return  # checked at the coarse nodes (plantgrowth.scene.places)
        linear = [f for f in self.fields() if not f.is_constant]
        # w_max is not linear in x1, x2: check the ends and the middle along each axis used
        width, height = (linear[0].width, linear[0].height) if linear else (1.0, 1.0)
        axes = {f.along for f in linear}
        x1s = (0.0, width / 2, width) if "x1" in axes else (0.0,)
        x2s = (0.0, height / 2, height) if "x2" in axes else (0.0,)
        for x1 in x1s:
            for x2 in x2s:
                place = f"x1 = {x1:g}" if axes == {"x1"} else f"x1 = {x1:g}, x2 = {x2:g}"
                self.check_at(x1, x2, "" if not linear else f" (at {place})")

    def fields(self) -> tuple[AnyField, ...]:
        return (self.l1, self.l2, self.theta, self.w)

    @property
    def by_expression(self) -> bool:
        """True if some parameter is a non-constant expression."""
        return any(isinstance(f, ExprField) and not f.is_constant for f in self.fields())

    def check_at(self, x1: float, x2: float, place: str) -> HoneycombCell:
        """The unit cell at (x1, x2), else SceneError naming the parameter and ``place``."""
        try:
            return self.at(x1, x2)
        except GeometryError as e:  # its message starts with the parameter's name
            msg = str(e) if str(e).startswith(("l1", "l2", "theta", "w")) else f"w: {e}"
            raise SceneError(f"cell.{msg}{place}") from None

    def at(self, x1: float, x2: float) -> HoneycombCell:
        """The unit cell at (x1, x2) (GeometryError if impossible there)."""
        return HoneycombCell(*(float(f(x1, x2)) for f in self.fields()))


@dataclass(frozen=True)
class Material:
    """Wall Young modulus E > 0 and Poisson ratio -1 < nu < 0.5 (docs/model.md section 1)."""

    E: AnyField
    nu: AnyField

    def __post_init__(self) -> None:
        self.E.check("material.E", *RANGES["material.E"])
        self.nu.check("material.nu", *RANGES["material.nu"])


@dataclass(frozen=True)
class Growth:
    """Growth law (docs/model.md section 4): G = clip(eta [X / phi_w - tau]_+, -clamp, clamp).

    ``law`` is "stress" (X = sigma_hom), "strain" (X = eps_hom) or "none" (G = 0).
    """

    law: str
    eta: AnyField
    tau: AnyField
    clamp: float = 1.0
    Fg0: tuple[tuple[float | AnyField, ...], ...] = IDENTITY  # entries: numbers or fields

    def __post_init__(self) -> None:
        choice("growth.law", self.law, LAWS)
        self.eta.check("growth.eta", *RANGES["growth.eta"])
        self.tau.check("growth.tau", *RANGES["growth.tau"])
        set_fields(self, clamp=in_range("growth.clamp", self.clamp, 0.0, BIG, hi_open=False))
        rows = tuple(
            tuple(
                _Fg0_entry(f"growth.Fg0[{i}][{j}]", x)
                for j, x in enumerate(array(f"growth.Fg0[{i}]", row, 2))
            )
            for i, row in enumerate(array("growth.Fg0", self.Fg0, 2))
        )
        set_fields(self, Fg0=rows)
        if self.Fg0_fields():
            return  # det Fg0 > 0 is checked where Fg0 is used (plantgrowth.scene.places)
        try:
            check_growth_tensor("growth.Fg0", rows)  # det > 0
        except InputError as e:
            raise SceneError(str(e)) from None

    def Fg0_fields(self) -> dict[str, AnyField]:
        """The entries of Fg0 that are fields, by dotted key (``growth.Fg0[0][1]``)."""
        return {
            f"growth.Fg0[{i}][{j}]": x
            for i, row in enumerate(self.Fg0)
            for j, x in enumerate(row)
            if not isinstance(x, float)
        }

    def initial(self, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
        """(n, 2, 2) initial growth tensors Fg0 at the points (x1, x2)."""
        x1, x2 = np.broadcast_arrays(np.asarray(x1, dtype=float), np.asarray(x2, dtype=float))
        out = np.empty((x1.size, 2, 2))
        for i, row in enumerate(self.Fg0):
            for j, x in enumerate(row):
                out[:, i, j] = x if isinstance(x, float) else x(x1.ravel(), x2.ravel())
        return out

    def over(self, width: float, height: float) -> Growth:
        """The growth fields across a tissue of another extent (docs/model.md section 7)."""
        Fg0 = tuple(tuple(x if isinstance(x, float) else x.over(width, height) for x in row)
                    for row in self.Fg0)  # fmt: skip
        return replace(
            self, eta=self.eta.over(width, height), tau=self.tau.over(width, height), Fg0=Fg0
        )


def _Fg0_entry(key: str, x: object) -> float | AnyField:
    """An entry of Fg0: a number or a field, finite and of magnitude <= MAX_LENGTH."""
    if isinstance(x, (Field, ExprField)):
        x.check(key, *FG0_RANGE)
        return x
    return in_range(key, x, *FG0_RANGE)


@dataclass(frozen=True)
class Time:
    """Time interval [0, t_max] in n_steps steps dt; integrator "euler", "exp" or "adaptive"
    (exp with step-doubling control of the growth tensor's local error, ``tolerance``)."""

    t_max: float = 60.0
    dt: float = knob(DEFAULT_PRESET, "time", "dt")
    integrator: str = knob(DEFAULT_PRESET, "time", "integrator")
    tolerance: float = 1e-3

    def __post_init__(self) -> None:
        dt = in_range("time.dt", self.dt, 0.0, BIG, hi_open=False)
        t_max = in_range("time.t_max", self.t_max, 0.0, BIG, hi_open=False)
        choice("time.integrator", self.integrator, INTEGRATORS)
        in_range("time.tolerance", self.tolerance, 0.0, 0.1, hi_open=False)
        n = t_max / dt
        if n < 1.0 - 1e-9:
            raise SceneError(
                f"time.t_max = {t_max!r} is smaller than time.dt = {dt!r}: set time.t_max to a "
                "multiple of time.dt"
            )
        if n > MAX_STEPS:
            raise SceneError(
                f"time.t_max / time.dt = {n:.3g} steps: too many (limit {MAX_STEPS:g})"
            )
        if abs(n - round(n)) > 1e-9 * n:
            raise SceneError(
                f"time.t_max = {t_max!r} is not a whole number of time steps: "
                f"time.t_max / time.dt = {n!r} must be an integer; use time.t_max = "
                f"{math.floor(n) * dt:.12g} or {math.ceil(n) * dt:.12g}, or a time.dt that "
                "divides it"
            )
        set_fields(self, t_max=t_max, dt=dt)

    @property
    def n_steps(self) -> int:
        return round(self.t_max / self.dt)


@dataclass(frozen=True)
class Output:
    """Fields written (a subset of OUTPUT_FIELDS) at t = 0, every ``every``-th step and t_max,
    stored with the given precision."""

    fields: tuple[str, ...] = DEFAULT_OUTPUT
    every: int = 1
    precision: str = "float32"

    def __post_init__(self) -> None:
        if not isinstance(self.fields, (list, tuple)):
            raise SceneError(
                f"output.fields: expected an array of strings, got {show(self.fields)}"
            )
        for i, name in enumerate(self.fields):
            choice(f"output.fields[{i}]", name, OUTPUT_FIELDS, close_fields(name, OUTPUT_FIELDS))
        if len(set(self.fields)) != len(self.fields):
            raise SceneError(f"output.fields = {list(self.fields)} names a field twice")
        integer("output.every", self.every, 1, int(MAX_STEPS))
        choice("output.precision", self.precision, ("float32", "float64"))
        set_fields(self, fields=tuple(self.fields))


@dataclass(frozen=True)
class Accuracy:
    """The accuracy preset the knobs came from, the cell-problem resolution (P2 elements across
    a wall), the rounding of their inputs and the surrogate's relative error (0: every distinct
    input solved exactly) and its interpolant: "bilinear" (the default) or "c1"
    (docs/surrogate_c1.md)."""

    preset: str = DEFAULT_PRESET
    cell_resolution: int = knob(DEFAULT_PRESET, "accuracy", "cell_resolution")
    key_tolerance: float = 1e-6
    cell_tolerance: float = knob(DEFAULT_PRESET, "accuracy", "cell_tolerance")
    cell_interpolant: str = "bilinear"

    def __post_init__(self) -> None:
        choice("accuracy.preset", self.preset, tuple(PRESETS))
        choice("accuracy.cell_interpolant", self.cell_interpolant, CELL_INTERPOLANTS)
        integer("accuracy.cell_resolution", self.cell_resolution, 1, MAX_RESOLUTION)
        tol = in_range("accuracy.key_tolerance", self.key_tolerance, 0.0, 1e-2, hi_open=False)
        cell = in_range("accuracy.cell_tolerance", self.cell_tolerance, 0.0, 0.1, False, False)
        set_fields(self, key_tolerance=tol, cell_tolerance=cell)


@dataclass(frozen=True)
class Solver:
    """The macro problem's linear solver: "direct", "iterative" or "auto" (iterative from
    ``macro_threshold`` fine dofs on); the iterative solve stops at the true relative residual
    ``macro_rtol``, or with ``macro_spare_iterations`` = n > 0 at ``macro_rtol / SPARE_FACTOR``
    unless it has taken n iterations (then at ``macro_rtol``: plantgrowth.models.linear.
    SpareAccuracy)."""

    macro: str = "auto"
    macro_threshold: int = MACRO_THRESHOLD
    macro_rtol: float = MACRO_RTOL
    macro_spare_iterations: int = 0

    def __post_init__(self) -> None:
        choice("solver.macro", self.macro, MACRO_SOLVERS)
        integer("solver.macro_threshold", self.macro_threshold, 0, 10**9)
        integer("solver.macro_spare_iterations", self.macro_spare_iterations,
                *SPARE_ITERATIONS_RANGE)  # fmt: skip
        rtol = in_range("solver.macro_rtol", self.macro_rtol, *MACRO_RTOL_RANGE, False, False)
        set_fields(self, macro_rtol=rtol)

    def macro_kind(self, ndofs: int) -> str:
        """The solver kind, "direct" or "iterative", for a macro problem of ``ndofs`` dofs."""
        if self.macro != "auto":
            return self.macro
        return "iterative" if ndofs >= self.macro_threshold else "direct"


INSTABILITY_ACTIONS = ("stop", "warn")


@dataclass(frozen=True)
class Numerics:
    """What the run does where the walls' law loses strong ellipticity on a connected set larger
    than one cell (the walls would buckle: plantgrowth.models.stability; smaller sets are
    singular points, reported, never a stop): "stop" (a named error after the step is written)
    or "warn" (when it appears and each time its area doubles, and go on)."""

    on_instability: str = "stop"

    def __post_init__(self) -> None:
        choice("numerics.on_instability", self.on_instability, INSTABILITY_ACTIONS)


def load_component(
    key: str, x: object, length: float, along: bool, constants: dict[str, float]
) -> edge_loads.Component:
    """A number, or (on an edge of the rectangle, ``along``) {expr = "..."} of s and the named
    parameters ``constants`` (plantgrowth/scene/loads.py), checked along the edge."""
    if isinstance(x, dict):
        if not along:
            raise SceneError(
                f"{key}: a load on an outline or mesh edge is a number; expressions of s, the "
                "coordinate along the edge, are defined on the rectangle's left, right and top"
            )
        check_keys(x, f"{key}.", ("expr",))
        if "expr" not in x:
            raise SceneError(f'{key}: a load component is a number or {{expr = "..."}} of s')
        x = parse_expression(f"{key}.expr", x["expr"], edge_loads.VARIABLES, constants)
    if not isinstance(x, Expression):
        return in_range(key, x, -BIG, BIG, False, False)
    edge_loads.check_component(key, x, length, BIG)
    return x


def edge_load(
    edge: str, raw: object, length: float, constants: dict[str, float]
) -> edge_loads.Load:
    """``loads.<edge>``: a traction ``[f1, f2]`` (each a number or, on the rectangle's edges,
    ``{expr = "..."}`` of s and the named parameters ``constants``) or a total force
    ``{force = [F1, F2]}`` (scene/loads.py)."""
    key = f"loads.{edge}"
    if isinstance(raw, edge_loads.EdgeForce):  # already checked (a scene rebuilt by replace)
        return raw
    if isinstance(raw, dict):
        check_keys(raw, f"{key}.", ("force",))
        if "force" not in raw:
            raise SceneError(
                f"{key}: a load is a traction [f1, f2] or a total force {{force = [F1, F2]}}"
            )
        force = array(f"{key}.force", raw["force"], 2)
        return edge_loads.EdgeForce(
            tuple(in_range(f"{key}.force[{i}]", x, -BIG, BIG, False, False)
                  for i, x in enumerate(force))
        )  # fmt: skip
    along = edge in edge_loads.ALONG  # s is defined on the rectangle's edges only
    return tuple(
        load_component(f"{key}[{i}]", x, length, along, constants)
        for i, x in enumerate(array(key, raw, 2))
    )


def check_edge(edge: str, shape: Shape | None) -> None:
    """SceneError unless ``loads.<edge>`` names a loadable edge of the tissue."""
    if shape is not None:
        if why := unloadable(shape, edge):
            raise SceneError(why)
        return
    if edge == "bottom":
        raise SceneError(
            "loads.bottom: the bottom edge x2 = 0 is the symmetry plane (u2 = 0, no tangential "
            f"traction) and cannot be loaded; loadable edges: {', '.join(EDGES)}"
        )
    if edge not in EDGES:
        raise SceneError(f"unknown key 'loads.{edge}' (valid keys: {', '.join(EDGES)})")


def held_edge(edge: str, kind: object, tissue: Tissue, loads: dict) -> tuple[int, ...]:
    """``supports.<edge> = kind``: the components of u it holds at zero (0: u1, 1: u2;
    docs/model.md section 4): "clamped" both, "roller" the normal one of an edge parallel to x1
    or x2. SceneError for an edge the tissue does not have, an unknown kind, an edge that is also
    in ``loads`` and a roller that is not one (inclined, or on x2 = 0, which is one already)."""
    key = f"supports.{edge}"
    axes = tissue.normal_axes()
    if edge not in axes:
        shape = f"{tissue.shape.key}: " if tissue.shape is not None else ""
        raise SceneError(f"unknown key '{key}' ({shape}edges that can be held: {', '.join(axes)})")
    choice(key, kind, SUPPORTS)
    if edge in loads:
        raise SceneError(
            f"{key} = {kind!r}: edge {edge!r} is also loaded (loads.{edge}): a held edge takes "
            "whatever force holds it in place; hold the edge or load it, not both"
        )
    if kind == "clamped":
        return (0, 1)
    if edge in tissue.symmetry_edges:
        raise SceneError(
            f"{key} = 'roller': edge {edge!r} lies on the symmetry plane x2 = 0, which holds u2 = "
            "0 already (it is a roller); 'clamped' holds u1 = 0 there too"
        )
    if axes[edge] is None:
        raise SceneError(
            f"{key} = 'roller': edge {edge!r} is parallel to neither x1 nor x2; a roller holds "
            "the normal displacement of an edge parallel to an axis (u1 = 0 on an edge parallel "
            "to x2, u2 = 0 on one parallel to x1); hold an inclined edge with 'clamped'"
        )
    return (axes[edge],)
