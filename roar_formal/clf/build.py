"""Building CLF syntax trees in code, for a compiler whose output is CLF.

A compiler that prints CLF text and has the parser read it back must get
every escape, parenthesis and name right in text, and can only edit what it
made with string surgery. Here it builds the parser's own trees
(:mod:`.surface`) instead, which the elaborator checks item by item:

* :func:`q` fills a template, written in CLF's concrete syntax with ``{}``
  holes, with trees, names and numbers. The template is a constant of the
  compiler's source: it is parsed once per process; the values never pass
  through text (a string is a :class:`~.surface.Str` node, a number a
  :class:`~.surface.Num`), so nothing needs escaping.
* :class:`Rule` is a forward rule ``name : P1 -o ... -o {Exists x. C1 * ...}``
  kept as its lists of premises and conclusions, so that a later pass adds a
  premise or a conclusion by appending to a list.
* :func:`decl`, :func:`fact`, :func:`backward`, :func:`query`, :func:`exec_`
  make the other items; :class:`Comment` is a remark kept for the printed
  model only.

Trees compare and hash by structure (positions aside), so they serve as keys.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field
from fractions import Fraction
from functools import lru_cache
from typing import Optional, Union

from ..errors import Pos
from . import surface as s
from .parser import is_identifier_word, parse_expr
from .pretty_surface import format_expr, format_item

__all__ = ["q", "name", "number", "string", "tensor", "Rule", "Comment", "decl", "fact", "backward",
           "query", "exec_", "head_of", "args_of", "format_items", "format_term", "BUILT"]

#: the position of every node a template makes (a compiled item's own position is its spec site's)
BUILT = Pos("<compiled model>", 1, 1)
_HOLE = "hole__"
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_']*\Z")

Arg = Union[s.Node, str, int, Fraction]


def name(x: str) -> s.Expr:
    """An identifier (a constant or an upper-case variable; ``type`` is the keyword); anything
    else is a compiler error."""
    if x == "type":
        return s.TypeKw(BUILT)
    if not _NAME.match(x) or not is_identifier_word(x):   # (not a keyword: in, let, Pi, ...)
        raise ValueError(f"not a CLF identifier: {x!r} (build a tree for it)")
    return s.Id(BUILT, x)


def number(x: Union[int, Fraction]) -> s.Expr:
    """A number literal (exact). The number one is the tree the parser makes of ``1``
    (:class:`~.surface.One`, which the elaborator reads as the number where a term is expected),
    so that a built tree and the parse of its printed text are equal."""
    if isinstance(x, bool):
        raise ValueError(f"not a number: {x!r}")
    value = Fraction(x)
    return s.One(BUILT) if value == 1 else s.Num(BUILT, value)


def string(x: str) -> s.Str:
    return s.Str(BUILT, x)


def _tree(x: Arg) -> s.Node:
    if isinstance(x, s.Node):
        return x
    if isinstance(x, str):
        return name(x)
    if isinstance(x, (int, Fraction)) and not isinstance(x, bool):
        return number(x)
    if isinstance(x, float):
        return number(Fraction(repr(x)))
    raise TypeError(f"cannot put {x!r} in a CLF tree")


@lru_cache(maxsize=None)
def _template(text: str) -> tuple[s.Expr, int]:
    if "{" in text.replace("{}", ""):
        raise ValueError(f"a template has no braces but its holes: {text!r} (use Rule for a monad)")
    parts = text.split("{}")
    filled = "".join(p + (f" {_HOLE}{i} " if i < len(parts) - 1 else "") for i, p in enumerate(parts))
    tree = parse_expr(filled, "<template>")
    return _relocate(tree), len(parts) - 1


def _relocate(e):
    """The template's tree with every position :data:`BUILT` (a template's text is not the model's)."""
    if not isinstance(e, s.Node):
        return e
    kw = {f.name: _relocate(getattr(e, f.name)) for f in dataclasses.fields(e) if f.name != "pos"}
    return type(e)(BUILT, **kw)


def _fill(e, args: tuple):
    if isinstance(e, s.Id) and e.name.startswith(_HOLE):
        return args[int(e.name[len(_HOLE):])]
    if not isinstance(e, s.Node) or isinstance(e, (s.Id, s.Num, s.Str)):
        return e
    changed = {}
    for f in dataclasses.fields(e):
        v = getattr(e, f.name)
        if isinstance(v, s.Node):
            w = _fill(v, args)
            if w is not v:
                changed[f.name] = w
    return dataclasses.replace(e, **changed) if changed else e


def q(template: str, *args: Arg) -> s.Expr:
    """The tree of ``template`` (CLF concrete syntax) with its ``{}`` holes filled, in order, by
    ``args``: trees as they are, strings as identifiers (:func:`name`), numbers as literals."""
    tree, holes = _template(template)
    if holes != len(args):
        raise ValueError(f"the template {template!r} has {holes} holes, given {len(args)} values")
    return _fill(tree, tuple(_tree(x) for x in args)) if holes else tree


