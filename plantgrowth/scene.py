"""Scenes: one TOML file describes one simulation (MODEL.md sections 4-6 and 9).

Every table and key is optional and defaults to the reference scene of MODEL.md section 9,
except ``growth.law``. Unknown keys, wrong types, NaN/inf and out-of-range values are errors
(:class:`SceneError`) whose message starts with the dotted key, e.g. ``material.nu = 0.5 is out
of range: ...``. Integers are accepted for floats. Everything is non-dimensional (wall E = 1,
inclined wall length l2 = 1)::

    model = "macro"            # "macro" | "micro" | "both"
    kinematics = "linear"      # "linear": the paper's eps_el; "finite": F = Fe Fg, Green-Lagrange
                               # Ee, Newton's method (MODEL.md 10, docs/finite_kinematics.md)
    [tissue]                   # the rectangle [0, width] x [0, height]; x2 = 0 is a symmetry plane
    width = 6.928203230275509  # 8 cos(30 deg), at most 1e6
    height = 3.0               # at most 1e6
    # or outline = [[x1, x2], ...]: a simple polygon (3 to 500 points, either orientation, in
    #   [0, 1e6]^2) with at least one edge on x2 = 0; edge i runs from point i to point i + 1
    #   and is loaded as loads.edge<i> (not the edges on x2 = 0)
    # or mesh = "file.msh": a gmsh mesh (relative to the scene file) with the curve group
    #   "symmetry" on x2 = 0, the point group "pinned" and named curve groups, loaded as
    #   loads.<name>
    # (docs/shapes.md; not with width or height: the shape's bounding box sets them)
    h = 0.1                    # (preset) fine-mesh edge: 0 < h <= min(width, height)/2,
                               # at most 4e6 cells
    H = 0.5                    # (preset) coarse-mesh edge (cell-problem nodes):
                               # h <= H <= max(width, height)
    [cell]                     # honeycomb unit cell, MODEL.md section 2
    l1 = 1.0                   # vertical wall length, > 0
    l2 = 1.0                   # inclined wall length, > 0
    theta = 30.0               # inclined wall angle in degrees, in (0, 90)
    w = 0.05                   # one cell's own wall thickness, > 0 and leaving a void
    [material]                 # wall material, MODEL.md section 1
    E = 1.0                    # Young modulus, > 0
    nu = 0.3                   # Poisson ratio, in (-1, 0.5)
    [pressure]
    P1 = 0.001                 # turgor pressure, >= 0 (MODEL.md section 6)
    [growth]                   # growth law, MODEL.md section 4
    law = "stress"             # REQUIRED: "stress" | "strain" | "none"
    eta = 1.0                  # extensibility, >= 0
    tau = 0.0                  # yield threshold, >= 0
    clamp = 1.0                # M: G is clipped component-wise to [-M, M], M > 0
    Fg0 = [[1.0, 0.0], [0.0, 1.0]]  # initial growth tensor, finite entries (numbers or
                               # fields), det > 0 wherever it is used
    [time]
    t_max = 60.0               # end time, a whole number (<= 1e6) of steps dt
    dt = 1.0                   # (preset) time step, > 0
    integrator = "exp"         # (preset) "exp": Fg <- expm(dt G) Fg (det Fg >= 1); "euler":
                               # the paper's Fg <- Fg + dt G Fg; "adaptive": exp with step
                               # doubling (below)
    tolerance = 1e-3           # adaptive: largest relative local error of Fg per step, (0, 0.1]
    [loads]                    # traction f on an edge (default none); "bottom" cannot be loaded
    right = [0.0, 0.0]         # also "left", "top"; an outline's "edge<i>", a mesh's group names;
                               # on left/right/top a component may be {expr = "..."} of s, the
                               # coordinate along the edge (x2 on left/right, x1 on top)
    [output]
    fields = ["u", "Fg", "G", "sigma_hom", "E_hom"]  # any of these, "eps_hom" and the growth
                               # outputs (docs/outputs.md), computed only when listed:
                               # "trG" (tr G, areal growth rate), "growth_anisotropy"
                               # ((g1 - g2)/(|g1| + |g2|) of G's principal rates g1 >= g2, in
                               # [0, 1], 0 when both vanish), "growth_direction" (unit vector of
                               # g1, x1 >= 0; zero vector where G is isotropic), "stress_direction"
                               # (same for sigma_hom; micro: the cells' mean wall stress).
                               # Micro runs write u, Fg, G, cell_id and the growth outputs
                               # listed, plus cells.csv and cells.xdmf (cell outlines)
    every = 1                  # fields at t = 0, every k-th step and t_max (summary.csv has
                               # every step), integer in [1, 1e6]
    precision = "float32"      # of the written fields: "float32" | "float64" (the resume
                               # state is float64 either way)
    [accuracy]
    preset = "balanced"        # "draft" | "balanced" | "fine": sets the keys marked (preset)
    cell_resolution = 2        # (preset) P2 elements across a cell wall, integer in [1, 64]
    key_tolerance = 1e-6       # cell-problem inputs are rounded to this before caching, (0, 1e-2]
    cell_tolerance = 1e-3      # (preset) surrogate's relative error of the homogenized tensors,
                               # [0, 0.1] (0: solve every distinct input exactly; surrogate.py)
    [micro]
    nx = 16                    # cells per row of the micro model, even integer in [2, 256]
    resolution = 2             # P2 elements across one cell's own wall, integer in [1, 64]
    [solver]                   # linear solvers: speed only, results agree to the solver tolerance
    macro = "auto"             # "direct" (LU), "iterative" (CG + GAMG, true relative residual
                               # <= 1e-10) or "auto": iterative from macro_threshold fine dofs on
    macro_threshold = 200000   # fine dofs (2 per node) where "auto" switches, integer in [0, 1e9]

The x1 forces of the loads must balance (only the pinned point, the origin of the rectangle,
holds the tissue along x1): the sum over the loaded edges of ``f[0]`` times the edge's length is
0 to a relative 1e-6. With an outline or mesh the pinned point is the bottom-left-most vertex on
x2 = 0 or the mesh's "pinned" point, coarse nodes outside the tissue get no cell problem, and
only ``model = "macro"`` is possible (the micro model builds its own honeycomb tissue).

Keys marked (preset) take the value of ``accuracy.preset`` (plantgrowth/presets.py; the values
shown are ``balanced``'s) unless the scene gives them; the preset's ``h`` and ``H`` are clipped
to the tissue (``h <= min(width, height)/2``, ``h <= H <= max(width, height)``).

The keys of ``[cell]``, ``[material]``, ``pressure.P1``, ``growth.eta``, ``growth.tau`` and each
entry of ``growth.Fg0`` are *fields* (docs/fields.md):

- a number;
- ``{from = a, to = b}`` (``along = "x1"``, the default) or ``{from = a, to = b, along = "x2"}``:
  linear from a at 0 to b at the end of the tissue simulated along that axis (MODEL.md sections
  7, 9): the macro rectangle's width or height, the cellular tissue's own extent for micro runs
  and the macro side of ``both`` and ``compare``, so a field never leaves [a, b];
- ``{expr = "..."}``: an expression of x1 and x2 (plantgrowth/expression.py: numbers, pi,
  ``+ - * / **``, parentheses, comparisons, exp log sqrt sin cos tanh abs min max and
  ``where(cond, a, b)``; never Python's eval), in absolute coordinates.

A number's and a linear field's range is checked at its ends when the scene is built, the cell
geometry at the ends and middle of each axis a field varies along. A non-constant expression, or
a varying Fg0, is checked where the run uses it (plantgrowth/field_checks.py): at every coarse node
and fine cell of the macro domain and at every cell centre of a micro tissue, before anything is
written; the error names the key, the place (x1, x2) and the range. Magnitudes above 1e12 (1e6
for lengths and Fg0) are rejected as typos: the model is non-dimensional with reference values of
order 1.

Load with :func:`load_scene` (a file) or :func:`parse_scene` (a dict); ``Scene.to_toml()``
writes the fully resolved scene, which loads back to an equal ``Scene``.
"""

