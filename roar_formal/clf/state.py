"""Contexts as values: hashable keys, equal up to renaming of fresh names.

Fresh names (destinations, channels, cells made by ``Exists``) differ from
run to run, so two contexts that differ only by a renaming must be one state.
:func:`canonical_key` renames parameters to canonical ones in an order fixed
by the context's shape: parameters are coloured by where they occur (colour
refinement, a few rounds), facts are sorted by their coloured shape, and
parameters are numbered by first occurrence in that order. The result is
always a renaming of the context (so distinct states are never merged);
isomorphic contexts get the same key except in highly symmetric ties.
"""

from __future__ import annotations

from typing import Optional

from .context import Context
from .terms import CanonParam, Lam, Node, Param, Root, params_of


def _shape(t: Node, colour: dict, memo: dict) -> int:
    """A hash of ``t`` with each parameter replaced by its colour."""
    if not t.maxp:
        return hash(t)
    r = memo.get(t)
    if r is not None:
        return r
    tt = type(t)
    if tt is Root:
        h = t.head
        hk = ("p", colour[h]) if isinstance(h, Param) and h in colour else h
        r = hash((hk, tuple(_shape(a, colour, memo) for a in t.args)))
    elif tt is Lam:
        r = hash(("lam", _shape(t.body, colour, memo)))
    else:
        r = hash((tt, tuple(_shape(v, colour, memo) if isinstance(v, Node) else v
                            for v in (getattr(t, f) for f in tt.fields))))
    memo[t] = r
    return r


def _rename(t: Node, ren: dict, memo: dict) -> Node:
    if not t.maxp:
        return t
    r = memo.get(t)
    if r is not None:
        return r
    tt = type(t)
    if tt is Root:
        h = ren.get(t.head, t.head)
        r = Root(h, tuple(_rename(a, ren, memo) for a in t.args))
    elif tt is Lam:
        r = Lam(_rename(t.body, ren, memo))
    else:
        r = tt(*[_rename(v, ren, memo) if isinstance(v, Node) else v for v in (getattr(t, f) for f in tt.fields)])
    memo[t] = r
    return r


def _items(ctx: Context) -> list[tuple]:
    """(kind, mode, payload tuple of terms or None, multiplicity) for every hypothesis."""
    items: list[tuple] = []
    for mode, t, n in ctx.facts():
        items.append(("f", mode, (t,), n))
    for r in ctx.rules.values():
        items.append(("r", r.mode, (id(r.alts[0]) if r.alts else 0,) + tuple(r.env), 1))
    for mode, t in ctx.inert:
        items.append(("i", mode, (t,), 1))
    return items


def canonical_key(ctx: Context, rounds: int = 3) -> tuple:
    """A hashable key equal for contexts equal up to renaming of fresh names."""
    items = _items(ctx)
    params: dict = {}
    for _, _, payload, _ in items:
        for v in payload:
            if isinstance(v, Node):
                params_of(v, params)
    if not params:
        return _key(items)
    colour = {p: 0 for p in params}
    for _ in range(rounds):
        memo: dict = {}
        occ: dict = {p: [] for p in params}
        for kind, mode, payload, n in items:
            sh = hash((kind, mode, n, tuple(_shape(v, colour, memo) if isinstance(v, Node) else v for v in payload)))
            for pos, v in enumerate(payload):
                if isinstance(v, Node) and v.maxp:
                    found: dict = {}
                    params_of(v, found)
                    for p in found:
                        occ[p].append((sh, pos))
        new = {p: hash(tuple(sorted(o))) for p, o in occ.items()}
        stable = len(set(new.values())) == len(set(colour.values()))
        colour = new
        if stable or len(set(colour.values())) == len(colour):
            break   # the partition no longer refines (or every parameter is told apart)
    memo = {}
    order = sorted(items, key=lambda it: (it[0], it[1], it[3], tuple(
        _shape(v, colour, memo) if isinstance(v, Node) else (v if v is not None else -1) for v in it[2])))
    ren: dict = {}
    for _, _, payload, _ in order:
        for v in payload:
            if isinstance(v, Node) and v.maxp:
                found = {}
                params_of(v, found)
                for p in sorted(found, key=lambda p: colour[p]):
                    if p not in ren:
                        ren[p] = CanonParam(len(ren))
    rmemo: dict = {}
    renamed = [(k, m, tuple(_rename(v, ren, rmemo) if isinstance(v, Node) else v for v in payload), n)
               for k, m, payload, n in items]
    return _key(renamed)


def _key(items: list[tuple]) -> tuple:
    from collections import Counter

    c: Counter = Counter()
    for kind, mode, payload, n in items:
        c[(kind, mode, payload)] += n
    return frozenset(c.items()),


def same_state(a: Context, b: Context) -> bool:
    """Are two contexts equal up to renaming of fresh names?"""
    return canonical_key(a) == canonical_key(b)


__all__ = ["canonical_key", "same_state"]
_unused: Optional[int] = None
