"""Safe arithmetic expressions of the position for scene fields (``{expr = "..."}``).

A tokenizer and a recursive-descent parser build a small tree of tuples, evaluated with numpy
over arrays of points; nothing is passed to Python's ``eval`` or ``compile`` and there is no
attribute access, indexing or call of anything but the functions below. Grammar (loosest first)::

    expr    := sum [("<" | "<=" | ">" | ">=" | "==" | "!=") sum]   # 1.0 if true, else 0.0
    sum     := product (("+" | "-") product)*
    product := unary (("*" | "/") unary)*
    unary   := ("-" | "+") unary | power
    power   := atom ["**" unary]                  # right-associative: 2**3**2 = 2**9
    atom    := number | name | function "(" expr ("," expr)* ")" | "(" expr ")"

As in Python, ``-2**2 = -4`` and ``2**-1 = 0.5``. Numbers: ``3``, ``0.5``, ``.5``, ``1e-3``.
Names: the variables the caller allows (``x1``, ``x2`` for fields, ``s`` for loads), ``pi`` and
the scene's named parameters (``[parameters]``, each replaced by its number when parsed, so a
parameter gives the same tree as its literal value).
Functions: ``exp log sqrt sin cos tanh abs`` (one argument), ``min max`` (two or more) and
``where(cond, a, b)`` (a where cond is non-zero, else b). Comparisons are allowed anywhere and
give 0 or 1, so ``where(x1 > 3, 0.6, 0.3)`` and ``0.3 + 0.3 * (x1 > 3)`` are the same field.
Values outside a function's domain (``log(-1)``, ``1/0``) evaluate to NaN or inf; the scene's
range checks at the places used report them (:mod:`plantgrowth.scene.places`).

:meth:`Expression.derivative` differentiates the tree symbolically (``where``, ``abs``, ``min``
and ``max`` piecewise, comparisons have zero derivative), so gradients are exact: a linear
expression has the constant gradient of the equivalent ``{from, to}`` field to round-off.
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from plantgrowth.base.errors import InputError

MAX_LENGTH = 1000
"""Longest accepted expression, in characters."""
MAX_DEPTH = 50
"""Deepest accepted nesting of parentheses, calls and operators."""

UNARY = ("exp", "log", "sqrt", "sin", "cos", "tanh", "abs")
FUNCTIONS = (*UNARY, "min", "max", "where")
COMPARISONS = ("<", "<=", ">", ">=", "==", "!=")
NUMPY = {
    "+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide, "**": np.power,
    "neg": np.negative, "exp": np.exp, "log": np.log, "sqrt": np.sqrt, "sin": np.sin,
    "cos": np.cos, "tanh": np.tanh, "abs": np.abs, "min": np.minimum, "max": np.maximum,
    "where": lambda c, a, b: np.where(np.asarray(c) != 0.0, a, b),
    **{op: lambda a, b, f=f: f(a, b).astype(float) for op, f in zip(COMPARISONS, (
        np.less, np.less_equal, np.greater, np.greater_equal, np.equal, np.not_equal),
        strict=True)},
}  # fmt: skip
"""The operations an expression's tree is evaluated with (numpy; another table, e.g. UFL's, can
be passed to :meth:`Expression.evaluate`): binary operators, "neg", the functions (min and max
binary) and the comparisons, which give 1.0 or 0.0."""
_TOKEN = re.compile(
    r"\s*(?:(?P<number>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)|(?P<name>[A-Za-z_]\w*)"
    r"|(?P<op>\*\*|<=|>=|==|!=|[-+*/(),<>]))"
)

Node = tuple  # ("num", v) | ("var", name) | ("neg", a) | (op, a, b) | ("call", name, args)


class ExpressionError(InputError):
    """A malformed expression; the message names the key, the position and the text."""


@dataclass(frozen=True)
class _Token:
    kind: str  # "number", "name", "op" or "end"
    text: str
    position: int  # index of its first character in the expression (from 0)


def _tokens(key: str, text: str) -> Iterator[_Token]:
    """The tokens of ``text``, read lazily (so a bad name is reported before a later bad
    character), ending with an "end" token."""
    i = 0
    while text[i:].strip():
        match = _TOKEN.match(text, i)
        if match is None:
            j = len(text) - len(text[i:].lstrip())
            raise ExpressionError(
                f"{key}: unexpected character {text[j]!r} at position {j} in {text!r}"
            )
        kind = str(match.lastgroup)
        yield _Token(kind, match.group(kind), match.start(kind))
        i = match.end()
    yield _Token("end", "", len(text))


class _Parser:
    """Recursive descent over the tokens (one method per grammar rule of the module doc)."""

    def __init__(
        self, key: str, text: str, names: tuple[str, ...], constants: Mapping[str, float]
    ) -> None:
        self.key, self.text, self.names, self.constants = key, text, names, constants
        self.tokens = _tokens(key, text)
        self.token = next(self.tokens)
        self.depth = 0

    def error(self, what: str, token: _Token | None = None, hint: str = "") -> ExpressionError:
        at = (token or self.token).position
        return ExpressionError(f"{self.key}: {what} at position {at} in {self.text!r}{hint}")

    def peek(self) -> _Token:
        return self.token

    def advance(self) -> _Token:
        token, self.token = self.token, next(self.tokens, self.token)
        return token

    def take(self, *ops: str) -> _Token | None:
        if self.token.kind == "op" and self.token.text in ops:
            return self.advance()
        return None

    def expect(self, op: str) -> None:
        if self.take(op) is None:
            found = self.peek()
            shown = "the end" if found.kind == "end" else repr(found.text)
            raise self.error(f"expected {op!r}, found {shown}")

    def parse(self) -> Node:
        tree = self.expr()
        if self.peek().kind != "end":
            raise self.error(f"unexpected {self.peek().text!r}")
        return tree

    def expr(self) -> Node:
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise self.error(f"nesting deeper than {MAX_DEPTH}")
        tree = self.sum()
        if token := self.take(*COMPARISONS):
            tree = (token.text, tree, self.sum())
            if self.peek().text in COMPARISONS:
                raise self.error("chained comparison (use where or parentheses)")
        self.depth -= 1
        return tree

    def sum(self) -> Node:
        tree = self.product()
        while token := self.take("+", "-"):
            tree = (token.text, tree, self.product())
        return tree

    def product(self) -> Node:
        tree = self.unary()
        while token := self.take("*", "/"):
            tree = (token.text, tree, self.unary())
        return tree

    def unary(self) -> Node:
        if token := self.take("-", "+"):
            self.depth += 1
            if self.depth > MAX_DEPTH:
                raise self.error(f"nesting deeper than {MAX_DEPTH}", token)
            operand = self.unary()
            self.depth -= 1
            return ("neg", operand) if token.text == "-" else operand
        base = self.atom()
        if self.take("**"):
            return ("**", base, self.unary())
        return base

    def atom(self) -> Node:
        token = self.peek()
        if token.kind == "number":
            self.advance()
            return ("num", float(token.text))
        if token.kind == "name":
            known = (*self.names, "pi", *FUNCTIONS, *self.constants)
            if token.text not in known:  # before reading on
                hint = f" (valid names: {', '.join(known)})"
                if not self.constants:
                    hint += "; a named parameter is defined in [parameters]"
                raise self.error(f"unknown name {token.text!r}", token, hint)
            self.advance()
            if token.text in FUNCTIONS:
                return self.call(token)
            if token.text in self.constants:
                return ("num", float(self.constants[token.text]))
            return ("num", math.pi) if token.text == "pi" else ("var", token.text)
        if self.take("("):
            tree = self.expr()
            self.expect(")")
            return tree
        shown = "the end" if token.kind == "end" else repr(token.text)
        raise self.error(f"expected a number, a name or '(', found {shown}")

    def call(self, name: _Token) -> Node:
        if self.take("(") is None:
            raise self.error(f"function {name.text!r} needs its arguments in parentheses")
        args = [self.expr()]
        while self.take(","):
            args.append(self.expr())
        self.expect(")")
        wanted = 1 if name.text in UNARY else 3 if name.text == "where" else None
        if (wanted is not None and len(args) != wanted) or (wanted is None and len(args) < 2):
            count = f"{wanted}" if wanted is not None else "at least 2"
            raise self.error(f"{name.text} takes {count} argument(s), got {len(args)}", name)
        return ("call", name.text, tuple(args))


def _fold(tree: Node) -> Node:
    """Replace every subtree without variables by its value."""
    if tree[0] in ("num", "var"):
        return tree
    if tree[0] == "call":
        tree = ("call", tree[1], tuple(_fold(a) for a in tree[2]))
        children = tree[2]
    else:
        tree = (tree[0], *(_fold(a) for a in tree[1:]))
        children = tree[1:]
    if all(c[0] == "num" for c in children):
        return ("num", float(_evaluate(tree, {}, NUMPY)))
    return tree


def _evaluate(tree: Node, values: dict[str, Any], ops: dict[str, Any]) -> Any:
    kind = tree[0]
    if kind == "num":
        return tree[1]
    if kind == "var":
        return values[tree[1]]
    if kind == "neg":
        return ops["neg"](_evaluate(tree[1], values, ops))
    if kind == "call":
        args = [_evaluate(a, values, ops) for a in tree[2]]
        if tree[1] in ("min", "max"):  # of two or more arguments
            return functools.reduce(ops[tree[1]], args)
        return ops[tree[1]](*args)
    return ops[kind](_evaluate(tree[1], values, ops), _evaluate(tree[2], values, ops))


# --- symbolic derivative, with the simplifications that keep linear trees exact ---------------

ZERO, ONE = ("num", 0.0), ("num", 1.0)


def _add(a: Node, b: Node) -> Node:
    return b if a == ZERO else a if b == ZERO else _fold(("+", a, b))


def _sub(a: Node, b: Node) -> Node:
    return a if b == ZERO else _neg(b) if a == ZERO else _fold(("-", a, b))


def _neg(a: Node) -> Node:
    return _fold(("neg", a))


def _mul(a: Node, b: Node) -> Node:
    if ZERO in (a, b):
        return ZERO
    return b if a == ONE else a if b == ONE else _fold(("*", a, b))


def _div(a: Node, b: Node) -> Node:
    return ZERO if a == ZERO else a if b == ONE else _fold(("/", a, b))


def _where(cond: Node, a: Node, b: Node) -> Node:
    return a if a == b else _fold(("call", "where", (cond, a, b)))


def _derivative(tree: Node, name: str) -> Node:
    kind = tree[0]
    if kind == "num" or kind in COMPARISONS:
        return ZERO
    if kind == "var":
        return ONE if tree[1] == name else ZERO
    if kind == "neg":
        return _neg(_derivative(tree[1], name))
    if kind == "call":
        return _call_derivative(tree[1], tree[2], name)
    a, b = tree[1], tree[2]
    da, db = _derivative(a, name), _derivative(b, name)
    if kind == "+":
        return _add(da, db)
    if kind == "-":
        return _sub(da, db)
    if kind == "*":
        return _add(_mul(da, b), _mul(a, db))
    if kind == "/":
        return _div(_sub(_mul(da, b), _mul(a, db)), _mul(b, b))
    # a**b: b a**(b - 1) da + a**b log(a) db
    power = _mul(_mul(b, _fold(("**", a, _sub(b, ONE)))), da)
    if db == ZERO:
        return power
    return _add(power, _mul(_mul(tree, ("call", "log", (a,))), db))


def _call_derivative(fname: str, args: tuple[Node, ...], name: str) -> Node:
    d = [_derivative(a, name) for a in args]
    a = args[0]
    if fname == "where":
        return _where(args[0], d[1], d[2])
    if fname in ("min", "max"):  # the derivative of the argument that is taken
        pick, dpick = a, d[0]
        for b, db in zip(args[1:], d[1:], strict=True):
            cond = ("<=" if fname == "min" else ">=", pick, b)
            pick, dpick = ("call", fname, (pick, b)), _where(cond, dpick, db)
        return dpick
    if d[0] == ZERO:
        return ZERO
    outer = {
        "exp": ("call", "exp", (a,)),
        "log": _div(ONE, a),
        "sqrt": _div(("num", 0.5), ("call", "sqrt", (a,))),
        "sin": ("call", "cos", (a,)),
        "cos": _neg(("call", "sin", (a,))),
        "tanh": _sub(ONE, _mul(("call", "tanh", (a,)), ("call", "tanh", (a,)))),
        "abs": ("call", "where", (("<", a, ZERO), ("num", -1.0), ONE)),
    }[fname]
    return _mul(outer, d[0])


@dataclass(frozen=True)
class Expression:
    """A parsed expression: its text (as written in the scene), the variables it may use and
    its tree. Build it with :func:`parse_expression`."""

    text: str
    names: tuple[str, ...]
    tree: Node = field(repr=False)

    @property
    def is_constant(self) -> bool:
        """True when it uses no variable (its value is ``self(...)`` anywhere)."""
        return self.tree[0] == "num"

    def __call__(self, **values: np.ndarray) -> np.ndarray:
        """Values at the given points, e.g. ``expr(x1=x1, x2=x2)`` (arrays broadcast; NaN or
        inf where the expression is undefined)."""
        arrays = {k: np.asarray(v, dtype=float) for k, v in values.items()}
        shape = np.broadcast_shapes(*(a.shape for a in arrays.values()))
        with np.errstate(all="ignore"):
            out = _evaluate(self.tree, arrays, NUMPY)
        return np.broadcast_to(np.asarray(out, dtype=float), shape).copy()

    def evaluate(self, ops: dict[str, Any], **values: Any) -> Any:
        """The tree evaluated with another table of operations (keys as :data:`NUMPY`), e.g.
        UFL's to make a form coefficient of the expression."""
        return _evaluate(self.tree, values, ops)

    def derivative(self, name: str) -> Expression:
        """d/d(name), symbolic (text: the derivative's tree is not written back)."""
        with np.errstate(all="ignore"):
            tree = _derivative(self.tree, name)
        return Expression(f"d({self.text})/d{name}", self.names, tree)


def parse_expression(
    key: str, text: object, names: tuple[str, ...], constants: Mapping[str, float] | None = None
) -> Expression:
    """Parse ``text`` allowing the variables ``names`` and the named ``constants`` (the scene's
    parameters: each becomes its number in the tree); ExpressionError naming ``key`` (e.g.
    ``material.E.expr: unknown name 'y' at position 5 in 'x1 + y'``) if it is malformed."""
    if not isinstance(text, str):
        raise ExpressionError(f"{key}: expected a string, got {text!r:.60}")
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"{key}: {len(text)} characters, more than {MAX_LENGTH}")
    if not text.strip():
        raise ExpressionError(f"{key}: the expression is empty")
    with np.errstate(all="ignore"):
        tree = _fold(_Parser(key, text, names, constants or {}).parse())
    return Expression(text, names, tree)