from __future__ import annotations

import difflib
import json
import math
import os
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from plantgrowth import loads as edge_loads
from plantgrowth.errors import InputError, SceneError, check_growth_tensor, check_number
from plantgrowth.expression import Expression, parse_expression
from plantgrowth.fields import AXES, AnyField, ExprField, Field
from plantgrowth.meshes.honeycomb import GeometryError, HoneycombCell
from plantgrowth.meshes.tissue import MAX_NX as TISSUE_MAX_NX
from plantgrowth.meshes.tissue import TissueLayout, wall_mesh_size
from plantgrowth.meshes.unit_cell import mesh_size
from plantgrowth.plausibility import unbalanced_load
from plantgrowth.presets import DEFAULT_PRESET, PRESETS, knob
from plantgrowth.shapes import Shape, mesh_shape, outline_points, outline_shape, unloadable

BIG = 1e12
"""Largest magnitude accepted for a non-dimensional parameter without a natural bound."""
MAX_LENGTH = 1e6  # tissue and cell lengths, |Fg0 entries|
MAX_CELLS = 4e6  # triangles of the fine mesh
MAX_STEPS = 1e6  # t_max / dt
MAX_RESOLUTION = 64  # accuracy.cell_resolution
MAX_NX = TISSUE_MAX_NX  # micro.nx
LAWS = ("stress", "strain", "none")
INTEGRATORS = ("euler", "exp", "adaptive")
MODELS = ("macro", "micro", "both")
KINEMATICS = ("linear", "finite")
MACRO_SOLVERS = ("auto", "direct", "iterative")
MACRO_THRESHOLD = 200_000
"""Fine dofs from which ``solver.macro = "auto"`` solves iteratively: where CG + GAMG's time per
step meets LU's on the E-gradient scene, 1 rank (measured 1.96e5; scripts/scaling.py)."""
GROWTH_FIELDS = ("trG", "growth_anisotropy", "growth_direction", "stress_direction")
"""Outputs derived from G and sigma_hom (plantgrowth/growth_fields.py, docs/outputs.md)."""
OUTPUT_FIELDS = ("u", "Fg", "G", "sigma_hom", "E_hom", "eps_hom", *GROWTH_FIELDS)
DEFAULT_OUTPUT = ("u", "Fg", "G", "sigma_hom", "E_hom")
EDGES = ("left", "right", "top")
RANGES = {
    "cell.l1": (0.0, MAX_LENGTH, True, False),
    "cell.l2": (0.0, MAX_LENGTH, True, False),
    "cell.theta": (0.0, 90.0, True, True),
    "cell.w": (0.0, MAX_LENGTH, True, False),
    "material.E": (0.0, BIG, True, False),
    "material.nu": (-1.0, 0.5, True, True),
    "pressure.P1": (0.0, BIG, False, False),
    "growth.eta": (0.0, BIG, False, False),
    "growth.tau": (0.0, BIG, False, False),
}
"""Each field's interval (low, high, low end open, high end open), checked wherever it is used."""
FG0_RANGE = (-MAX_LENGTH, MAX_LENGTH, False, False)
"""The interval of each entry of growth.Fg0 (and det Fg0 > 0)."""
IDENTITY = ((1.0, 0.0), (0.0, 1.0))
REFERENCE_WIDTH = 4.0 * math.sqrt(3.0)  # = 8 cos(30 deg), exactly rounded
"""Reference tissue width 8c = 6.928203230275509 (MODEL.md section 9)."""


