"""Explanations of violations: the false atoms of an instance, with the trace's values.

``interp`` is the checker's interpretation of a trace: ``lookup(name, args)``
gives a value and ``z3_value(x)`` a Z3 term for a message or a number.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Any, Callable

import z3

from .countermodel import format_number
from .evaluate import LATE, UNKNOWN, compile_formula, show


def show_value(value: Any) -> str:
    if value is LATE:
        return "not yet (after the trace ends)"
    if value is UNKNOWN:
        return "unknown"
    return format_number(value) if isinstance(value, Fraction) else str(value)


def _values(e: z3.ExprRef, interp) -> list[str]:
    """``fn(m) = value`` for each interval term in a ground atom."""
    out, todo = [], [e]
    while todo:
        x = todo.pop(0)
        if z3.is_app(x) and x.decl().kind() == z3.Z3_OP_UNINTERPRETED and x.num_args() > 0 and z3.is_arith(x):
            args = tuple(a.decl().name() for a in x.children())
            out.append(f"{show(x, format_number)} = {show_value(interp.lookup(x.decl().name(), args))}")
        elif z3.is_app(x):
            todo.extend(x.children())
    return out


def false_atoms(e: z3.ExprRef, interp, params, values, negated: bool = False) -> list[str]:
    """The atoms that make a false ground instance false, with the trace's values."""
    if compile_formula(e, params)(values, interp.lookup) is not negated:
        return []
    op, kids = e.decl().kind(), e.children()
    if op == z3.Z3_OP_NOT:
        return false_atoms(kids[0], interp, params, values, not negated)
    if op == z3.Z3_OP_IMPLIES and not negated:
        return false_atoms(kids[1], interp, params, values)
    if (op == z3.Z3_OP_AND and not negated) or (op == z3.Z3_OP_OR and negated):
        return [a for c in kids for a in false_atoms(c, interp, params, values, negated)]
    ground = z3.substitute(e, *zip(params, [interp.z3_value(x) for x in values]))
    if op in (z3.Z3_OP_EQ, z3.Z3_OP_IFF) and kids[0].sort() == z3.BoolSort() and not negated:
        sides = [compile_formula(k, params)(values, interp.lookup) for k in kids]
        held = [g for g, value in zip(ground.children(), sides) if value is True]
        reasons = [a for k, value in zip(kids, sides) if value is False
                   for a in false_atoms(k, interp, params, values)]
        return [f"{show(held[0], format_number)} holds but " + " and ".join(reasons)] if held else reasons
    statement = show(z3.Not(ground) if negated else ground, format_number)
    values_text = ", ".join(_values(ground, interp))
    return [f"{statement} is false" + (f" ({values_text})" if values_text else "")]


def instance_label(rule: str, values: tuple) -> str:
    shown = [x if isinstance(x, str) else None for x in values]
    return f"{rule}({', '.join(x for x in shown if x)})"


def describe(rule: str, values: tuple, constraint: z3.BoolRef) -> Callable[[], str]:
    """The text of an instance in a core, built only if a core needs it."""
    return lambda: f"{instance_label(rule, values)}: {show(z3.simplify(constraint), format_number)}"
