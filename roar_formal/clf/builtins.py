"""The built-in constraint domain of ground numbers and strings.

An extension of Celf's language in the manner of Twelf's constraint domains
(``%use inequality/rationals``): literals ``5``, ``-2.5``, ``"abc"`` are terms
of the predeclared types ``number`` (exact rationals) and ``string``, and a
few predeclared type families are decided by the engine rather than by
clauses. A goal of a built-in family is evaluated natively as soon as its
inputs are ground: a test succeeds once or fails, a function unifies its last
argument (the output) with the computed value. See docs/clf.md, "Built-in
numbers and strings".

Literals are terms like any other (``Root(Lit(...), ())``, hash-consed by
value), so unification, matching, context indexing, state keys and printing
need nothing special; only proof search (``backward.py``), the forward
matcher's proved premises (``prove_premise``), rule compilation (``rules.py``)
and the elaborator (``signature.py``) know about the built-in families.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from typing import Callable, Optional

from ..errors import RoarError
from .terms import (NUMBER, STRING, Const, Imp, Lit, Node, Root, Type, deref, format_number, num_term, num_value,
                    string_term, string_value)

__all__ = [
    "Builtin", "BuiltinError", "BUILTINS", "BUILTIN_FAMILIES", "BUILTIN_TYPES", "builtin_names", "is_builtin",
    "evaluate", "input_values", "num_term", "num_value", "string_term", "string_value",
]


class BuiltinError(RoarError):
    """A built-in family was used in a way the engine cannot evaluate (an input not ground)."""


@dataclass(frozen=True)
class Builtin:
    """A built-in type family: argument types, and how to decide it.

    ``output`` is False for a test (every argument is an input; ``fn`` returns a
    bool) and True for a function (the last argument is the output; ``fn`` returns
    the output's value, or None when the function is undefined there: the goal fails).
    """

    name: str
    const: Const
    arg_types: tuple[Const, ...]
    output: bool
    fn: Callable
    doc: str

    @property
    def n_inputs(self) -> int:
        return len(self.arg_types) - (1 if self.output else 0)

    @property
    def mode(self) -> str:
        """The family's mode as ``#mode`` would write it: ``+`` inputs, ``-`` the output."""
        return " ".join(["+"] * self.n_inputs + (["-"] if self.output else []))


def _integral(q: Fraction) -> bool:
    return q.denominator == 1


def _idiv(a: Fraction, b: Fraction) -> Optional[Fraction]:
    """Integer division truncating toward zero (as in C); undefined unless both are
    integers and ``b`` is not zero."""
    if not (_integral(a) and _integral(b)) or b == 0:
        return None
    q = abs(a.numerator) // abs(b.numerator)
    return Fraction(q if (a < 0) == (b < 0) else -q)


def _mod(a: Fraction, b: Fraction) -> Optional[Fraction]:
    """The remainder matching :func:`_idiv`: ``a = b * idiv(a, b) + mod(a, b)``, with
    the sign of ``a`` (as C's ``%``)."""
    q = _idiv(a, b)
    return None if q is None else a - b * q


def _floor(a: Fraction) -> Fraction:
    return Fraction(a.numerator // a.denominator)


_N, _S = NUMBER, STRING


def _b(name: str, arg_types: tuple, output: bool, fn: Callable, doc: str) -> Builtin:
    return Builtin(name, Const(name), arg_types, output, fn, doc)


_TABLE: list[Builtin] = [
    _b("num_lt", (_N, _N), False, lambda a, b: a < b, "A < B"),
    _b("num_le", (_N, _N), False, lambda a, b: a <= b, "A <= B"),
    _b("num_eq", (_N, _N), False, lambda a, b: a == b, "A = B"),
    _b("num_ne", (_N, _N), False, lambda a, b: a != b, "A != B"),
    _b("string_eq", (_S, _S), False, lambda a, b: a == b, "S = T"),
    _b("string_ne", (_S, _S), False, lambda a, b: a != b, "S != T"),
    _b("num_add", (_N, _N, _N), True, lambda a, b: a + b, "C = A + B"),
    _b("num_sub", (_N, _N, _N), True, lambda a, b: a - b, "C = A - B"),
    _b("num_mul", (_N, _N, _N), True, lambda a, b: a * b, "C = A * B"),
    _b("num_div", (_N, _N, _N), True, lambda a, b: a / b if b != 0 else None, "C = A / B (exact; fails if B = 0)"),
    _b("num_idiv", (_N, _N, _N), True, _idiv,
       "C = A / B truncated toward zero (fails unless A, B are integers and B != 0)"),
    _b("num_mod", (_N, _N, _N), True, _mod, "C = A - B * idiv(A, B), the sign of A (fails as num_idiv)"),
    _b("num_neg", (_N, _N), True, lambda a: -a, "B = -A"),
    _b("num_abs", (_N, _N), True, abs, "B = |A|"),
    _b("num_floor", (_N, _N), True, _floor, "B = the greatest integer <= A"),
    _b("num_min", (_N, _N, _N), True, min, "C = min(A, B)"),
    _b("num_max", (_N, _N, _N), True, max, "C = max(A, B)"),
    _b("string_concat", (_S, _S, _S), True, lambda s, t: s + t, "U = S followed by T"),
    _b("num_to_string", (_N, _S), True, format_number, "S = A as printed (5, 2.5, 1/3)"),
]

#: the built-in families decided by the engine, by constant
BUILTINS: dict[Const, Builtin] = {b.const: b for b in _TABLE}
#: the built-in types (families of kind ``type`` with literals as their only elements)
BUILTIN_TYPES: tuple[Const, ...] = (NUMBER, STRING)
#: every built-in family constant (types, tests and functions)
BUILTIN_FAMILIES: frozenset = frozenset(BUILTINS) | frozenset(BUILTIN_TYPES)


def builtin_names() -> list[str]:
    """The names reserved by the built-in domain: ``number``, ``string``, then the
    tests and functions in the order of docs/clf.md."""
    return [c.name for c in BUILTIN_TYPES] + [b.name for b in _TABLE]


_NAMES = frozenset(builtin_names())


def is_builtin(name: str) -> bool:
    """Is ``name`` reserved by the built-in domain?"""
    return name in _NAMES


def kind_of(b: Builtin) -> Node:
    """The family's kind, e.g. ``number -> number -> type``."""
    k: Node = Type()
    for ty in reversed(b.arg_types):
        k = Imp("!", Root(ty, ()), k)
    return k


def _what(t: Node) -> str:
    from .printer import show

    return show(t)


def input_values(b: Builtin, args: tuple) -> list:
    """The values of a goal's input arguments (logic variables followed); raises
    :class:`BuiltinError` when one is not a ground literal."""
    vals = []
    for i in range(b.n_inputs):
        a = deref(args[i])
        h = a.head if type(a) is Root else None
        if type(h) is Lit and h.family is b.arg_types[i]:
            vals.append(h.value)
            continue
        kind = "number" if b.arg_types[i] is NUMBER else "string"
        if a.evars:
            found = "an unbound logic variable" if type(a) is Root and not a.args else f"'{_what(a)}', not ground"
        else:
            found = f"'{_what(a)}', which is not a {kind} literal"
        raise BuiltinError(f"built-in '{b.name}': its inputs must be ground (argument {i + 1} is {found}); "
                           f"mode {b.name} {b.mode}")
    return vals


def evaluate(b: Builtin, args: tuple):
    """Decide a goal ``b args``: for a test, True or False; for a function, the output
    term (a literal) or None when the function is undefined at the inputs."""
    vals = input_values(b, args)
    r = b.fn(*vals)
    if not b.output:
        return bool(r)
    if r is None:
        return None
    return num_term(r) if b.arg_types[-1] is NUMBER else string_term(r)
