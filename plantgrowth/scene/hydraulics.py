"""Water fluxes, ``[hydraulics]`` (docs/model.md, water fluxes): turgor becomes an unknown that
water entering the cells sets. The key reference is :mod:`plantgrowth.scene`::

    [hydraulics]
    osmotic = 0.001            # Pi, a field >= 0; replaces pressure.P1 (not with it)
    conductivity = 1.0         # L, a field >= 0: water area per time, length of shared wall
                               # and unit difference of psi = P - Pi
    initial_potential = 0.0    # psi_0: every cell starts in equilibrium with it (P = Pi + psi_0)
    [[hydraulics.supply]]      # any number of supplies, each an edge or a region, once each
    edge = "left"              # an edge of the tissue ("left", "right", "top"; outline and mesh
                               # edges as [loads] names them); not the symmetry plane x2 = 0
    potential = 0.0            # psi_s (default 0), or in time: {times = [0, 30], values = [0,
                               # -0.0005]} (interpolation = "step" (default) or "linear")
    conductance = 1.0          # L_s > 0: per unit grown edge length
    [[hydraulics.supply]]
    region = "strand"          # a name of [regions]
    conductance = 0.5          # L_r > 0: per unit grown area

A potential in time is ``values[i]`` from ``times[i]`` on ("step": a drought lowered at once)
or linear between the times ("linear"); before the first time, ``values[0]``; after the last,
the last value. Backward Euler reads it at the end of each step (of each sub-step with the
adaptive integrator).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

from plantgrowth.base.errors import SceneError
from plantgrowth.scene.field_syntax import parse_field
from plantgrowth.scene.fields import AnyField
from plantgrowth.scene.limits import BIG, RANGES, WATER_FIELDS
from plantgrowth.scene.values import check_keys, choice, in_range, show

if TYPE_CHECKING:
    from plantgrowth.scene.parts import Tissue

KEYS = ("osmotic", "conductivity", "initial_potential", "supply")
SUPPLY_KEYS = ("edge", "region", "potential", "conductance")
INTERPOLATIONS = ("step", "linear")
MAX_TIMES = 10_000
DEFAULT_OSMOTIC = 0.001  # the reference turgor, pressure.P1's default


@dataclass(frozen=True)
class Potential:
    """A supply's water potential psi_s(t): ``values[i]`` from ``times[i]`` on ("step") or
    linear between the times ("linear"); constant outside [times[0], times[-1]]."""

    times: tuple[float, ...]
    values: tuple[float, ...]
    interpolation: str = "step"

    def __call__(self, t: float) -> float:
        """psi_s at time t."""
        i = bisect.bisect_right(self.times, t) - 1
        if i < 0:
            return self.values[0]
        if i == len(self.times) - 1 or self.interpolation == "step":
            return self.values[i]
        t0, t1, v0, v1 = *self.times[i : i + 2], *self.values[i : i + 2]
        return v0 + (v1 - v0) * (t - t0) / (t1 - t0)

    @property
    def is_constant(self) -> bool:
        return len(set(self.values)) == 1

    def to_toml(self) -> float | dict[str, Any]:
        if len(self.times) == 1:
            return self.values[0]
        out = {"times": list(self.times), "values": list(self.values)}
        return out | {"interpolation": self.interpolation}


@dataclass(frozen=True)
class Supply:
    """Water at ``potential`` reaching an edge (conductance per unit grown edge length) or a
    region's cells (per unit grown area): ``kind`` is "edge" or "region", ``name`` its name."""

    kind: str
    name: str
    potential: Potential
    conductance: float

    @property
    def label(self) -> str:
        """``edge.<name>`` or ``region.<name>`` (summary.csv's ``inflow.<label>``)."""
        return f"{self.kind}.{self.name}"

    def to_toml(self) -> dict[str, Any]:
        return {self.kind: self.name, "potential": self.potential.to_toml(),
                "conductance": self.conductance}  # fmt: skip


