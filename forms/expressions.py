"""UFL versions of the operations of scene expressions (the keys of
``plantgrowth.scene.expression.NUMPY``), so an expression can be a form coefficient, e.g. a traction
that varies along an edge. Comparisons give 1.0 or 0.0, ``where(c, a, b)`` is a conditional."""

from __future__ import annotations

import operator

import ufl


def _indicator(compare):
    return lambda a, b: ufl.conditional(compare(a, b), 1.0, 0.0)


UFL_OPS = {
    "+": operator.add, "-": operator.sub, "*": operator.mul, "/": operator.truediv,
    "**": operator.pow, "neg": operator.neg, "exp": ufl.exp, "log": ufl.ln, "sqrt": ufl.sqrt,
    "sin": ufl.sin, "cos": ufl.cos, "tanh": ufl.tanh, "abs": abs, "min": ufl.min_value,
    "max": ufl.max_value, "where": lambda c, a, b: ufl.conditional(ufl.ne(c, 0.0), a, b),
    "<": _indicator(ufl.lt), "<=": _indicator(ufl.le), ">": _indicator(ufl.gt),
    ">=": _indicator(ufl.ge), "==": _indicator(ufl.eq), "!=": _indicator(ufl.ne),
}  # fmt: skip
