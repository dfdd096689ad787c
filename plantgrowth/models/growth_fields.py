"""Growth outputs a biologist reads: ``trG``, ``growth_anisotropy``, ``growth_direction`` and
``stress_direction`` (scene key ``output.fields``; definitions in :mod:`plantgrowth.base.principal`
and docs/outputs.md).

They are DG0 fields where G lives: per fine cell (macro), per biological cell (micro). Only the
fields a scene asks for get a function and are computed. Directions are 2-vectors (x1, x2),
written padded to 3 components as XDMF vectors (ParaView: Glyph filter, cell data).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from dolfinx import fem
from dolfinx.mesh import Mesh

from plantgrowth.base import principal
from plantgrowth.scene.limits import GROWTH_FIELDS

VECTOR_FIELDS = ("growth_direction", "stress_direction")


def growth_field(name: str, G: np.ndarray, sigma: np.ndarray | None = None) -> np.ndarray:
    """One field from the growth rates G (n, 2, 2) and, for ``stress_direction``, the stress
    sigma (n, 2, 2): (n,) for a scalar, (n, 2) for a direction."""
    if name == "trG":
        return principal.trace(G)
    if name == "growth_anisotropy":
        return principal.anisotropy(G)
    if name == "growth_direction":
        return principal.principal_direction(G)
    if name == "stress_direction":
        if sigma is None:
            raise ValueError("stress_direction needs the stress")
        return principal.principal_direction(sigma)
    raise ValueError(f"unknown growth field {name!r}: one of {GROWTH_FIELDS}")


class GrowthFields:
    """The DG0 output functions of the growth fields in ``fields`` (the others are ignored).

    Args:
        mesh: the mesh the model writes.
        fields: the scene's ``output.fields``.
    """

    def __init__(self, mesh: Mesh, fields: tuple[str, ...]) -> None:
        names = [name for name in fields if name in GROWTH_FIELDS]
        spaces: dict[bool, fem.FunctionSpace] = {}
        if any(name not in VECTOR_FIELDS for name in names):
            spaces[False] = fem.FunctionSpace(mesh, ("DG", 0))
        if any(name in VECTOR_FIELDS for name in names):
            spaces[True] = fem.VectorFunctionSpace(mesh, ("DG", 0))
        self.functions = {
            name: fem.Function(spaces[name in VECTOR_FIELDS], name=name) for name in names
        }

    @property
    def needs_stress(self) -> bool:
        """Whether ``stress_direction`` is asked for (the micro strain law then averages the
        stress too)."""
        return "stress_direction" in self.functions

    def fill(
        self, G: np.ndarray, sigma: np.ndarray | None,
        set_values: Callable[[fem.Function, np.ndarray], None],
    ) -> None:  # fmt: skip
        """Compute every asked field and store it with ``set_values(function, values)`` (the
        model's per-unit writer: fine cells or biological cells)."""
        for name, function in self.functions.items():
            set_values(function, growth_field(name, G, sigma))
