"""Evaluate the axioms' own Z3 formulas on a finite structure such as a trace.

A formula is compiled once into Python closures; an instance then costs a few
microseconds. Values the structure does not know evaluate to ``UNKNOWN``
(Kleene's three-valued logic); a time known only to lie after the end of the
trace is ``LATE``, which compares above every known time. An instance whose
value stays unknown is rebuilt as a Z3 constraint over the unknown values
(``compile_residual``), for the checker's solver to decide.
"""

from __future__ import annotations

import operator
from fractions import Fraction
from typing import Any, Callable, Sequence

import z3


class _Unknown:
    def __repr__(self) -> str:
        return "UNKNOWN"


class _Late:
    def __repr__(self) -> str:
        return "LATE"


UNKNOWN = _Unknown()
LATE = _Late()

Lookup = Callable[[str, tuple], Any]
Closure = Callable[[tuple, Lookup], Any]

_CMP = {z3.Z3_OP_LT: operator.lt, z3.Z3_OP_LE: operator.le, z3.Z3_OP_GT: operator.gt, z3.Z3_OP_GE: operator.ge}
_LATE_FIRST = {z3.Z3_OP_LT: False, z3.Z3_OP_LE: False, z3.Z3_OP_GT: True, z3.Z3_OP_GE: True}


def _and(values: list) -> Any:
    if any(v is False for v in values):
        return False
    return UNKNOWN if any(v is UNKNOWN for v in values) else True


def _or(values: list) -> Any:
    if any(v is True for v in values):
        return True
    return UNKNOWN if any(v is UNKNOWN for v in values) else False


def _not(value: Any) -> Any:
    return UNKNOWN if value is UNKNOWN else not value


def _distinct(values: list) -> Any:
    return _and([_not(_equal(x, y)) for i, x in enumerate(values) for y in values[i + 1:]])


def _compare(op: int, a: Any, b: Any) -> Any:
    if a is UNKNOWN or b is UNKNOWN or (a is LATE and b is LATE):
        return UNKNOWN
    if a is LATE:
        return _LATE_FIRST[op]
    if b is LATE:
        return not _LATE_FIRST[op]
    return _CMP[op](a, b)


def _equal(a: Any, b: Any) -> Any:
    if a is UNKNOWN or b is UNKNOWN or a is LATE or b is LATE:
        return UNKNOWN if (a is UNKNOWN or b is UNKNOWN or a is b) else False
    return a == b


def _arith(op: Callable, values: list) -> Any:
    if any(v is UNKNOWN or v is LATE for v in values):
        return UNKNOWN
    result = values[0]
    for v in values[1:]:
        result = op(result, v)
    return result


def _numeral(e: z3.ExprRef) -> Fraction:
    return Fraction(e.numerator_as_long(), e.denominator_as_long())


def compile_formula(expr: z3.ExprRef, params: Sequence[z3.ExprRef]) -> Closure:
    """``expr`` as a closure of (values for ``params``, lookup for the other symbols)."""
    slots = {p.get_id(): i for i, p in enumerate(params)}
    return _compile(expr, slots)


def _compile(e: z3.ExprRef, slots: dict[int, int]) -> Closure:
    if e.get_id() in slots:
        i = slots[e.get_id()]
        return lambda args, look: args[i]
    if z3.is_quantifier(e):
        raise ValueError("cannot evaluate a nested quantifier on a finite trace")
    if z3.is_rational_value(e):
        value = _numeral(e)
        return lambda args, look: value
    if z3.is_true(e) or z3.is_false(e):
        value = z3.is_true(e)
        return lambda args, look: value
    decl, op = e.decl(), e.decl().kind()
    kids = [_compile(c, slots) for c in e.children()]
    if op == z3.Z3_OP_DT_CONSTRUCTOR and not kids:
        name = decl.name()
        return lambda args, look: name
    if op == z3.Z3_OP_UNINTERPRETED:
        name = decl.name()
        return lambda args, look: look(name, tuple(k(args, look) for k in kids))
    return _operator(op, kids, e)


