"""The small expression language of model claims and bounds.

    claim  := compare ("and" compare)*
    compare:= sum ("<" | "<=" | "=" | ">=" | ">") sum
    sum    := product (("+" | "-") product)*
    product:= factor ("*" factor)*
    factor := number | "-" factor | "(" sum ")" | ref
    ref    := FN "(" path ")"        in claims: FN is sent, start, end, ach_start, ach_end
            | NAME "." ("lo" | "hi")  in bounds: a duration's bounds
    path   := "self" | step ("." step)*   step := NAME | NAME "[" ("k" | "k+1") "]"

A claim speaks about one message of its ``about`` class (``self``) and the
messages its handler issues, by child name: ``ach_end(body) < start(next.next)``.
Parsing yields a tree; ``build`` maps it to Z3 with a resolver for the refs.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from fractions import Fraction
from typing import Callable, Optional, Union

import z3

from ..errors import Pos, RoarError

FUNCTIONS = ("sent", "start", "end", "ach_start", "ach_end")
PathStep = tuple[str, Optional[str]]  # (child name, None | "k" | "k+1")

_TOKEN = re.compile(r"\s*(?:(\d+(?:\.\d+)?)|(<=|>=|[<>=+\-*().\[\]])|([A-Za-z_][A-Za-z0-9_]*))")


@dataclass(frozen=True)
class Ref:
    """``fn(path)`` in a claim, or ``name.lo`` / ``name.hi`` in a bound (fn is then lo or hi)."""

    fn: str
    path: tuple[PathStep, ...]


Node = Union[Fraction, Ref, tuple]  # tuple: (op, left, right) or ("neg", x) or ("and", [...])


class _Parser:
    def __init__(self, text: str, pos: Optional[Pos], what: str):
        self.text, self.pos, self.what = text, pos, what
        self.tokens: list[str] = []
        i = 0
        while i < len(text):
            m = _TOKEN.match(text, i)
            if not m or m.end() == i:
                if text[i:].strip():
                    raise self.fail(f"unexpected {text[i:].strip()[:10]!r}")
                break
            self.tokens.append(next(g for g in m.groups() if g is not None))
            i = m.end()
        self.i = 0

    def fail(self, message: str) -> RoarError:
        return RoarError(f"{self.what} {self.text!r}: {message}", self.pos)

    def peek(self) -> Optional[str]:
        return self.tokens[self.i] if self.i < len(self.tokens) else None

    def take(self, expected: Optional[str] = None) -> str:
        tok = self.peek()
        if tok is None or (expected is not None and tok != expected):
            raise self.fail(f"expected {expected or 'more'}, found {tok or 'the end'}")
        self.i += 1
        return tok

    def claim(self) -> tuple:
        parts = [self.compare()]
        while self.peek() == "and":
            self.take()
            parts.append(self.compare())
        if self.peek() is not None:
            raise self.fail(f"unexpected {self.peek()!r}")
        return ("and", parts)

    def compare(self) -> tuple:
        left = self.sum()
        op = self.take()
        if op not in ("<", "<=", "=", ">=", ">"):
            raise self.fail(f"expected a comparison, found {op!r}")
        return (op, left, self.sum())

    def sum(self) -> Node:
        node = self.product()
        while self.peek() in ("+", "-"):
            op = self.take()
            node = (op, node, self.product())
        return node

    def product(self) -> Node:
        node = self.factor()
        while self.peek() == "*":
            self.take()
            node = ("*", node, self.factor())
        return node

    def factor(self) -> Node:
        tok = self.take()
        if tok == "-":
            return ("neg", self.factor())
        if tok == "(":
            node = self.sum()
            self.take(")")
            return node
        if tok[0].isdigit():
            return Fraction(tok)
        if not tok[0].isalpha() and tok[0] != "_":
            raise self.fail(f"unexpected {tok!r}")
        if self.peek() == "(":
            if tok not in FUNCTIONS:
                raise self.fail(f"{tok} is not one of {', '.join(FUNCTIONS)}")
            self.take("(")
            path = self.path()
            self.take(")")
            return Ref(tok, path)
        self.take(".")
        side = self.take()
        if side not in ("lo", "hi"):
            raise self.fail(f"expected {tok}.lo or {tok}.hi")
        return Ref(side, ((tok, None),))

    def path(self) -> tuple[PathStep, ...]:
        if self.peek() == "self":
            self.take()
            return ()
        steps = [self.step()]
        while self.peek() == ".":
            self.take()
            steps.append(self.step())
        return tuple(steps)

    def step(self) -> PathStep:
        name = self.take()
        if not re.match(r"^[A-Za-z_]\w*$", name):
            raise self.fail(f"expected a child name, found {name!r}")
        if self.peek() != "[":
            return (name, None)
        self.take("[")
        self.take("k")
        index = "k"
        if self.peek() == "+":
            self.take()
            self.take("1")
            index = "k+1"
        self.take("]")
        return (name, index)


def parse_claim(text: str, pos: Optional[Pos] = None, what: str = "claim") -> tuple:
    return _Parser(text, pos, what).claim()


def refs(node: Node) -> list[Ref]:
    """Every ref in a parsed claim, in order."""
    if isinstance(node, Ref):
        return [node]
    if isinstance(node, tuple):
        if node[0] == "and":
            return [r for part in node[1] for r in refs(part)]
        return [r for part in node[1:] for r in refs(part)]
    return []


def build(node: Node, resolve: Callable[[Ref], z3.ArithRef]) -> z3.ExprRef:
    """The Z3 formula or term of a parsed claim, with ``resolve`` giving each ref."""
    if isinstance(node, Fraction):
        return z3.RealVal(str(node))
    if isinstance(node, Ref):
        return resolve(node)
    op = node[0]
    if op == "and":
        return z3.And([build(p, resolve) for p in node[1]])
    if op == "neg":
        return -build(node[1], resolve)
    a, b = build(node[1], resolve), build(node[2], resolve)
    return {"<": lambda: a < b, "<=": lambda: a <= b, "=": lambda: a == b, ">=": lambda: a >= b,
            ">": lambda: a > b, "+": lambda: a + b, "-": lambda: a - b, "*": lambda: a * b}[op]()
