"""Printing terms and types in Celf's concrete syntax.

Implicit arguments (reconstructed by elaboration) are hidden, as Celf hides
them. Literals of the built-in domain print as written (``5``, ``-2.5``,
``"a\\"b"``); a rational that is not a finite decimal prints as ``1/3``, which
does not read back. Printing is iterative over argument spines so that a unary
numeral of depth 40,000 prints without hitting Python's recursion limit.
"""

from __future__ import annotations

from .terms import (Aff, Bang, BVar, CanonParam, Const, EVar, Exists, Imp, Lam, Lit, Meta, Monad,
                    Node, One, Param, Pi, Root, Tensor, Top, Type, With, apply)

#: number of leading implicit arguments of each constant (filled by the signature)
IMPLICIT: dict[Const, int] = {}

_IMP = {"!": "->", "1": "-o", "@": "-@"}

# precedence levels: higher binds tighter
_P_BINDER, _P_ARROW, _P_TENSOR, _P_PREFIX, _P_APP, _P_ATOM = 0, 1, 2, 3, 4, 5


def show(t: Node, names: list[str] | None = None, show_implicit: bool = False,
         implicit: dict | None = None) -> str:
    """Render a term or type; ``names`` are the bound names, innermost last.

    ``implicit`` is the program's table of implicit-argument counts (a
    program's own table keeps its printing independent of programs loaded
    later); without it the table of the most recent declarations is used.
    """
    out: list[str] = []
    _render(t, list(names or []), _P_BINDER, out, show_implicit, IMPLICIT if implicit is None else implicit)
    return "".join(out)


def _head_name(h, names: list[str]) -> str:
    if type(h) is Const:
        return h.name
    if type(h) is Lit:
        return h.text  # 5, -2.5, 1/3 (not re-readable), "a\"b"
    if type(h) is BVar:
        i = len(names) - 1 - h.index
        return names[i] if 0 <= i < len(names) else f"^{h.index}"
    if isinstance(h, CanonParam):
        return h.hint
    if isinstance(h, Param):
        # a fresh name prints as hint#id: never an identifier, so a trace can tell it apart
        return f"{h.hint}#{h.id}" if not h.hint.startswith("#") else h.hint
    if type(h) is EVar:
        return h.name
    if type(h) is Meta:
        return f"?{h.index}"
    return repr(h)


def _fresh(names: list[str], hint: str = "x") -> str:
    base = hint or "x"
    if base not in names:
        return base
    k = 1
    while f"{base}{k}" in names:
        k += 1
    return f"{base}{k}"


def _render(t: Node, names: list[str], prec: int, out: list[str], imp: bool, table: dict) -> None:
    # work stack of either strings or (node, names, prec) items
    stack: list = [(t, names, prec)]
    while stack:
        item = stack.pop()
        if type(item) is str:
            out.append(item)
            continue
        t, names, prec = item
        tt = type(t)
        if tt is Root:
            h = t.head
            if type(h) is EVar and h.ref is not None:
                stack.append((apply(h.ref, t.args), names, prec))
                continue
            args = t.args
            if not imp and type(h) is Const:
                args = args[table.get(h, 0):]
            hn = _head_name(h, names)
            if not args:
                out.append(hn)
                continue
            paren = prec > _P_APP
            parts: list = []
            if paren:
                parts.append("(")
            parts.append(hn)
            for a in args:
                parts.append(" ")
                parts.append((a, names, _P_ATOM))
            if paren:
                parts.append(")")
            stack.extend(reversed(parts))
        elif tt is Lam:
            v = _fresh(names, "x")
            paren = prec > _P_BINDER
            parts = (["("] if paren else []) + [f"\\{v}. ", (t.body, names + [v], _P_BINDER)] + ([")"] if paren else [])
            stack.extend(reversed(parts))
        else:
            stack.extend(reversed(_type_parts(t, names, prec)))


def _type_parts(t: Node, names: list[str], prec: int) -> list:
    tt = type(t)
    if tt is Type:
        return ["type"]
    if tt is Top:
        return ["T"]
    if tt is One:
        return ["1"]
    if tt in (Pi, Exists):
        v = _fresh(names, t.hint)
        kw = "Pi" if tt is Pi else "Exists"
        parts = [f"{kw} {v}: ", (t.dom, names, _P_ARROW), ". ", (t.body, names + [v], _P_BINDER)]
        return _wrap(parts, prec > _P_BINDER)
    if tt is Imp:
        parts = [(t.dom, names, _P_TENSOR), f" {_IMP[t.mode]} ", (t.body, names, _P_ARROW)]
        return _wrap(parts, prec > _P_ARROW)
    if tt in (Tensor, With):
        op = " * " if tt is Tensor else " & "
        parts = [(t.left, names, _P_PREFIX), op, (t.right, names, _P_TENSOR)]
        return _wrap(parts, prec > _P_TENSOR)
    if tt in (Bang, Aff):
        parts = ["!" if tt is Bang else "@", (t.body, names, _P_ATOM)]
        return _wrap(parts, prec > _P_PREFIX)
    if tt is Monad:
        return ["{", (t.body, names, _P_BINDER), "}"]
    return [repr(t)]


def _wrap(parts: list, paren: bool) -> list:
    return ["("] + parts + [")"] if paren else parts