def _operator(op: int, kids: list[Closure], e: z3.ExprRef) -> Closure:
    if op == z3.Z3_OP_AND:
        return lambda args, look: _and([k(args, look) for k in kids])
    if op == z3.Z3_OP_OR:
        return lambda args, look: _or([k(args, look) for k in kids])
    if op == z3.Z3_OP_NOT:
        (k,) = kids
        return lambda args, look: _not(k(args, look))
    if op == z3.Z3_OP_IMPLIES:
        a, b = kids
        return lambda args, look: _or([_not(a(args, look)), b(args, look)])
    if op in (z3.Z3_OP_EQ, z3.Z3_OP_IFF):
        a, b = kids
        return lambda args, look: _equal(a(args, look), b(args, look))
    if op == z3.Z3_OP_DISTINCT:
        return lambda args, look: _distinct([k(args, look) for k in kids])
    if op in _CMP:
        a, b = kids
        return lambda args, look: _compare(op, a(args, look), b(args, look))
    if op == z3.Z3_OP_ADD:
        return lambda args, look: _arith(operator.add, [k(args, look) for k in kids])
    if op == z3.Z3_OP_SUB:
        return lambda args, look: _arith(operator.sub, [k(args, look) for k in kids])
    if op == z3.Z3_OP_MUL:
        return lambda args, look: _arith(operator.mul, [k(args, look) for k in kids])
    if op == z3.Z3_OP_UMINUS:
        (k,) = kids
        return lambda args, look: _arith(operator.neg, [k(args, look)])
    raise ValueError(f"cannot evaluate {e.decl().name()} in {e}")


def compile_residual(expr: z3.ExprRef, params: Sequence[z3.ExprRef],
                     lift: Callable[[Any], z3.ExprRef]) -> Closure:
    """``expr`` as a partial evaluator: known parts fold to Python values, the
    rest becomes a Z3 term. ``look`` returns a value or a Z3 variable for an
    unknown; ``lift`` turns a value into a Z3 term where the two meet."""
    slots = {p.get_id(): i for i, p in enumerate(params)}
    return _compile_residual(expr, slots, lift)


def _symbolic(x: Any) -> bool:
    return isinstance(x, z3.ExprRef)


def _compile_residual(e: z3.ExprRef, slots: dict[int, int], lift) -> Closure:
    if e.get_id() in slots or z3.is_rational_value(e) or z3.is_true(e) or z3.is_false(e):
        return _compile(e, slots)
    decl, op = e.decl(), e.decl().kind()
    if op == z3.Z3_OP_DT_CONSTRUCTOR and e.num_args() == 0:
        return _compile(e, slots)
    kids = [_compile_residual(c, slots, lift) for c in e.children()]
    if op == z3.Z3_OP_UNINTERPRETED:
        name = decl.name()
        return lambda args, look: look(name, tuple(k(args, look) for k in kids))
    if op in (z3.Z3_OP_AND, z3.Z3_OP_OR):
        absorbing = op == z3.Z3_OP_OR  # True absorbs a disjunction, False a conjunction
        build = z3.Or if absorbing else z3.And

        def junction(args, look):
            rest = []
            for k in kids:
                v = k(args, look)
                if v is absorbing:
                    return absorbing
                if v is not (not absorbing):
                    rest.append(v)
            return (not absorbing) if not rest else rest[0] if len(rest) == 1 else build(rest)

        return junction
    if op == z3.Z3_OP_NOT:
        (k,) = kids
        return lambda args, look: _negate(k(args, look))
    if op == z3.Z3_OP_IMPLIES:
        a, b = kids
        return lambda args, look: _either(_negate(a(args, look)), b(args, look))
    known = _KNOWN.get(op)
    symbolic = {z3.Z3_OP_EQ: lambda x, y: x == y, z3.Z3_OP_IFF: lambda x, y: x == y,
                z3.Z3_OP_DISTINCT: lambda x, y: x != y,
                z3.Z3_OP_LT: lambda x, y: x < y, z3.Z3_OP_LE: lambda x, y: x <= y,
                z3.Z3_OP_GT: lambda x, y: x > y, z3.Z3_OP_GE: lambda x, y: x >= y,
                z3.Z3_OP_ADD: lambda x, y: x + y, z3.Z3_OP_SUB: lambda x, y: x - y,
                z3.Z3_OP_MUL: lambda x, y: x * y}.get(op)
    if symbolic is None or len(kids) != 2:
        raise ValueError(f"cannot evaluate {decl.name()} in {e}")

    def binary(args, look):
        x, y = kids[0](args, look), kids[1](args, look)
        if not _symbolic(x) and not _symbolic(y):
            return known(x, y)
        return symbolic(x if _symbolic(x) else lift(x), y if _symbolic(y) else lift(y))

    return binary


