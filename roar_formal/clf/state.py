"""Contexts as values: hashable keys, equal up to renaming of fresh names.

Fresh names (destinations, channels, cells made by ``Exists``) differ from
run to run, so two contexts that differ only by a renaming must be one state.
:func:`canonical_key` renames parameters to canonical ones in an order fixed
by the context's shape: parameters are coloured by where they occur (colour
refinement, a few rounds), facts are sorted by their coloured shape, and
parameters are numbered by first occurrence in that order. Names refinement
cannot tell apart are individualised one at a time (the least key of the
search's leaves, at most ``_LEAVES`` of them). The result is always a renaming
of the context (so distinct states are never merged); isomorphic contexts get
the same key unless a tie needs more leaves than that.
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
_MEMO_MAX = 200_000


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


def _canonical_key(ctx: Context, rounds: int) -> bytes:
    """The key: by the fast path when it applies (see ``_fast_key``), else by
    ``_numbered_key``."""
    key = _fast_key(ctx, rounds)
    return key if key is not None else _numbered_key(ctx, rounds)


def _numbered_key(ctx: Context, rounds: int) -> bytes:
    """The key by colour refinement, a sort of the hypotheses by coloured shape and names
    numbered by first occurrence in that order (any context)."""
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
    colour, ncolours = _refine(pitems, dict.fromkeys(params, 0), 1, rounds, False)
    if ncolours == len(colour):
        return _numbered(pitems, colour, counts)
    return _individualised(pitems, colour, counts, rounds)


def _refine(pitems: list, colour: dict, ncolours: int, rounds: int, keep: bool) -> tuple[dict, int]:
    """Colour refinement of the names of ``pitems`` for at most ``rounds`` rounds, from
    ``colour``: a name's new colour hashes the multiset of its occurrences (the shape of each
    hypothesis it occurs in under the current colours, and its position there), and with
    ``keep`` its own colour too (after an individualisation, which no occurrence shows)."""
    smemo = _shape_memo
    for _ in range(rounds):
        memo: dict = {}
        occ: dict = {p: [] for p in colour}
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
        if keep:
            new = {p: hash((colour[p], tuple(sorted(o)))) for p, o in occ.items()}
        else:
            new = {p: hash(tuple(sorted(o))) for p, o in occ.items()}
        nnew = len(set(new.values()))
        stable = nnew == ncolours
        colour = new
        ncolours = nnew
        if stable or nnew == len(colour):
            break   # the partition no longer refines (or every parameter is told apart)
    return colour, ncolours


#: leaves of the individualisation search (``_individualised``) tried per key at most
_LEAVES = 32


def _individualised(pitems: list, colour: dict, static: dict, rounds: int) -> bytes:
    """The key of a state whose refined colouring keeps a tie: names of one colour that
    refinement cannot tell apart, as in two continuations of one rule each holding a fresh name
    with a fact of its own. Numbering them in the order the context happens to hold them gave
    isomorphic states different keys. Instead each name of the smallest tied colour is given a
    colour of its own in turn and the colouring refined again, recursively until no tie is left;
    the key is the least of the keys of those leaves. The cell chosen at each level and the
    leaves' keys depend on the state up to renaming alone, so isomorphic states get one key. The
    search stops after ``_LEAVES`` leaves (a tie among many interchangeable names, which would
    need a factorial of them): the least key found then is still a renaming of the state (never
    merging different states), but two isomorphic states may again get two keys."""
    best: list = [None]
    left = [_LEAVES]

    def go(colour: dict) -> None:
        cells: dict = {}
        for p, c in colour.items():
            cells.setdefault(c, []).append(p)
        tied = [ps for ps in cells.values() if len(ps) > 1]
        if not tied or left[0] <= 1:
            left[0] -= 1
            key = _numbered(pitems, colour, static)
            if best[0] is None or key < best[0]:
                best[0] = key
            return
        cell = min(tied, key=lambda ps: (len(ps), colour[ps[0]]))
        mark = hash((colour[cell[0]], "individual"))
        for p in cell:
            if left[0] <= 0:
                return
            new = dict(colour)
            new[p] = mark
            new, _n = _refine(pitems, new, len(cells) + 1, rounds, True)
            go(new)

    go(colour)
    return best[0]


def _numbered(pitems: list, colour: dict, static: dict) -> bytes:
    """The key: the hypotheses with names sorted by their shapes under ``colour``, the names
    numbered by first occurrence in that order, the renamed hypotheses counted with ``static``."""
    counts = dict(static)
    memo: dict = {}
    smemo = _shape_memo
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
    equal: each item's number and multiplicity in one word, sorted (see ``_words_bytes``). A
    visited state's key costs 4 bytes per distinct hypothesis instead of a frozenset of tuples
    (benchmark B8)."""
    ids = _item_ids
    words = []
    big = False
    for k, n in counts.items():
        i = ids.get(k)
        if i is None:
            i = ids[k] = len(ids)
        if n >= 256 or i >= _NARROW_IDS:
            big = True
        words.append(i << 8 | n)
    if big:
        return _wide(counts)
    return _words_bytes(words)