@dataclass(frozen=True)
class Hydraulics:
    """Osmotic pressure Pi and wall conductivity L (fields), the initial water potential psi_0
    and the supplies (docs/model.md, water fluxes)."""

    osmotic: AnyField
    conductivity: AnyField
    initial_potential: float = 0.0
    supplies: tuple[Supply, ...] = ()

    def __post_init__(self) -> None:
        for key, f in self.fields().items():
            f.check(key, *RANGES[key])

    def fields(self) -> dict[str, AnyField]:
        """The fields by dotted key."""
        return {"hydraulics.osmotic": self.osmotic, "hydraulics.conductivity": self.conductivity}

    def over(self, width: float, height: float) -> Hydraulics:
        """The fields across a tissue of another extent (docs/model.md section 7)."""
        return replace(
            self, osmotic=self.osmotic.over(width, height),
            conductivity=self.conductivity.over(width, height),
        )  # fmt: skip

    def regions(self) -> list[Supply]:
        return [s for s in self.supplies if s.kind == "region"]

    def to_toml(self) -> dict[str, Any]:
        return {
            "osmotic": self.osmotic.to_toml(), "conductivity": self.conductivity.to_toml(),
            "initial_potential": self.initial_potential,
            "supply": [s.to_toml() for s in self.supplies],
        }  # fmt: skip


def potential_from(key: str, raw: object) -> Potential:
    """A number, or ``{times = [...], values = [...], interpolation = "step" | "linear"}``
    with strictly increasing finite times >= 0 and finite values."""
    if not isinstance(raw, dict):
        value = in_range(key, raw, -BIG, BIG, False, False)
        return Potential((0.0,), (value,))
    check_keys(raw, f"{key}.", ("times", "values", "interpolation"))
    for name in ("times", "values"):
        if name not in raw:
            raise SceneError(
                f"{key}.{name} is required: a potential in time is {{times = [t0, t1, ...], "
                "values = [v0, v1, ...]}"
            )
        items = raw[name]
        if not isinstance(items, list) or not 1 <= len(items) <= MAX_TIMES:
            raise SceneError(
                f"{key}.{name}: expected an array of 1 to {MAX_TIMES} numbers, got {show(items)}"
            )
    times, values = raw["times"], raw["values"]
    if len(times) != len(values):
        raise SceneError(
            f"{key}: times has {len(times)} entries and values {len(values)}: one value per time"
        )
    times = tuple(in_range(f"{key}.times[{i}]", t, 0.0, BIG, False, False)
                  for i, t in enumerate(times))  # fmt: skip
    values = tuple(in_range(f"{key}.values[{i}]", v, -BIG, BIG, False, False)
                   for i, v in enumerate(values))  # fmt: skip
    for i in range(1, len(times)):
        if times[i] <= times[i - 1]:
            raise SceneError(
                f"{key}.times[{i}] = {times[i]!r} is not after times[{i - 1}] = "
                f"{times[i - 1]!r}: the times must increase strictly"
            )
    interpolation = choice(f"{key}.interpolation", raw.get("interpolation", "step"), INTERPOLATIONS)
    return Potential(times, values, interpolation)


def _supply(key: str, raw: object, edges: tuple[str, ...], symmetry: tuple[str, ...],
            regions: tuple[str, ...]) -> Supply:  # fmt: skip
    """One ``[[hydraulics.supply]]`` entry, its edge or region checked against the tissue."""
    if not isinstance(raw, dict):
        raise SceneError(
            f'{key}: a supply is a table {{edge = "left", conductance = 1.0}} or {{region = '
            f'"strand", conductance = 1.0}}, got {show(raw)}'
        )
    check_keys(raw, f"{key}.", SUPPLY_KEYS)
    given = [k for k in ("edge", "region") if k in raw]
    if len(given) != 1:
        raise SceneError(
            f"{key}: give one of edge (an edge of the tissue) or region (a name of [regions]), "
            f"{'not both' if given else 'none was given'}"
        )
    kind = given[0]
    name = raw[kind]
    if kind == "edge":
        if name in symmetry:
            raise SceneError(
                f"{key}.edge = {name!r} is the symmetry plane x2 = 0: the tissue continues "
                "below it as its mirror, so no water crosses it; supply a region there instead "
                '(e.g. [regions] base = {expr = "x2 < 0.5"})'
            )
        choice(f"{key}.edge", name, edges)
    else:
        if not regions:
            raise SceneError(
                f"{key}.region = {show(name)}: the scene has no [regions]; name one there, "
                'e.g. [regions] strand = {expr = "x1 < 1"}'
            )
        choice(f"{key}.region", name, regions)
    if "conductance" not in raw:
        raise SceneError(
            f"{key}.conductance is required: L_s > 0 per unit grown edge length (an edge) or "
            "L_r > 0 per unit grown area (a region)"
        )
    conductance = in_range(f"{key}.conductance", raw["conductance"], 0.0, BIG, True, False)
    return Supply(kind, name, potential_from(f"{key}.potential", raw.get("potential", 0.0)),
                  conductance)  # fmt: skip


