"""Surface syntax tree of Celf programs, as the parser produces it.

Kinds, types and terms share one syntactic category (as in Twelf and Celf);
the elaborator (``signature.py``) decides what each node is. Every node keeps
its source position so later errors can point at it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from typing import Literal, Optional, Union

from ..errors import Pos


@dataclass(frozen=True)
class Node:
    pos: Pos = field(compare=False, repr=False)


@dataclass(frozen=True)
class Id(Node):
    """An identifier: constant, bound variable, or (upper case, free) implicit variable.

    ``T`` alone is also read as this node; the elaborator turns it into top
    where a type is expected and it is not bound.
    """

    name: str


@dataclass(frozen=True)
class TypeKw(Node):
    """The keyword ``type``."""


@dataclass(frozen=True)
class One(Node):
    """The multiplicative unit ``1`` (where a term is expected: the number 1)."""


@dataclass(frozen=True)
class Num(Node):
    """A number literal (``5``, ``-2.5``; ``1`` alone is read as :class:`One`):
    its exact value, and the text it was written as (not compared)."""

    value: Fraction
    text: str = field(default="", compare=False)


@dataclass(frozen=True)
class Str(Node):
    """A string literal, by its value (escapes resolved)."""

    value: str


@dataclass(frozen=True)
class Underscore(Node):
    """``_``: a placeholder to be reconstructed."""


@dataclass(frozen=True)
class App(Node):
    """``fn arg``, ``fn !arg`` or ``fn @arg``."""

    fn: "Expr"
    arg: "Expr"
    mark: Optional[Literal["!", "@"]] = None


@dataclass(frozen=True)
class Lam(Node):
    """``\\x. body`` (linear), ``\\@x. body`` (affine), ``\\!x. body`` (persistent)."""

    var: str
    body: "Expr"
    mode: Literal["linear", "affine", "persistent"] = "linear"
    ty: Optional["Expr"] = None


@dataclass(frozen=True)
class Pi(Node):
    """``Pi x:A. B`` or ``Pi x. B`` (``ty`` is None)."""

    var: str
    ty: Optional["Expr"]
    body: "Expr"


@dataclass(frozen=True)
class Exists(Node):
    """``Exists x:A. S`` or ``Exists x. S``."""

    var: str
    ty: Optional["Expr"]
    body: "Expr"


@dataclass(frozen=True)
class Arrow(Node):
    """An implication ``left op right`` where left is the premise.

    ``op`` is ``->`` (persistent), ``-o`` (linear) or ``-@`` (affine). Reversed
    forms are normalised: ``B o- A`` becomes ``Arrow('-o', A, B, reversed=True)``.
    """

    op: Literal["->", "-o", "-@"]
    left: "Expr"
    right: "Expr"
    reversed: bool = False


@dataclass(frozen=True)
class Tensor(Node):
    left: "Expr"
    right: "Expr"


@dataclass(frozen=True)
class With(Node):
    left: "Expr"
    right: "Expr"


@dataclass(frozen=True)
class Bang(Node):
    """``!A``: persistent."""

    body: "Expr"


@dataclass(frozen=True)
class Affine(Node):
    """``@A``: affine."""

    body: "Expr"


@dataclass(frozen=True)
class Monad(Node):
    """``{S}``."""

    body: "Expr"


@dataclass(frozen=True)
class Pair(Node):
    """``<M, N>``."""

    left: "Expr"
    right: "Expr"


@dataclass(frozen=True)
class Proj(Node):
    """``M #1`` or ``M #2``."""

    body: "Expr"
    index: Literal[1, 2]


@dataclass(frozen=True)
class Annot(Node):
    """``(M : A)``."""

    term: "Expr"
    ty: "Expr"


@dataclass(frozen=True)
class PVar(Node):
    """A pattern variable: ``x`` (linear), ``!x`` (persistent) or ``@x`` (affine)."""

    name: str
    mode: Literal["linear", "affine", "persistent"] = "linear"


@dataclass(frozen=True)
class PBlank(Node):
    """``_``, ``!_`` or ``@_`` in a ``PI``/``EXISTS`` pattern."""

    mode: Literal["linear", "affine", "persistent"] = "linear"


@dataclass(frozen=True)
class POne(Node):
    """``1`` as a pattern."""


@dataclass(frozen=True)
class PTuple(Node):
    """``[p1, p2, ...]``: a pattern for a tensor (right nested)."""

    items: tuple


Pattern = Union[PVar, PBlank, POne, PTuple]


@dataclass(frozen=True)
class PatLam(Node):
    """``\\[x, y]. M`` or ``\\1. M``: a lambda whose pattern is not a single variable."""

    pattern: Pattern
    ty: Optional["Expr"]
    body: "Expr"


@dataclass(frozen=True)
class Tuple(Node):
    """``[M, N, ...]``: a monadic object of a tensor type (Celf's proof-term syntax)."""

    items: tuple


@dataclass(frozen=True)
class Let(Node):
    """``let {p} = M in E`` inside a monadic proof term ``{...}``."""

    pattern: Pattern
    value: "Expr"
    body: "Expr"


Expr = Union[Id, TypeKw, One, Num, Str, Underscore, App, Lam, Pi, Exists, Arrow, Tensor, With,
             Bang, Affine, Monad, Pair, Proj, Annot, PatLam, Tuple, Let]

Bound = Union[int, Literal["*"]]


@dataclass(frozen=True)
class Decl(Node):
    """``name : classifier.`` or ``name : classifier = definition.``"""

    name: str
    classifier: Expr
    definition: Optional[Expr] = None


@dataclass(frozen=True)
class Query(Node):
    """``#query d e l a A.``"""

    depth: Bound
    expected: Bound
    look: Bound
    attempts: Bound
    goal: Expr
    bounds_pos: tuple = field(default=(), compare=False)  # where d, e, l, a are written (Celf's checks)


@dataclass(frozen=True)
class Exec(Node):
    """``#exec n S.`` (``trace=False``) or ``#trace n S.`` (``trace=True``)."""

    steps: Bound
    start: Expr
    trace: bool = False


@dataclass(frozen=True)
class Mode(Node):
    """``#mode p + - .``"""

    family: str
    modes: tuple[Literal["+", "-", "-D", "*"], ...]
    implicit: Optional[tuple[Literal["+", "-", "-D", "*"], ...]] = None  # ``#mode p {+} + -.``


Item = Union[Decl, Query, Exec, Mode]


@dataclass(frozen=True)
class Program:
    file: str
    items: tuple[Item, ...]


def headed_by_number(goal: "Expr") -> bool:
    """Is ``goal`` an application whose head is ``1`` or a number? After a #query's four bounds,
    written bare, such a head reads as a fifth bound (the parser refuses it; the printer writes the
    goal in parentheses)."""
    head = goal
    while isinstance(head, App):
        head = head.fn
    return head is not goal and isinstance(head, (One, Num))