#: item numbers below this, multiplicities below 256: a key's words are 32 bits (``_words_bytes``)
_NARROW_IDS = (1 << 24) - 1


def _words_bytes(words: list) -> bytes:
    """Narrow words (item number << 8 | multiplicity, each below 2^32, never 0), sorted, as
    bytes; a zero word after them when their count is odd, so that a key is a whole number of
    8-byte units. A key with an item number or a multiplicity too large for a narrow word is
    written by ``_wide`` instead, behind a marker word no narrow key begins with."""
    words.sort()
    if len(words) & 1:
        words.append(0)
    return array("I", words).tobytes()


_WIDE_MARK = array("Q", [(1 << 64) - 1]).tobytes()


def _wide(counts: dict) -> bytes:
    """``_compact`` with 64-bit words (number << 24 | multiplicity) behind ``_WIDE_MARK``."""
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
    return _WIDE_MARK + array("Q", words).tobytes()


def _shapes(payload: tuple, pl: tuple, shapes: list, colour: dict, memo: dict) -> None:
    """Fill ``shapes`` with ``_shape`` of each term of ``payload`` (other entries as they are)."""
    j = 0
    for v in payload:
        shapes[j] = v if not isinstance(v, Node) else (hash(v) if not v.maxp else None)
        j += 1
    for pos, ps in pl:
        shapes[pos] = _shape_of(payload[pos], ps, colour, memo)


# ---------------------------------------------------------------- the fast path
#
# Colour refinement partitions the fresh names alike however a round's colours are encoded:
# names p and q get one colour exactly when their occurrences, (hypothesis shape under the
# previous colours, payload position), are the same multiset. ``_numbered_key`` encodes a
# fact's shape by hashing the term with each name replaced by its colour; the fast path
# encodes the same information as (the term with every name replaced by one placeholder, the
# colours of the names in the order they occur): per term, the placeholder term and that
# order are computed once, and a round costs a tuple hash per fact instead of a walk of it.
# So both refine to the same partitions round by round, and stop at the same round.
#
# When the final colouring is discrete (every name its own colour: the usual case, a fresh
# name is a request, an activation, a destination, each with facts of its own), the colours
# themselves name the names: a fact becomes (mode, the term with its names numbered in the
# order params_of finds them, their colours). That is an injective renaming of the state (so
# two states with one key are equal up to renaming), and isomorphic states get the same
# colours (so equal up to renaming gives one key): in that case the key is exact, as
# ``_numbered_key``'s first-occurrence numbering is, without its sort and its renaming of
# every fact. A state whose colouring keeps a tie, or with a rule or an inert hypothesis
# holding a fresh name, takes ``_numbered_key`` as before: the states equal under one path
# are those equal under the other.