def hydraulics_from(
    data: dict, tissue: Tissue, constants: dict[str, float], regions: tuple[str, ...]
) -> Hydraulics | None:
    """``[hydraulics]`` (None if the scene has none): SceneError naming the key for anything
    wrong, for ``pressure.P1`` given as well, and for an edge or region supplied twice."""
    if "hydraulics" not in data:
        return None
    table = data["hydraulics"]
    if not isinstance(table, dict):
        raise SceneError(f"hydraulics: expected a table [hydraulics], got {show(table)}")
    check_keys(table, "hydraulics.", KEYS)
    pressure = data.get("pressure")
    if isinstance(pressure, dict) and "P1" in pressure:
        raise SceneError(
            "pressure.P1: not with [hydraulics]: turgor is solved from the water the cells "
            "hold (docs/model.md, water fluxes); give the osmotic pressure hydraulics.osmotic "
            "(and hydraulics.initial_potential) instead"
        )
    if "conductivity" not in table:
        raise SceneError(
            "hydraulics.conductivity is required in [hydraulics]: L, a field >= 0 (water area "
            "per unit time, length of shared wall and difference of potential)"
        )
    width, height = tissue.width, tissue.height
    osmotic = parse_field(
        "hydraulics.osmotic", table.get("osmotic", DEFAULT_OSMOTIC), width, height, constants
    )
    conductivity = parse_field(
        "hydraulics.conductivity", table["conductivity"], width, height, constants
    )
    psi0 = in_range(
        "hydraulics.initial_potential", table.get("initial_potential", 0.0), -BIG, BIG,
        False, False,
    )  # fmt: skip
    raw = table.get("supply", [])
    if not isinstance(raw, list):
        raise SceneError(
            "hydraulics.supply: expected an array of tables [[hydraulics.supply]], got "
            f"{show(raw)}"
        )
    edges = tuple(tissue.normal_axes())
    symmetry = tissue.symmetry_edges
    supplies, seen = [], set()
    for i, entry in enumerate(raw):
        supply = _supply(f"hydraulics.supply[{i}]", entry, edges, symmetry, regions)
        if supply.label in seen:
            raise SceneError(
                f"hydraulics.supply[{i}].{supply.kind} = {supply.name!r} is supplied twice: "
                "give each edge and region once"
            )
        seen.add(supply.label)
        supplies.append(supply)
    return Hydraulics(osmotic, conductivity, psi0, tuple(supplies))


def turgor_input(scene: Any) -> AnyField | None:
    """The turgor input of ``scene`` (a Scene) with ``[hydraulics]``, Pi; None without;
    SceneError for a water field it does not write."""
    osmotic = None if scene.hydraulics is None else scene.hydraulics.osmotic
    check_water_fields(scene.output.fields, scene.hydraulics, scene.model)
    return osmotic


def check_water_fields(fields: tuple[str, ...], hydraulics: Hydraulics | None, model: str) -> None:
    """SceneError for an ``[output] fields`` water field (P, psi, water_flux) that the run does
    not write: they are the macro model's, with ``[hydraulics]`` (model = "macro" or "both")."""
    asked = [name for name in fields if name in WATER_FIELDS]
    if asked and (hydraulics is None or model == "micro"):
        where = (
            "the micro model writes each cell's P and psi in cells.csv"
            if hydraulics is not None
            else "give [hydraulics] (docs/usage.md, water fluxes) or remove them"
        )
        raise SceneError(
            f"output.fields: {asked} are the macro model's water fields, written with "
            f"[hydraulics] and model = 'macro' or 'both' (this scene: model = {model!r}"
            f"{'' if hydraulics is not None else ', no [hydraulics]'}); {where}"
        )
