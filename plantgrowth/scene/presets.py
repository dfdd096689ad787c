"""Accuracy presets: ``accuracy.preset = "draft" | "balanced" | "fine"`` (issue 9).

A preset sets the numerical knobs a scene leaves out: the fine and coarse mesh sizes
(``tissue.h``, ``tissue.H``), the unit-cell resolution and surrogate tolerance
(``accuracy.cell_resolution``, ``accuracy.cell_tolerance``) and the time stepping
(``time.dt``, ``time.integrator``). Keys the scene gives override the preset. The values are
read off the accuracy-cost map (``scripts/studies/accuracy_cost.py``,
``benchmarks/results/accuracy_cost.json``): each preset is a point on the error-time Pareto
front of the map's scenes, ``balanced`` within 1% of the converged reference, ``draft``
within 3% and ``fine`` within 0.1% (docs/accuracy_cost.md).
"""

from __future__ import annotations

PRESETS: dict[str, dict[str, dict[str, float | int | str]]] = {
    "draft": {
        "tissue": {"h": 0.2, "H": 1.0},
        "accuracy": {"cell_resolution": 1, "cell_tolerance": 1e-2},
        "time": {"dt": 1.0, "integrator": "exp"},
    },
    "balanced": {
        "tissue": {"h": 0.1, "H": 0.5},
        "accuracy": {"cell_resolution": 2, "cell_tolerance": 1e-3},
        "time": {"dt": 1.0, "integrator": "exp"},
    },
    "fine": {
        "tissue": {"h": 0.05, "H": 0.0625},
        "accuracy": {"cell_resolution": 3, "cell_tolerance": 1e-4},
        "time": {"dt": 0.5, "integrator": "exp"},
    },
}
DEFAULT_PRESET = "balanced"


def knob(preset: str, section: str, key: str) -> float | int | str:
    """The value ``preset`` gives to ``section.key``."""
    return PRESETS[preset][section][key]
