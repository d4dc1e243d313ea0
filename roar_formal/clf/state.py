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

from array import array
from typing import Optional

from .context import Context
from .rules import AFF, LIN, PERS
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


def _other_items(ctx: Context) -> list[tuple]:
    """(kind, mode, payload tuple of terms or None, multiplicity) for every rule and inert hypothesis."""
    items: list[tuple] = []
    for r in ctx.rules.values():
        items.append(("r", r.mode, (id(r.alts[0]) if r.alts else 0,) + tuple(r.env), 1))
    for mode, t in ctx.inert:
        items.append(("i", mode, (t,), 1))
    return items


#: Caches keyed by hash-consed terms (facts recur from state to state): a term's fresh
#: names in params_of's order of discovery; its shape given the colours of those names;
#: its renaming given their new names. Each is emptied when it reaches _MEMO_MAX entries.
_params_memo: dict = {}
_shape_memo: dict = {}
_rename_memo: dict = {}
_MEMO_MAX = 500_000


def _params(t: Node) -> tuple:
    r = _params_memo.get(t)
    if r is None:
        if len(_params_memo) >= _MEMO_MAX:
            _params_memo.clear()
        r = _params_memo[t] = tuple(params_of(t, {}))
    return r


def _shape_of(t: Node, ps: tuple, colour: dict, memo: dict) -> int:
    """``_shape(t, colour, memo)``, which depends only on ``t`` and its names' colours."""
    k = (t, colour[ps[0]]) if len(ps) == 1 else (t, tuple([colour[p] for p in ps]))
    r = _shape_memo.get(k)
    if r is None:
        if len(_shape_memo) >= _MEMO_MAX:
            _shape_memo.clear()
        r = _shape_memo[k] = _shape(t, colour, memo)
    return r


def _rename_of(t: Node, ps: tuple, ren: dict, memo: dict) -> Node:
    """``_rename(t, ren, memo)``, which depends only on ``t`` and its names' new names."""
    k = (t, ren[ps[0]]) if len(ps) == 1 else (t, tuple([ren[p] for p in ps]))
    r = _rename_memo.get(k)
    if r is None:
        if len(_rename_memo) >= _MEMO_MAX:
            _rename_memo.clear()
        r = _rename_memo[k] = _rename(t, ren, memo)
    return r


def canonical_key(ctx: Context, rounds: int = 3) -> tuple:
    """A hashable key equal for contexts equal up to renaming of fresh names.

    Cached on the context until it changes (the explorer asks twice for each new
    state). Hypotheses without fresh names take no part in the renaming: only the
    others are coloured, sorted and renamed (a stable sort of a subset keeps the
    subset's order, so the renaming is the one sorting every hypothesis gives)."""
    if rounds == 3:
        cached = getattr(ctx, "_canon", None)
        # the context's mutators clear the cache; its inert list is appended to directly
        if cached is not None and cached[0] is ctx.inert and cached[1] == len(ctx.inert):
            return cached[2]
    key = _canonical_key(ctx, rounds)
    if rounds == 3:
        ctx._canon = (ctx.inert, len(ctx.inert), key)
    return key