#: term -> (its names in params_of's order (None when it has one), placeholder term, its names
#: in occurrence order (with repeats; None when it has one), the term with its names numbered
#: locally, its name when it has one, its first-round code as a linear fact): every fact recurs from state
#: to state, so this is computed once per distinct fact. Emptied at _INFO_MAX entries (the
#: values are hash-consed terms and tuples: recomputing gives the same objects): a fact's
#: entry serves the states of the frontier that hold it, and kept for every fact ever seen the
#: table would grow by about 200 bytes per state visited (benchmark B8).
_term_info: dict = {}
_INFO_MAX = 2048
_PLACEHOLDER = CanonParam(-1)


def _info(t: Node) -> tuple:
    r = _term_info.get(t)
    if r is None:
        if len(_term_info) >= _INFO_MAX:
            _term_info.clear()
        ps = tuple(params_of(t, {}))
        abs0, local = _abs_local(t, {p: CanonParam(i) for i, p in enumerate(ps)})
        if len(ps) == 1:   # (the usual case: one name, no order of occurrence to keep)
            p0 = ps[0]
            ps = seq = None
        else:
            p0 = None
            seq = []
            _occurrences(t, seq)
            seq = tuple(seq)
        code = _abs_codes.get(abs0)
        if code is None:
            if len(_abs_codes) >= _MEMO_MAX:
                _abs_codes.clear()
            code = _abs_codes[abs0] = _code0(LIN, 1, abs0, seq, p0)
        r = _term_info[t] = (ps, abs0, seq, local, p0, code)
    return r


#: placeholder term -> its first-round code as a linear fact (shared by the facts of one shape)
_abs_codes: dict = {}


def _abs_local(t: Node, ren: dict) -> tuple:
    """(``t`` with every fresh name replaced by the placeholder, ``t`` renamed by ``ren``), in one walk."""
    if not t.maxp:
        return t, t
    tt = type(t)
    if tt is Root:
        h = t.head
        r = ren.get(h)
        a0 = []
        a1 = []
        for a in t.args:
            if a.maxp:
                x, y = _abs_local(a, ren)
                a0.append(x)
                a1.append(y)
            else:
                a0.append(a)
                a1.append(a)
        if r is None:
            return Root(h, tuple(a0)), Root(h, tuple(a1))
        return Root(_PLACEHOLDER, tuple(a0)), Root(r, tuple(a1))
    if tt is Lam:
        x, y = _abs_local(t.body, ren)
        return Lam(x), Lam(y)
    return _rename(t, dict.fromkeys(ren, _PLACEHOLDER), {}), _rename(t, ren, {})


def _code0(mode: str, n: int, abs0: Node, seq, p0) -> int:
    """A fact's code in the first round of refinement (every name of colour 0)."""
    return hash((mode, n, abs0, 0))


def _code(mode: str, n: int, abs0: Node, cols: list) -> int:
    """A fact's code given the colours of its names in order of occurrence: (mode, n, abs0, c)
    when they are all one colour c (as a fact with one name always has: ``abs0`` says how
    many times it occurs), else (mode, n, abs0, the colours). Two facts get one code exactly
    when they have one shape under the colouring, whatever their number of names."""
    c = cols[0]
    for x in cols:
        if x != c:
            return hash((mode, n, abs0, tuple(cols)))
    return hash((mode, n, abs0, c))



def _occurrences(t: Node, out: list) -> None:
    """Append the fresh names of ``t`` as they occur, preorder (head, then arguments)."""
    if not t.maxp:
        return
    tt = type(t)
    if tt is Root:
        h = t.head
        if isinstance(h, Param) and h.id > 0:
            out.append(h)
        for a in t.args:
            _occurrences(a, out)
    elif tt is Lam:
        _occurrences(t.body, out)
    else:
        for f in tt.fields:
            v = getattr(t, f)
            if isinstance(v, Node):
                _occurrences(v, out)


#: per mode, a fact without fresh names -> its number in _item_ids
_static_ids: dict = {LIN: {}, AFF: {}, PERS: {}}


