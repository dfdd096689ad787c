"""The fibred walls and their feedback, parts of a scene validated in ``__post_init__`` (the key
reference: :mod:`plantgrowth.scene`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from plantgrowth.base.errors import SceneError
from plantgrowth.scene.field_syntax import parse_field
from plantgrowth.scene.fields import AnyField
from plantgrowth.scene.limits import (
    BIG,
    CUES,
    DEFAULT_OUTPUT,
    DIRECTOR_OUTPUT,
    FEEDBACK_OUTPUT,
    FEEDBACK_WALLS,
    RANGES,
)
from plantgrowth.scene.values import choice, in_range, set_fields

if TYPE_CHECKING:
    from plantgrowth.scene.parts import Tissue


@dataclass(frozen=True)
class Walls:
    """Fibre-reinforced walls (docs/model.md, fibre-reinforced walls): the wall tensor
    ``C_w = C_iso(E, nu) + E_f q (t_g x t_g x t_g x t_g)`` with ``E_f = fibre_stiffness * E``,
    the fibre weight ``q = (m . t_g)^2`` of a wall's grown tangent t_g and the director
    ``m = (cos a, sin a)``, ``a = fibre_angle`` (degrees from x1). Both are fields;
    ``fibre_stiffness`` the constant 0 is the paper's isotropic walls, and only then may
    ``fibre_angle`` be left out (there is no fibre direction to give)."""

    fibre_stiffness: AnyField
    fibre_angle: AnyField | None = None

    def __post_init__(self) -> None:
        for key, f in self.fields().items():
            f.check(key, *RANGES[key])
        if self.fibred and self.fibre_angle is None:
            raise SceneError(
                "walls.fibre_angle is required with walls.fibre_stiffness other than 0: the "
                "fibre direction, a field of degrees from x1 (finite, |a| <= 1e6)"
            )

    @property
    def fibred(self) -> bool:
        """False if ``fibre_stiffness`` is the constant 0: the paper's isotropic walls."""
        f = self.fibre_stiffness
        return not (f.is_constant and float(f(0.0, 0.0)) == 0.0)

    def fields(self) -> dict[str, AnyField]:
        """The walls' fields by dotted key (``walls.fibre_stiffness``, ``walls.fibre_angle``)."""
        out = {"walls.fibre_stiffness": self.fibre_stiffness}
        return out | ({} if self.fibre_angle is None else {"walls.fibre_angle": self.fibre_angle})

    def over(self, width: float, height: float) -> Walls:
        """The fibre fields across a tissue of another extent (docs/model.md section 7)."""
        angle = None if self.fibre_angle is None else self.fibre_angle.over(width, height)
        return Walls(self.fibre_stiffness.over(width, height), angle)


@dataclass(frozen=True)
class Feedback:
    """Mechanical feedback on the fibre director: ``da/dt = -(k A / 2) sin(2 (a - a_Q))``
    with k = ``rate`` >= 0, a_Q the principal direction of the ``cue`` tensor ("stress":
    sigma_hom, "strain": eps_hom) and A its anisotropy (plantgrowth/models/fibres.py). The micro
    model averages the cue over the ``walls`` around each cell, both halves of each ("around"),
    or over the cell's own halves only ("own": unstable cell by cell, docs/fibres.md)."""

    cue: str
    rate: float
    walls: str = "around"

    def __post_init__(self) -> None:
        choice("feedback.cue", self.cue, CUES)
        choice("feedback.walls", self.walls, FEEDBACK_WALLS)
        set_fields(self, rate=in_range("feedback.rate", self.rate, 0.0, BIG, False, False))


def walls_from(
    data: dict, table: dict, tissue: Tissue, constants: dict[str, float]
) -> Walls | None:
    """``[walls]`` (None if the scene has none): fibre_stiffness (required) and fibre_angle,
    fields of x1, x2 and the named parameters ``constants``."""
    if "walls" not in data:
        return None
    if "fibre_stiffness" not in table:
        raise SceneError(
            "walls.fibre_stiffness is required in [walls]: E_f / E, a field >= 0 (0: the "
            "paper's isotropic walls); without it the fibre direction has no effect"
        )
    width, height = tissue.width, tissue.height
    return Walls(
        **{k: parse_field(f"walls.{k}", v, width, height, constants) for k, v in table.items()}
    )


def feedback_from(data: dict, table: dict) -> Feedback | None:
    """``[feedback]`` (None if the scene has none): cue and rate, both required; walls
    (default "around")."""
    if "feedback" not in data:
        return None
    for key, valid in (
        ("cue", f"one of {', '.join(map(repr, CUES))}"),
        ("rate", "the director's turning rate k, a number >= 0"),
    ):
        if key not in table:
            raise SceneError(f"feedback.{key} is required in [feedback]: {valid}")
    return Feedback(**table)


def carries_director(walls: Walls | None, feedback: Feedback | None) -> bool:
    """Whether a run carries a fibre director (docs/fibres.md): fibred walls
    (``walls.fibre_stiffness`` other than the constant 0), or ``[feedback]`` turning one."""
    return walls is not None and (walls.fibred or feedback is not None)


def default_fields(walls: Walls | None, feedback: Feedback | None) -> tuple[str, ...]:
    """``output.fields`` of a scene that lists none: DEFAULT_OUTPUT, with the director
    (``fibre_direction``) when the run carries one and the cue's anisotropy
    (``cue_anisotropy``) with ``[feedback]``, so that ``render --fibres`` and ParaView's glyphs
    find them."""
    director = DIRECTOR_OUTPUT if carries_director(walls, feedback) else ()
    return DEFAULT_OUTPUT + director + (FEEDBACK_OUTPUT if feedback is not None else ())


def check_outputs(fields: tuple[str, ...], walls: Walls | None, feedback: Feedback | None) -> None:
    """``output.fields`` may list ``fibre_direction`` only with a director and
    ``cue_anisotropy`` only with ``[feedback]``: SceneError otherwise."""
    if "fibre_direction" in fields and not carries_director(walls, feedback):
        raise SceneError(
            "output.fields: fibre_direction is the fibre director, but the scene has none: "
            "give walls.fibre_stiffness (E_f / E, > 0) and walls.fibre_angle (degrees from "
            "x1), or remove fibre_direction"
        )
    if "cue_anisotropy" in fields and feedback is None:
        raise SceneError(
            "output.fields: cue_anisotropy is the anisotropy of the [feedback] cue, but the "
            'scene has no [feedback]: give it (cue = "stress" or "strain", rate >= 0) with '
            "fibred [walls], or remove cue_anisotropy"
        )