# --- checks shared by the dataclasses and the loader ----------------------------------------------


def _show(value: object) -> str:
    kind = {dict: "a table ", list: "an array ", tuple: "an array "}.get(type(value), "")
    text = repr(value)
    return kind + (text if len(text) <= 60 else text[:57] + "...")


def _number(key: str, value: object) -> float:
    """``value`` as a float (ints accepted), else SceneError naming ``key``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"{key}: expected a number, got {_show(value)}")
    try:
        return float(value)
    except OverflowError:  # a TOML integer beyond the float range
        raise SceneError(f"{key} = {str(value)[:12]}... is out of range: far too large") from None


def _range(key: str, value: object, low: float, high: float, lo_open=True, hi_open=True) -> float:
    """A finite number in the interval (open or closed ends), else SceneError naming ``key``."""
    _number(key, value)  # the type and float-range check, with the key
    try:  # the user's own value (e.g. 0, not 0.0) in the message
        return check_number(key, value, low, high, lo_open, hi_open)
    except InputError as e:
        raise SceneError(str(e)) from None


def _integer(key: str, value: object, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise SceneError(f"{key}: expected an integer, got {_show(value)}")
    if not low <= value <= high:
        raise SceneError(
            f"{key} = {value} is out of range: it must be an integer in [{low}, {high}]"
        )
    return value


def _choice(key: str, value: object, choices: tuple[str, ...]) -> str:
    options = ", ".join(map(repr, choices))
    if not isinstance(value, str):
        raise SceneError(f"{key}: expected a string (one of {options}), got {_show(value)}")
    if value not in choices:
        raise SceneError(f"{key} = {value!r} is invalid: it must be one of {options}")
    return value


def _array(key: str, value: object, n: int) -> list | tuple:
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise SceneError(f"{key}: expected an array of {n} items, got {_show(value)}")
    return value


def _set(obj: object, **values: object) -> None:
    """Store normalised values in a frozen dataclass."""
    for name, value in values.items():
        object.__setattr__(obj, name, value)


# --- the scene ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Tissue:
    """The tissue: the rectangle [0, width] x [0, height], or an ``outline`` polygon or a
    ``mesh`` file whose bounding box sets width and height (plantgrowth/shapes.py); the fine (h)
    and coarse (H) mesh sizes."""

    width: float = REFERENCE_WIDTH
    height: float = 3.0
    h: float = knob(DEFAULT_PRESET, "tissue", "h")
    H: float = knob(DEFAULT_PRESET, "tissue", "H")
    outline: tuple[tuple[float, float], ...] | None = None
    mesh: str | None = None
    shape: Shape | None = field(default=None, init=False, compare=False, repr=False)

    def __post_init__(self) -> None:
        if self.outline is not None and self.mesh is not None:
            raise SceneError("tissue.mesh: not with tissue.outline: give one tissue shape")
        try:
            if self.outline is not None:
                _set(self, outline=outline_points(self.outline))
                _set(self, shape=outline_shape(self.outline))
            elif self.mesh is not None:
                _set(self, shape=mesh_shape(self.mesh))
        except InputError as e:
            raise SceneError(str(e)) from None
        if self.shape is not None:  # the bounding box
            _set(self, width=self.shape.width, height=self.shape.height)
        W = _range("tissue.width", self.width, 0.0, MAX_LENGTH, hi_open=False)
        Ht = _range("tissue.height", self.height, 0.0, MAX_LENGTH, hi_open=False)
        h = _range("tissue.h", self.h, 0.0, min(W, Ht) / 2, hi_open=False)
        H = _range("tissue.H", self.H, h, max(W, Ht), lo_open=False, hi_open=False)
        given = self.shape.triangles if self.shape is not None else None
        cells = 2.0 * math.ceil(W / h) * math.ceil(Ht / h) if given is None else given
        if cells > MAX_CELLS:
            raise SceneError(
                f"tissue.mesh has {cells} triangles (limit {MAX_CELLS:g})"
                if given is not None
                else f"tissue.h = {h!r} is too small: the fine mesh would have about {cells:.3g} "
                f"triangles (limit {MAX_CELLS:g}); use h >= {math.sqrt(2 * W * Ht / MAX_CELLS):.3g}"
            )
        _set(self, width=W, height=Ht, h=h, H=H)

    def edge_lengths(self) -> dict[str, tuple[float, str]]:
        """Loadable edge -> (reference length, its name in the load-balance formula)."""
        if self.shape is None:
            return {
                "left": (self.height, "height"), "right": (self.height, "height"),
                "top": (self.width, "width"),
            }  # fmt: skip
        return {edge: (length, f"{length:.6g}") for edge, length in self.shape.edges.items()}

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
        return {"width": self.width, "height": self.height, "h": self.h, "H": self.H}


@dataclass(frozen=True)
class CellGeometry:
    """Honeycomb cell parameters (MODEL.md section 2); theta in degrees."""

    l1: AnyField
    l2: AnyField
    theta: AnyField
    w: AnyField

    def __post_init__(self) -> None:
        for key in ("l1", "l2", "theta", "w"):
            getattr(self, key).check(f"cell.{key}", *RANGES[f"cell.{key}"])
        if self.by_expression:
            return  # checked at the coarse nodes (plantgrowth.field_checks)
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
    """Wall Young modulus E > 0 and Poisson ratio -1 < nu < 0.5 (MODEL.md section 1)."""

    E: AnyField
    nu: AnyField

    def __post_init__(self) -> None:
        self.E.check("material.E", *RANGES["material.E"])
        self.nu.check("material.nu", *RANGES["material.nu"])


@dataclass(frozen=True)
class Growth:
    """Growth law (MODEL.md section 4): G = clip(eta [X / phi_w - tau]_+, -clamp, clamp).

    ``law`` is "stress" (X = sigma_hom), "strain" (X = eps_hom) or "none" (G = 0).
    """

    law: str
    eta: AnyField
    tau: AnyField
    clamp: float = 1.0
    Fg0: tuple[tuple[float | AnyField, ...], ...] = IDENTITY  # entries: numbers or fields

    def __post_init__(self) -> None:
        _choice("growth.law", self.law, LAWS)
        self.eta.check("growth.eta", *RANGES["growth.eta"])
        self.tau.check("growth.tau", *RANGES["growth.tau"])
        _set(self, clamp=_range("growth.clamp", self.clamp, 0.0, BIG, hi_open=False))
        rows = tuple(
            tuple(
                _Fg0_entry(f"growth.Fg0[{i}][{j}]", x)
                for j, x in enumerate(_array(f"growth.Fg0[{i}]", row, 2))
            )
            for i, row in enumerate(_array("growth.Fg0", self.Fg0, 2))
        )
        _set(self, Fg0=rows)
        if self.Fg0_fields():
            return  # det Fg0 > 0 is checked where Fg0 is used (plantgrowth.field_checks)
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
        """The growth fields across a tissue of another extent (MODEL.md 7)."""
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
    return _range(key, x, *FG0_RANGE)


@dataclass(frozen=True)
class Time:
    """Time interval [0, t_max] in n_steps steps dt; integrator "euler", "exp" or "adaptive"
    (exp with step-doubling control of the growth tensor's local error, ``tolerance``)."""

    t_max: float = 60.0
    dt: float = knob(DEFAULT_PRESET, "time", "dt")
    integrator: str = knob(DEFAULT_PRESET, "time", "integrator")
    tolerance: float = 1e-3

    def __post_init__(self) -> None:
        dt = _range("time.dt", self.dt, 0.0, BIG, hi_open=False)
        t_max = _range("time.t_max", self.t_max, 0.0, BIG, hi_open=False)
        _choice("time.integrator", self.integrator, INTEGRATORS)
        _range("time.tolerance", self.tolerance, 0.0, 0.1, hi_open=False)
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
        _set(self, t_max=t_max, dt=dt)

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
                f"output.fields: expected an array of strings, got {_show(self.fields)}"
            )
        for i, name in enumerate(self.fields):
            _choice(f"output.fields[{i}]", name, OUTPUT_FIELDS)
        if len(set(self.fields)) != len(self.fields):
            raise SceneError(f"output.fields = {list(self.fields)} names a field twice")
        _integer("output.every", self.every, 1, int(MAX_STEPS))
        _choice("output.precision", self.precision, ("float32", "float64"))
        _set(self, fields=tuple(self.fields))


