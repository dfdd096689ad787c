"""The messages of ``plantgrowth render`` for a field a run did not write and for a wrong
``--component``: each names what the run has and how to get what was asked for.

An unknown name gets "did you mean" (:func:`plantgrowth.scene.field_names.close_fields`: the
written fields it may mean, else the fields a scene may ask for). Example: ``--field trG`` on a
run that wrote G but not trG::

    --field = 'trG' is not written in results/a: it wrote G, u; trG is tr G: give --field G
    --component tr; a field is written when the scene's [output] fields lists it: add it there
    and run the scene again (docs/outputs.md lists the fields)
"""

from __future__ import annotations

import re

from plantgrowth.results.reader import ResultSeries
from plantgrowth.scene.field_names import close_fields
from plantgrowth.scene.limits import OUTPUT_FIELDS

DERIVED = {"trG": ("G", "tr")}
"""A field that is a component of another written field: name -> (field, component)."""
SPLIT = {"E_hom": re.compile(r"E\d{4}")}
"""A field written as several scalar fields (its components): name -> their names' pattern."""


def missing_field(series: ResultSeries, name: str) -> str:
    """``--field = NAME`` is not written: the written fields, then the closest way to it."""
    names = series.names
    text = f"--field = {name!r} is not written in {series.directory}: it wrote {', '.join(names)}"
    if name in SPLIT and (parts := [n for n in names if SPLIT[name].fullmatch(n)]):
        return f"{text}; {name} is written as its components: give --field {' or '.join(parts)}"
    if name in DERIVED and DERIVED[name][0] in names:
        source, component = DERIVED[name]
        return f"{text}; {name} is a component of {source}: give --field {source} --component {component}"
    close = close_fields(name, names)
    if close:
        return f"{text}; did you mean {' or '.join(close)}?"
    unwritten = [] if name in OUTPUT_FIELDS else close_fields(name, OUTPUT_FIELDS)
    meant = f" (did you mean {' or '.join(unwritten)}?)" if unwritten else ""
    return (
        f"{text}{meant}; a field is written when the scene's [output] fields lists it: add it "
        "there and run the scene again (docs/outputs.md lists the fields)"
    )


def bad_component(name: str, kind: str, component: str | None, valid: tuple[str, ...]) -> str:
    """A missing, unknown or needless ``--component`` of the ``kind`` (tensor, vector, scalar)
    field ``name``, with the components it has."""
    if kind == "scalar":
        return (
            f"--component = {component!r}: {name} is a scalar field, it has none: drop --component"
        )
    if component is None:
        return (
            f"--component is required for the tensor field {name}: give one of {', '.join(valid)}"
        )
    arrows = " (or none, for arrows)" if kind == "vector" else ""
    return (
        f"--component = {component!r} is invalid for the {kind} field {name}: one of "
        f"{', '.join(valid)}{arrows}"
    )


def missing_fibres(series: ResultSeries, micro: bool, has_director: bool) -> str:
    """``--fibres`` on a run that wrote no director: what is missing and the scene key that
    writes it (macro: ``[output] fields`` with fibre_direction, once the run has a director;
    without a director: ``[walls] fibre_stiffness``)."""
    text = f"--fibres: {series.directory} has no fibre director to draw"
    if micro:
        return (
            f"{text} (its cells.csv has no fibre_angle column): a micro run writes it when the "
            "scene has fibres: give it [walls] fibre_stiffness and fibre_angle (or [feedback]) "
            "and run it again"
        )
    if has_director:
        return (
            f"{text} (it wrote {', '.join(series.names)}): its scene has a director but did not "
            'write it: add "fibre_direction" to the scene\'s [output] fields and run it again'
        )
    return (
        f"{text}: its scene has no fibres: give it [walls] fibre_stiffness and fibre_angle (or "
        '[feedback]), add "fibre_direction" to its [output] fields and run it again'
    )
