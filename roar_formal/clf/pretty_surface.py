"""Print surface trees back as Celf concrete syntax.

The output re-parses to an equal tree (positions aside), using as few
parentheses as the grammar in ``celf.lark`` allows: binders are left bare
where nothing follows them (the end of the text, a closing bracket, or the
right end of an operator or application), and parenthesised elsewhere.
"""

from __future__ import annotations

from . import surface as s
from .terms import format_number, format_string

__all__ = ["format_expr", "format_item", "format_program"]

# Precedence levels, loosest first (see the grammar).
_BINDER, _REV, _ARR, _CONJ, _PRE, _APP, _POST, _ATOM = range(8)
_REVERSED_OP = {"-o": "o-", "->": "<-", "-@": "@-"}
_LAM_MARK = {"linear": "", "affine": "@", "persistent": "!"}


def _level(e: s.Expr) -> int:
    if isinstance(e, (s.Pi, s.Exists, s.Lam)):
        return _BINDER
    if isinstance(e, s.Arrow):
        return _REV if e.reversed else _ARR
    if isinstance(e, (s.Tensor, s.With)):
        return _CONJ
    if isinstance(e, (s.Bang, s.Affine)):
        return _PRE
    if isinstance(e, s.App):
        return _APP
    if isinstance(e, s.Proj):
        return _POST
    return _ATOM


def _fmt(e: s.Expr, prec: int, tail: bool) -> str:
    """Print ``e`` where the context needs level ``prec``; ``tail`` says nothing follows it."""
    level = _level(e)
    if (level == _BINDER and not tail) or (level != _BINDER and level < prec):
        return "(" + _fmt(e, _BINDER, True) + ")"
    if isinstance(e, s.Id):
        return e.name
    if isinstance(e, s.TypeKw):
        return "type"
    if isinstance(e, s.One):
        return "1"
    if isinstance(e, s.Underscore):
        return "_"
    if isinstance(e, s.Num):
        # `1` alone reads back as the unit, so the number one is written `1.0`
        text = e.text or format_number(e.value)
        return "1.0" if text == "1" else text
    if isinstance(e, s.Str):
        return format_string(e.value)
    if isinstance(e, s.Annot):
        return f"({_fmt(e.term, _BINDER, True)} : {_fmt(e.ty, _BINDER, True)})"
    if isinstance(e, s.Monad):
        return "{" + _fmt(e.body, _BINDER, True) + "}"
    if isinstance(e, s.Pair):
        # `<` and `>` are identifier characters: they stand apart from what they enclose
        return f"< {_fmt(e.left, _BINDER, True)}, {_fmt(e.right, _BINDER, True)} >"
    if isinstance(e, s.Proj):
        return f"{_fmt(e.body, _POST, False)} #{e.index}"
    if isinstance(e, s.App):
        return f"{_fmt(e.fn, _APP, False)} {e.mark or ''}{_fmt(e.arg, _POST, tail)}"
    if isinstance(e, (s.Bang, s.Affine)):
        return ("!" if isinstance(e, s.Bang) else "@") + _fmt(e.body, _PRE, tail)
    if isinstance(e, (s.Tensor, s.With)):
        op = "*" if isinstance(e, s.Tensor) else "&"
        return f"{_fmt(e.left, _PRE, False)} {op} {_fmt(e.right, _CONJ, tail)}"
    if isinstance(e, s.Arrow):
        if e.reversed:
            return f"{_fmt(e.right, _REV, False)} {_REVERSED_OP[e.op]} {_fmt(e.left, _ARR, tail)}"
        return f"{_fmt(e.left, _CONJ, False)} {e.op} {_fmt(e.right, _ARR, tail)}"
    if isinstance(e, (s.Pi, s.Exists, s.Lam)):
        if isinstance(e, s.Lam):
            head = "\\" + _LAM_MARK[e.mode] + e.var
        else:
            head = ("Pi " if isinstance(e, s.Pi) else "Exists ") + e.var
        if e.ty is not None:
            head += ":" + _fmt(e.ty, _BINDER, True)
        return f"{head}. {_fmt(e.body, _BINDER, True)}"
    raise TypeError(f"not a surface expression: {e!r}")


def format_expr(e: s.Expr) -> str:
    """Concrete syntax for ``e`` that :func:`parser.parse_expr` reads back as ``e``."""
    return _fmt(e, _BINDER, True)


def _bound(b: s.Bound) -> str:
    return str(b)


def format_item(item: s.Item) -> str:
    """One declaration or directive, with its final '.'."""
    if isinstance(item, s.Decl):
        text = f"{item.name} : {format_expr(item.classifier)}"
        if item.definition is not None:
            text += f" = {format_expr(item.definition)}"
        return text + "."
    if isinstance(item, s.Query):
        bounds = " ".join(_bound(b) for b in (item.depth, item.expected, item.look, item.attempts))
        goal = format_expr(item.goal)
        if s.headed_by_number(item.goal):
            goal = f"({goal})"   # bare, `1 a` after the bounds reads as a fifth bound
        return f"#query {bounds} {goal}."
    if isinstance(item, s.Exec):
        kw = "#trace" if item.trace else "#exec"
        return f"{kw} {_bound(item.steps)} {format_expr(item.start)}."
    if isinstance(item, s.Mode):
        return f"#mode {item.family} {' '.join(item.modes)}."
    raise TypeError(f"not a surface item: {item!r}")


def format_program(program: s.Program) -> str:
    return "".join(format_item(i) + "\n" for i in program.items)