def _canonical_key(ctx: Context, rounds: int) -> tuple:
    # Every hypothesis is (kind, mode, payload tuple of terms or None, multiplicity): a fact
    # ("f", mode, (t,), n), a rule ("r", mode, (id of its first alternative, *env), 1), an
    # inert one ("i", mode, (t,), 1), in this order. Those without fresh names go to
    # ``static`` as (key entry, multiplicity); the others to ``pitems``, with
    # ((payload position, its names), ...), the payload's shapes, its term if it is one
    # and that term's name if it has one.
    static: list = []
    pitems: list[tuple] = []
    params: dict = {}
    pmemo = _params_memo
    for mode, d in ((LIN, ctx.lin), (AFF, ctx.aff), (PERS, ctx.pers)):
        for t, n in d.items():
            if mode == PERS:
                n = 1
            if t.maxp:
                ps = pmemo.get(t)
                if ps is None:
                    ps = _params(t)
                pitems.append(("f", mode, (t,), n, ((0, ps),), [None], t, ps[0] if len(ps) == 1 else None))
                for p in ps:
                    params[p] = None
            else:
                static.append((("f", mode, (t,)), n))
    for it in _other_items(ctx):
        payload = it[2]
        pl = []
        pos = 0
        for v in payload:
            if isinstance(v, Node) and v.maxp:
                ps = _params(v)
                pl.append((pos, ps))
                for p in ps:
                    params[p] = None
            pos += 1
        if not pl:
            static.append((it[:3], it[3]))
        elif len(payload) == 1:
            ps = pl[0][1]
            pitems.append(it + (tuple(pl), [None], payload[0], ps[0] if len(ps) == 1 else None))
        else:
            pitems.append(it + (tuple(pl), [None] * len(payload), None, None))
    counts: dict = {}
    for k, n in static:
        counts[k] = counts.get(k, 0) + n
    if not params:
        return _compact(counts)
    colour = dict.fromkeys(params, 0)
    ncolours = 1
    smemo = _shape_memo
    for _ in range(rounds):
        memo: dict = {}
        occ: dict = {p: [] for p in params}
        for kind, mode, payload, n, pl, shapes, one, p0 in pitems:
            if p0 is not None:  # one term, one name: _shape_of inlined
                sh = smemo.get((one, colour[p0]))
                if sh is None:
                    sh = _shape_of(one, (p0,), colour, memo)
                shapes[0] = sh
                occ[p0].append((hash((kind, mode, n, (sh,))), 0))
                continue
            if one is not None:
                ps = pl[0][1]
                sh = shapes[0] = _shape_of(one, ps, colour, memo)
                sh = hash((kind, mode, n, (sh,)))
                for p in ps:
                    occ[p].append((sh, 0))
                continue
            _shapes(payload, pl, shapes, colour, memo)
            sh = hash((kind, mode, n, tuple(shapes)))
            for pos, ps in pl:
                for p in ps:
                    occ[p].append((sh, pos))
        new = {p: hash(tuple(sorted(o))) for p, o in occ.items()}
        nnew = len(set(new.values()))
        stable = nnew == ncolours
        colour = new
        ncolours = nnew
        if stable or nnew == len(colour):
            break   # the partition no longer refines (or every parameter is told apart)
    memo = {}
    for kind, mode, payload, n, pl, shapes, one, p0 in pitems:
        if p0 is not None:
            sh = smemo.get((one, colour[p0]))
            shapes[0] = sh if sh is not None else _shape_of(one, (p0,), colour, memo)
            continue
        if one is not None:
            shapes[0] = _shape_of(one, pl[0][1], colour, memo)
            continue
        _shapes(payload, pl, shapes, colour, memo)
        for i, v in enumerate(payload):
            if v is None:
                shapes[i] = -1
    order = sorted(pitems, key=lambda it: (it[0], it[1], it[3], tuple(it[5])))
    ren: dict = {}
    for it in order:
        for _pos, ps in it[4]:
            for p in (sorted(ps, key=colour.__getitem__) if len(ps) > 1 else ps):
                if p not in ren:
                    ren[p] = CanonParam(len(ren))
    rmemo: dict = {}
    rnmemo = _rename_memo
    for kind, mode, payload, n, pl, shapes, one, p0 in pitems:
        if p0 is not None:
            r = rnmemo.get((one, ren[p0]))
            payload = (r if r is not None else _rename_of(one, (p0,), ren, rmemo),)
        elif one is not None:
            payload = (_rename_of(one, pl[0][1], ren, rmemo),)
        else:
            payload = tuple([_rename_of(v, _params(v), ren, rmemo) if isinstance(v, Node) and v.maxp else v
                             for v in payload])
        k = (kind, mode, payload)
        counts[k] = counts.get(k, 0) + n
    return _compact(counts)


#: every (kind, mode, payload) a key has held -> a number (terms are hash-consed for the
#: process's life, so this table grows with the distinct hypotheses, not with the states)
_item_ids: dict = {}


def _compact(counts: dict) -> bytes:
    """The multiset ``counts`` as a short byte string, equal exactly when the multisets are
    equal: each item's number and multiplicity in one 64-bit word, sorted. A visited state's
    key costs 8 bytes per distinct hypothesis instead of a frozenset of tuples (benchmark B8)."""
    ids = _item_ids
    words = []
    for k, n in counts.items():
        i = ids.get(k)
        if i is None:
            i = ids[k] = len(ids)
        if n >= 1 << 24:   # (a multiplicity past 16 million: no room in the word) pragma: no cover
            raise OverflowError("a hypothesis occurs more than 16,777,215 times")
        words.append(i << 24 | n)
    words.sort()
    return array("Q", words).tobytes()


def _shapes(payload: tuple, pl: tuple, shapes: list, colour: dict, memo: dict) -> None:
    """Fill ``shapes`` with ``_shape`` of each term of ``payload`` (other entries as they are)."""
    j = 0
    for v in payload:
        shapes[j] = v if not isinstance(v, Node) else (hash(v) if not v.maxp else None)
        j += 1
    for pos, ps in pl:
        shapes[pos] = _shape_of(payload[pos], ps, colour, memo)


def same_state(a: Context, b: Context) -> bool:
    """Are two contexts equal up to renaming of fresh names?"""
    return canonical_key(a) == canonical_key(b)


__all__ = ["canonical_key", "same_state"]
_unused: Optional[int] = None