@dataclass(frozen=True)
class Accuracy:
    """The accuracy preset the knobs came from, the cell-problem resolution (P2 elements across
    a wall), the rounding of their inputs and the surrogate's relative error (0: every distinct
    input solved exactly)."""

    preset: str = DEFAULT_PRESET
    cell_resolution: int = knob(DEFAULT_PRESET, "accuracy", "cell_resolution")
    key_tolerance: float = 1e-6
    cell_tolerance: float = knob(DEFAULT_PRESET, "accuracy", "cell_tolerance")

    def __post_init__(self) -> None:
        _choice("accuracy.preset", self.preset, tuple(PRESETS))
        _integer("accuracy.cell_resolution", self.cell_resolution, 1, MAX_RESOLUTION)
        tol = _range("accuracy.key_tolerance", self.key_tolerance, 0.0, 1e-2, hi_open=False)
        cell = _range("accuracy.cell_tolerance", self.cell_tolerance, 0.0, 0.1, False, False)
        _set(self, key_tolerance=tol, cell_tolerance=cell)


@dataclass(frozen=True)
class Solver:
    """The macro problem's linear solver: "direct", "iterative" or "auto" (iterative from
    ``macro_threshold`` fine dofs on)."""

    macro: str = "auto"
    macro_threshold: int = MACRO_THRESHOLD

    def __post_init__(self) -> None:
        _choice("solver.macro", self.macro, MACRO_SOLVERS)
        _integer("solver.macro_threshold", self.macro_threshold, 0, 10**9)

    def macro_kind(self, ndofs: int) -> str:
        """The solver kind, "direct" or "iterative", for a macro problem of ``ndofs`` dofs."""
        if self.macro != "auto":
            return self.macro
        return "iterative" if ndofs >= self.macro_threshold else "direct"


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
    loads: dict[str, tuple[edge_loads.Component, ...]] = field(default_factory=dict)
    output: Output = Output()
    accuracy: Accuracy = Accuracy()
    micro_nx: int = 16
    micro_resolution: int = 2
    solver: Solver = Solver()
    kinematics: str = "linear"

    def __post_init__(self) -> None:
        _choice("model", self.model, MODELS)
        _choice("kinematics", self.kinematics, KINEMATICS)
        self.P1.check("pressure.P1", *RANGES["pressure.P1"])
        for key, f in (self.parameter_fields() | self.growth.Fg0_fields()).items():
            if isinstance(f, Field) and f.width != self.tissue.width:
                raise SceneError(f"{key}: field width {f.width!r} != tissue.width")
            if isinstance(f, Field) and f.height != self.tissue.height:
                raise SceneError(f"{key}: field height {f.height!r} != tissue.height")
        loads = {}
        lengths = self.tissue.edge_lengths()
        for edge, f in self.loads.items():
            _check_edge(edge, self.tissue.shape)
            pair = _array(f"loads.{edge}", f, 2)
            along = edge in edge_loads.ALONG  # s is defined on the rectangle's edges only
            pair = tuple(
                _load_component(f"loads.{edge}[{i}]", x, lengths[edge][0], along)
                for i, x in enumerate(pair)
            )
            if pair != (0.0, 0.0):  # only non-zero loads are kept
                loads[edge] = pair
        _set(self, loads=loads)
        if _integer("micro.nx", self.micro_nx, 2, MAX_NX) % 2:
            raise SceneError(f"micro.nx = {self.micro_nx} is invalid: it must be even")
        _integer("micro.resolution", self.micro_resolution, 1, MAX_RESOLUTION)
        try:  # the unit-cell meshes at the corners must be affordable (expressions: field_checks)
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
        if loads and (unbalanced := unbalanced_load(loads, lengths, self.tissue.pin, fix)):
            raise SceneError(unbalanced)

    def corners(self) -> list[tuple[float, float]]:
        """The tissue rectangle's corners (x1, x2)."""
        return [(x1, x2) for x1 in (0.0, self.tissue.width) for x2 in (0.0, self.tissue.height)]

    def check_micro(self) -> None:
        """The micro model needs a constant cell geometry (a gradient of w, l1, l2 or theta has no
        well-defined cellular tissue: MODEL.md section 7, paper section 5.3), builds its own
        tissue (no outline or mesh) and has no loads."""
        if self.tissue.shape is not None:
            raise SceneError(
                f"{self.tissue.shape.key}: the micro model builds its own honeycomb tissue "
                f'(MODEL.md section 7); use model = "macro"'
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
        try:  # the walls mesh must be affordable
            wall_mesh_size(
                TissueLayout(self.cell.at(0.0, 0.0), self.micro_nx), self.micro_resolution
            )
        except GeometryError as e:
            raise SceneError(str(e)) from None

    def over_extent(self, width: float, height: float) -> Scene:
        """This scene on a tissue of extent [0, width] x [0, height] (a micro tissue, or the
        macro side of a micro-macro comparison): every linear field runs from its ``from`` value
        at 0 to its ``to`` value at the extent along its axis, never extrapolated (MODEL.md
        section 7); expressions are unchanged. Revalidated."""
        if (width, height) == (self.tissue.width, self.tissue.height):
            return self

        def over(f: AnyField) -> AnyField:
            return f.over(width, height)

        cell = CellGeometry(*(over(f) for f in self.cell.fields()))
        material = Material(over(self.material.E), over(self.material.nu))
        return replace(
            self, tissue=replace(self.tissue, width=width, height=height), cell=cell,
            material=material, P1=over(self.P1), growth=self.growth.over(width, height),
        )  # fmt: skip

    def parameter_fields(self) -> dict[str, AnyField]:
        """All spatially varying parameters by dotted key."""
        cell, mat, g = self.cell, self.material, self.growth
        out = {f"cell.{k}": getattr(cell, k) for k in ("l1", "l2", "theta", "w")}
        return out | {
            "material.E": mat.E,
            "material.nu": mat.nu,
            "pressure.P1": self.P1,
            "growth.eta": g.eta,
            "growth.tau": g.tau,
        }

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
        out["loads"] = {edge: [edge_loads.to_toml(c) for c in f] for edge, f in self.loads.items()}
        out["output"] = {f.name: getattr(self.output, f.name) for f in fields(self.output)}
        out["accuracy"] = {f.name: getattr(self.accuracy, f.name) for f in fields(self.accuracy)}
        out["micro"] = {"nx": self.micro_nx, "resolution": self.micro_resolution}
        out["solver"] = {f.name: getattr(self.solver, f.name) for f in fields(self.solver)}
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
        header = "# plantgrowth scene, fully resolved (keys: see plantgrowth/scene.py)\n"
        return header + dict_to_toml(self.to_dict())


def dict_to_toml(data: dict[str, Any]) -> str:
    """TOML text of scene-like data: top-level values first, then one ``[table]`` per dict."""
    lines = [f"{k} = {_toml_value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    for key, value in data.items():
        if isinstance(value, dict):
            lines += ["", f"[{key}]"] + [f"{k} = {_toml_value(v)}" for k, v in value.items()]
    return "\n".join(lines) + "\n"


def _toml_value(v: Any) -> str:
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string is a valid TOML basic string
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(v)  # an int, or a float: repr round-trips exactly and is valid TOML


# --- loader ---------------------------------------------------------------------------------------

_TABLES = {
    "tissue": ("width", "height", "h", "H", "outline", "mesh"),
    "cell": ("l1", "l2", "theta", "w"),
    "material": ("E", "nu"),
    "pressure": ("P1",),
    "growth": ("law", "eta", "tau", "clamp", "Fg0"),
    "time": ("t_max", "dt", "integrator", "tolerance"),
    "loads": EDGES,
    "output": ("fields", "every", "precision"),
    "accuracy": ("preset", "cell_resolution", "key_tolerance", "cell_tolerance"),
    "micro": ("nx", "resolution"),
    "solver": ("macro", "macro_threshold"),
}
_FIELD_DEFAULTS = {
    "cell": {"l1": 1.0, "l2": 1.0, "theta": 30.0, "w": 0.05},
    "material": {"E": 1.0, "nu": 0.3},
    "pressure": {"P1": 0.001},
    "growth": {"eta": 1.0, "tau": 0.0},
}


def _load_component(key: str, x: object, length: float, along: bool) -> edge_loads.Component:
    """A number, or (on an edge of the rectangle, ``along``) {expr = "..."} of s
    (plantgrowth/loads.py), checked along the edge."""
    if isinstance(x, dict):
        if not along:
            raise SceneError(
                f"{key}: a load on an outline or mesh edge is a number; expressions of s, the "
                "coordinate along the edge, are defined on the rectangle's left, right and top"
            )
        _check_keys(x, f"{key}.", ("expr",))
        if "expr" not in x:
            raise SceneError(f'{key}: a load component is a number or {{expr = "..."}} of s')
        x = parse_expression(f"{key}.expr", x["expr"], edge_loads.VARIABLES)
    if not isinstance(x, Expression):
        return _range(key, x, -BIG, BIG, False, False)
    edge_loads.check_component(key, x, length, BIG)
    return x


def _check_edge(edge: str, shape: Shape | None) -> None:
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


def _check_keys(table: dict, path: str, valid: tuple[str, ...]) -> None:
    for key in table:
        if key not in valid:
            elsewhere = [f"{t}.{key}" for t, keys in _TABLES.items() if key in keys]  # wrong table
            close = elsewhere if path.count(".") <= 1 else []
            close = close or difflib.get_close_matches(key, valid, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            raise SceneError(f"unknown key '{path}{key}' (valid keys: {', '.join(valid)}){hint}")


def _table(data: dict, name: str) -> dict:
    """The top-level table ``name`` ({} if absent), its keys checked."""
    table = data.get(name, {})
    if not isinstance(table, dict):
        raise SceneError(f"{name}: expected a table [{name}], got {_show(table)}")
    if name != "loads":  # the loadable edges depend on the tissue: Scene checks them
        _check_keys(table, f"{name}.", _TABLES[name])
    return table


def _tissue_box(tissue: dict) -> tuple[float, float]:
    """(width, height) of a tissue table: the rectangle's, or the bounding box of its outline
    or mesh (which may not be given with width or height)."""
    shapes = [key for key in ("outline", "mesh") if key in tissue]
    if not shapes:
        width = tissue.get("width", REFERENCE_WIDTH)
        return (
            _range("tissue.width", width, 0.0, MAX_LENGTH, hi_open=False),
            _range("tissue.height", tissue.get("height", 3.0), 0.0, MAX_LENGTH, hi_open=False),
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
        raise SceneError(f"tissue.mesh: expected a string (a .msh file path), got {_show(value)}")
    return os.path.abspath(directory / value)


def _field(key: str, raw: object, width: float, height: float) -> AnyField:
    """A field value: a number, {from = a, to = b[, along = "x1" | "x2"]} or {expr = "..."}."""
    if isinstance(raw, dict):
        _check_keys(raw, f"{key}.", ("from", "to", "along", "expr"))
        if "expr" in raw:
            if len(raw) != 1:
                raise SceneError(f'{key}: an expression field is {{expr = "..."}} alone')
            return ExprField(parse_expression(f"{key}.expr", raw["expr"], AXES))
        if "from" not in raw or "to" not in raw:
            raise SceneError(f"{key}: a linear field needs both ends, {{from = a, to = b}}")
        along = _choice(f"{key}.along", raw.get("along", "x1"), AXES)
        start, end = _number(f"{key}.from", raw["from"]), _number(f"{key}.to", raw["to"])
        return Field(start, end, width, height, along)
    if isinstance(raw, bool) or not isinstance(raw, (int, float)):
        raise SceneError(
            f'{key}: expected a number, {{from = a, to = b}} or {{expr = "..."}}, got '
            f"{_show(raw)}"
        )
    return Field(_number(key, raw), _number(key, raw), width, height)


def _with_preset(tables: dict[str, dict]) -> dict[str, dict]:
    """The tables with every knob of ``accuracy.preset`` the scene leaves out filled in; the
    preset's h and H clipped to the tissue (the scene's own values are never changed)."""
    name = _choice(
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
        h = _range("tissue.h", tissue["h"], 0.0, min(width, height) / 2, hi_open=False)
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
        raise SceneError(f"scene: expected a table of tables, got {_show(data)}")
    _check_keys(data, "", ("model", *_TABLES, "kinematics"))
    tables = {name: _table(data, name) for name in _TABLES}
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