def _negate(v: Any) -> Any:
    return z3.Not(v) if _symbolic(v) else not v


_KNOWN = {z3.Z3_OP_EQ: operator.eq, z3.Z3_OP_IFF: operator.eq, z3.Z3_OP_DISTINCT: operator.ne, z3.Z3_OP_LT: operator.lt,
          z3.Z3_OP_LE: operator.le, z3.Z3_OP_GT: operator.gt, z3.Z3_OP_GE: operator.ge,
          z3.Z3_OP_ADD: operator.add, z3.Z3_OP_SUB: operator.sub, z3.Z3_OP_MUL: operator.mul}


def _either(x: Any, y: Any) -> Any:
    if x is True or y is True:
        return True
    if x is False:
        return y
    if y is False:
        return x
    return z3.Or(x, y)


_INFIX = {z3.Z3_OP_LE: "<=", z3.Z3_OP_LT: "<", z3.Z3_OP_GE: ">=", z3.Z3_OP_GT: ">", z3.Z3_OP_EQ: "=",
          z3.Z3_OP_ADD: "+", z3.Z3_OP_SUB: "-", z3.Z3_OP_MUL: "*"}
_NEGATED = {z3.Z3_OP_LE: ">", z3.Z3_OP_LT: ">=", z3.Z3_OP_GE: "<", z3.Z3_OP_GT: "<=", z3.Z3_OP_EQ: "!="}


def show(e: z3.ExprRef, number: Callable[[Fraction], str] = str) -> str:
    """A compact infix rendering; time arguments of relations are left out."""
    if z3.is_rational_value(e):
        return number(_numeral(e))
    if not z3.is_app(e):
        return str(e)
    op, kids = e.decl().kind(), e.children()
    if op == z3.Z3_OP_UNINTERPRETED:
        args = [show(k, number) for k in kids if not (e.sort() == z3.BoolSort() and z3.is_arith(k))]
        return f"{e.decl().name()}({', '.join(args)})" if kids else e.decl().name()
    if op == z3.Z3_OP_NOT and z3.is_app(kids[0]) and kids[0].decl().kind() in _NEGATED:
        a, b = kids[0].children()
        return f"{show(a, number)} {_NEGATED[kids[0].decl().kind()]} {show(b, number)}"
    if op == z3.Z3_OP_NOT:
        return f"not ({show(kids[0], number)})"
    if op in (z3.Z3_OP_AND, z3.Z3_OP_OR):
        word = " and " if op == z3.Z3_OP_AND else " or "
        return word.join(f"({show(k, number)})" if z3.is_or(k) or z3.is_and(k) else show(k, number) for k in kids)
    if op == z3.Z3_OP_IMPLIES:
        return f"{show(kids[0], number)} implies {show(kids[1], number)}"
    if op in _INFIX and len(kids) == 2:
        return f"{show(kids[0], number)} {_INFIX[op]} {show(kids[1], number)}"
    return str(e)