def tensor(items: list) -> s.Expr:
    """``A * B * ...`` (right-nested, as the parser reads it); ``1`` when empty."""
    if not items:
        return s.One(BUILT)
    out = _tree(items[-1])
    for x in reversed(items[:-1]):
        out = s.Tensor(BUILT, _tree(x), out)
    return out


def head_of(e: s.Expr) -> Optional[str]:
    """The constant an atom is an application of (``!`` taken off), or None."""
    while isinstance(e, (s.Bang, s.Affine)):
        e = e.body
    while isinstance(e, s.App):
        e = e.fn
    return e.name if isinstance(e, s.Id) else None


def args_of(e: s.Expr) -> list:
    """The arguments of an atom, in order."""
    while isinstance(e, (s.Bang, s.Affine)):
        e = e.body
    out = []
    while isinstance(e, s.App):
        out.append(e.arg)
        e = e.fn
    return out[::-1]


@dataclass
class Rule:
    """A forward rule ``name : P1 -o ... -o Pn -o {Exists x1. ... C1 * ... * Cm}``: premises (``!``
    for a persistent one) in order, the fresh names of its monad, its conclusions in order.
    ``pos`` is where it comes from (a spec statement), for errors."""

    name: str
    premises: list
    conclusions: list
    fresh: tuple = ()
    pos: Optional[Pos] = None

    def __post_init__(self):
        self.premises = [_tree(x) for x in self.premises]
        self.conclusions = [_tree(x) for x in self.conclusions]

    def has_premise(self, p: s.Expr) -> bool:
        return any(x == p for x in self.premises)

    def item(self) -> s.Decl:
        body: s.Expr = tensor(self.conclusions)
        for v in reversed(self.fresh):
            body = s.Exists(BUILT, v, None, body)
        out: s.Expr = s.Monad(BUILT, body)
        for p in reversed(self.premises):
            out = s.Arrow(BUILT, "-o", p, out)
        return s.Decl(self.pos or BUILT, self.name, out)


@dataclass(frozen=True)
class Comment:
    """A remark in the printed model (``% text``, one per line; an empty line stays empty); the
    elaborator never sees it."""

    text: str
    pos: Pos = field(default=BUILT, compare=False)


def decl(const: str, classifier: Union[s.Expr, str], pos: Optional[Pos] = None) -> s.Decl:
    """``const : classifier.`` (a constant of a type, or a fact)."""
    return s.Decl(pos or BUILT, const, _tree(classifier))


def fact(const: str, template: str, *args: Arg, pos: Optional[Pos] = None) -> s.Decl:
    """A persistent fact: ``const : template`` with its holes filled."""
    return s.Decl(pos or BUILT, const, q(template, *args))


def backward(const: str, conclusion: s.Expr, premises: list, pos: Optional[Pos] = None) -> s.Decl:
    """A backward clause ``const : C <- P1 <- ... <- Pn.`` (the premises tried in order)."""
    out = conclusion
    for p in premises:
        out = s.Arrow(BUILT, "->", _tree(p), out, reversed=True)
    return s.Decl(pos or BUILT, const, out)


def query(goal: s.Expr, attempts: int = 1) -> s.Query:
    """``#query * * * attempts goal.``"""
    return s.Query(BUILT, "*", "*", "*", attempts, goal)


def exec_(start: s.Expr) -> s.Exec:
    """``#exec * start.``"""
    return s.Exec(BUILT, "*", start)


#: a forward rule longer than this is printed one premise a line
WIDE = 100


def format_items(items: list) -> str:
    """The items as CLF text (one per line; a comment as ``% text``; a long forward rule one
    premise a line), for people to read."""
    out = []
    for it in items:
        if isinstance(it, Comment):
            out.append("\n".join("% " + line if line else "" for line in it.text.split("\n")))
        else:
            out.append(_format_decl(it.item() if isinstance(it, Rule) else it))
    return "\n".join(out) + "\n"


def _format_decl(item) -> str:
    text = format_item(item)
    if len(text) <= WIDE or not isinstance(item, s.Decl) or item.definition is not None:
        return text
    parts, e = [], item.classifier
    while isinstance(e, s.Arrow) and e.op == "-o" and not e.reversed and \
            isinstance(e.left, (s.App, s.Id, s.Bang, s.Affine)):
        parts.append(format_expr(e.left))
        e = e.right
    if not parts or not isinstance(e, s.Monad):
        return text
    return f"{item.name} : " + "\n    -o ".join(parts + [format_expr(e)]) + "."


def format_term(e: s.Expr) -> str:
    """One tree as CLF text."""
    return format_expr(e)