def _fast_key(ctx: Context, rounds: int):
    """The key of a context whose hypotheses with fresh names are all facts and whose colouring
    ends discrete (see above); None otherwise (``_numbered_key`` decides)."""
    for r in ctx.rules.values():
        if any(isinstance(v, Node) and v.maxp for v in r.env):
            return None
    for _mode, t in ctx.inert:
        if t.maxp:
            return None
    ids = _item_ids
    words: list = []
    items: list = []
    info_memo = _term_info
    for mode, d in ((LIN, ctx.lin), (AFF, ctx.aff), (PERS, ctx.pers)):
        sids = _static_ids[mode]
        for t, n in d.items():
            if mode == PERS:
                n = 1
            if t.maxp:
                inf = info_memo.get(t)
                if inf is None:
                    inf = _info(t)
                items.append((mode, n, inf))
                continue
            i = sids.get(t)
            if i is None:
                k = ("f", mode, (t,))
                i = ids.get(k)
                if i is None:
                    i = ids[k] = len(ids)
                sids[t] = i
            if n >= 256 or i >= _NARROW_IDS:
                return None   # (a wide key: _numbered_key writes it)
            words.append(i << 8 | n)
    if ctx.rules or ctx.inert:
        for k, n in _static_others(ctx).items():
            i = ids.get(k)
            if i is None:
                i = ids[k] = len(ids)
            if n >= 256 or i >= _NARROW_IDS:
                return None
            words.append(i << 8 | n)
    if not items:
        return _words_bytes(words)
    if rounds < 1:
        return None
    # the first round (every name of colour 0): each fact's code depends on the fact alone
    occ: dict = {}
    for mode, n, (ps, abs0, seq, _local, p0, code) in items:
        if n != 1 or mode != LIN:
            code = _code0(mode, n, abs0, seq, p0)
        if p0 is not None:
            o = occ.get(p0)
            if o is None:
                occ[p0] = [code]
            else:
                o.append(code)
            continue
        for p in ps:
            o = occ.get(p)
            if o is None:
                occ[p] = [code]
            else:
                o.append(code)
    colour = {p: hash((o[0],)) if len(o) == 1 else hash(tuple(sorted(o))) for p, o in occ.items()}
    nparams = len(colour)
    ncolours = len(set(colour.values()))
    stable = ncolours == 1
    for _ in range(rounds - 1):
        if stable or ncolours == nparams:
            break
        occ = {p: [] for p in colour}
        for mode, n, (ps, abs0, seq, _local, p0, _c0) in items:
            if p0 is not None:
                occ[p0].append(hash((mode, n, abs0, colour[p0])))
                continue
            code = _code(mode, n, abs0, [colour[p] for p in seq])
            for p in ps:
                occ[p].append(code)
        colour = {p: hash(tuple(sorted(o))) for p, o in occ.items()}
        nnew = len(set(colour.values()))
        stable = nnew == ncolours
        ncolours = nnew
    if ncolours != nparams:
        return None   # a tie: the first-occurrence numbering decides (_numbered_key)
    # each name by its colour's rank among the state's colours (one name a colour): the items'
    # numbers then recur from state to state. Numbered by the colours themselves, a fact holding
    # several names (an activation's locals) was a new item in almost every state, and the table
    # of items grew by about 450 bytes a visited state (benchmark B8, fan-8)
    rank = {c: i for i, c in enumerate(sorted(colour.values()))}
    for mode, n, (ps, _abs0, _seq, local, p0, _c0) in items:
        k = (mode, local, rank[colour[p0]]) if p0 is not None else (
            mode, local, tuple([rank[colour[p]] for p in ps]))
        i = ids.get(k)
        if i is None:
            i = ids[k] = len(ids)
        if n >= 256 or i >= _NARROW_IDS:
            return None
        words.append(i << 8 | n)
    return _words_bytes(words)


def _static_others(ctx: Context) -> dict:
    """The rules and inert hypotheses (none with a fresh name), as ``_numbered_key`` counts them."""
    counts: dict = {}
    for it in _other_items(ctx):
        k = it[:3]
        counts[k] = counts.get(k, 0) + it[3]
    return counts


def same_state(a: Context, b: Context) -> bool:
    """Are two contexts equal up to renaming of fresh names?"""
    return canonical_key(a) == canonical_key(b)


__all__ = ["canonical_key", "same_state"]
_unused: Optional[int] = None
