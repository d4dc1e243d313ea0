"""Difference constraints over the reals, with conflicts read off negative cycles.

What a trace leaves open (goals' achievement intervals, times after the
trace's end) meets the axioms only in atoms ``x - y <= c`` or ``x - y < c``
(``x``, ``y`` unknown times or zero, ``c`` rational): axioms 2 to 8 and the
definitions compare two times, and the checker knows every other value. A
conjunction of such atoms is satisfiable exactly when its constraint graph
(an edge ``y -> x`` of weight ``c`` per atom) has no negative cycle, strict
atoms counting as ``c - epsilon``; and a simple negative cycle is a minimal
unsatisfiable subset (remove one edge and the rest is a path). So one
Bellman-Ford pass with cycle detection replaces an SMT search and its
core minimisation, whose time and memory grew with the square of the
trace (a deep chain of goals: cores as long as the chain, each literal of
each core re-checked by the solver). Memory here is linear in the atoms.

Weights are exact: every constant is scaled to an integer by the least
common denominator, and strictness is the low-order part of the weight
(``c * K - 1`` with ``K`` above the number of edges), so a cycle is negative
exactly when its constant sum is negative, or zero with a strict edge on it.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from fractions import Fraction
from math import lcm
from typing import Hashable, Optional

import z3

ZERO = "0"  # the node standing for the constant 0


@dataclass(frozen=True)
class Atom:
    """``x - y <= c`` (``x - y < c`` when ``strict``); ``x`` or ``y`` may be :data:`ZERO`."""

    x: str
    y: str
    c: Fraction
    strict: bool


class NotDifference(Exception):
    """A constraint outside the difference fragment (a disjunction, a product, ...)."""


def _numeral(e: z3.ExprRef) -> Fraction:
    return Fraction(e.numerator_as_long(), e.denominator_as_long())


def _linear(e: z3.ExprRef) -> tuple[dict[str, int], Fraction]:
    """``e`` as (coefficients of its variables, constant)."""
    if z3.is_rational_value(e):
        return {}, _numeral(e)
    if z3.is_int_value(e):
        return {}, Fraction(e.as_long())
    if not z3.is_app(e):
        raise NotDifference(str(e))
    op = e.decl().kind()
    if op == z3.Z3_OP_UNINTERPRETED and e.num_args() == 0 and z3.is_arith(e):
        return {e.decl().name(): 1}, Fraction(0)
    if op in (z3.Z3_OP_ADD, z3.Z3_OP_SUB):
        coeffs: dict[str, int] = {}
        const = Fraction(0)
        for i, kid in enumerate(e.children()):
            sign = -1 if op == z3.Z3_OP_SUB and i > 0 else 1
            kc, kk = _linear(kid)
            for v, a in kc.items():
                coeffs[v] = coeffs.get(v, 0) + sign * a
            const += sign * kk
        return {v: a for v, a in coeffs.items() if a}, const
    if op == z3.Z3_OP_UMINUS:
        kc, kk = _linear(e.children()[0])
        return {v: -a for v, a in kc.items()}, -kk
    if op == z3.Z3_OP_MUL:
        kids = [_linear(k) for k in e.children()]
        const_kids = [k for k in kids if not k[0]]
        var_kids = [k for k in kids if k[0]]
        if len(var_kids) > 1:
            raise NotDifference(str(e))
        factor = Fraction(1)
        for _c, k in const_kids:
            factor *= k
        if not var_kids:
            return {}, factor
        vc, vk = var_kids[0]
        if factor.denominator != 1:
            raise NotDifference(str(e))
        return {v: int(a * factor) for v, a in vc.items() if a * factor}, vk * factor
    raise NotDifference(str(e))


def _compare(lhs: z3.ExprRef, rhs: z3.ExprRef, strict: bool) -> list[Atom]:
    """``lhs <= rhs`` (``<`` when strict) as difference atoms."""
    lc, lk = _linear(lhs)
    rc, rk = _linear(rhs)
    coeffs = dict(lc)
    for v, a in rc.items():
        coeffs[v] = coeffs.get(v, 0) - a
    coeffs = {v: a for v, a in coeffs.items() if a}
    c = rk - lk  # sum(coeffs * vars) <= c
    pos = [v for v, a in coeffs.items() if a == 1]
    neg = [v for v, a in coeffs.items() if a == -1]
    if len(pos) + len(neg) != len(coeffs) or len(pos) > 1 or len(neg) > 1:
        raise NotDifference(f"{lhs} vs {rhs}")
    return [Atom(pos[0] if pos else ZERO, neg[0] if neg else ZERO, c, strict)]


_FLIP = {z3.Z3_OP_LE: z3.Z3_OP_GT, z3.Z3_OP_LT: z3.Z3_OP_GE, z3.Z3_OP_GE: z3.Z3_OP_LT, z3.Z3_OP_GT: z3.Z3_OP_LE}


def atoms(e, negated: bool = False) -> list[Atom]:
    """A constraint (a conjunction of comparisons) as difference atoms; raises
    :class:`NotDifference` for anything else. A constant true gives no atom, a
    constant false the atom ``0 - 0 < 0``."""
    if isinstance(e, bool):
        return [] if e is not negated else [Atom(ZERO, ZERO, Fraction(0), True)]
    if z3.is_true(e) or z3.is_false(e):
        return [] if z3.is_true(e) is not negated else [Atom(ZERO, ZERO, Fraction(0), True)]
    if not z3.is_app(e):
        raise NotDifference(str(e))
    op, kids = e.decl().kind(), e.children()
    if op == z3.Z3_OP_NOT:
        return atoms(kids[0], not negated)
    if op == z3.Z3_OP_AND and not negated:
        return [a for k in kids for a in atoms(k)]
    if op == z3.Z3_OP_OR and negated:
        return [a for k in kids for a in atoms(k, True)]
    if op in (z3.Z3_OP_EQ, z3.Z3_OP_IFF) and kids[0].sort() == z3.BoolSort():
        a, b = kids
        if z3.is_true(a) or z3.is_false(a):
            return atoms(b, negated ^ z3.is_false(a))
        if z3.is_true(b) or z3.is_false(b):
            return atoms(a, negated ^ z3.is_false(b))
        raise NotDifference(str(e))
    if op == z3.Z3_OP_EQ and not negated:
        a, b = kids
        return _compare(a, b, False) + _compare(b, a, False)
    if op in _FLIP:
        if negated:
            op = _FLIP[op]
        a, b = kids
        if op == z3.Z3_OP_LE:
            return _compare(a, b, False)
        if op == z3.Z3_OP_LT:
            return _compare(a, b, True)
        if op == z3.Z3_OP_GE:
            return _compare(b, a, False)
        return _compare(b, a, True)
    raise NotDifference(str(e))


class DifferenceSystem:
    """Labelled difference atoms; :meth:`conflict` finds a minimal unsatisfiable set of labels.

    Labels can be switched off (:meth:`drop`) and the search resumed: the node potentials
    of the previous search are kept (Bellman-Ford converges from any finite start), so
    reporting a few conflicts costs little more than finding the first."""

    def __init__(self) -> None:
        self.index: dict[str, int] = {ZERO: 0}
        self.src: list[int] = []
        self.dst: list[int] = []
        self.const: list[Fraction] = []
        self.strict: list[bool] = []
        self.label: list[Hashable] = []
        self.alive: list[bool] = []
        self.by_label: dict[Hashable, list[int]] = {}
        self._weights: Optional[list[int]] = None
        self._dist: Optional[list[int]] = None

    def _node(self, name: str) -> int:
        i = self.index.get(name)
        if i is None:
            i = self.index[name] = len(self.index)
        return i

    def add(self, label: Hashable, found: list[Atom]) -> None:
        for a in found:
            e = len(self.src)
            self.src.append(self._node(a.y))  # x - y <= c: an edge y -> x of weight c
            self.dst.append(self._node(a.x))
            self.const.append(a.c)
            self.strict.append(a.strict)
            self.label.append(label)
            self.alive.append(True)
            self.by_label.setdefault(label, []).append(e)
        self._weights = None

    def drop(self, label: Hashable) -> None:
        for e in self.by_label.get(label, ()):
            self.alive[e] = False

    def _integer_weights(self) -> list[int]:
        scale = 1
        for c in self.const:
            scale = lcm(scale, c.denominator)
        k = len(self.const) + 1
        return [int(c * scale) * k - (1 if s else 0) for c, s in zip(self.const, self.strict)]

    def conflict(self) -> Optional[set]:
        """The labels of a negative cycle among the live atoms, or None if they are satisfiable."""
        if self._weights is None:
            self._weights = self._integer_weights()
            self._dist = None
        n = len(self.index)
        w, src, dst, alive = self._weights, self.src, self.dst, self.alive
        out: list[list[int]] = [[] for _ in range(n)]
        for e in range(len(src)):
            if alive[e]:
                out[src[e]].append(e)
        dist = self._dist if self._dist is not None and len(self._dist) == n else [0] * n
        self._dist = dist
        parent = [-1] * n
        queue = deque(range(n))
        queued = [True] * n
        relaxed = 0
        check_every = n + 1
        while queue:
            u = queue.popleft()
            queued[u] = False
            du = dist[u]
            for e in out[u]:
                v = dst[e]
                nd = du + w[e]
                if nd < dist[v]:
                    dist[v] = nd
                    parent[v] = e
                    relaxed += 1
                    if not queued[v]:
                        queued[v] = True
                        queue.append(v)
                    if relaxed >= check_every:
                        relaxed = 0
                        cycle = self._parent_cycle(parent)
                        if cycle is not None:
                            return {self.label[e] for e in cycle}
        return None

    def _parent_cycle(self, parent: list[int]) -> Optional[list[int]]:
        """A cycle of the parent-edge graph (every such cycle is negative), as edges."""
        n = len(parent)
        mark = [0] * n  # 0 unseen, else the walk that reached it
        for start in range(n):
            if mark[start]:
                continue
            walk = start + 1
            v = start
            while v >= 0 and not mark[v]:
                mark[v] = walk
                e = parent[v]
                v = self.src[e] if e >= 0 else -1
            if v >= 0 and mark[v] == walk:  # closed a cycle within this walk
                cycle, x = [], v
                while True:
                    e = parent[x]
                    cycle.append(e)
                    x = self.src[e]
                    if x == v:
                        return cycle
        return None
