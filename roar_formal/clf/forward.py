"""Forward chaining inside the monad: one matcher, two drivers.

* :func:`all_matches` is the matcher: the ways a template's premises can be found in a
  context (premises ordered on the fly, most selective first, through the context's
  argument index), every one or only the first (:func:`first_match`). Both drivers use it,
  so the first match of a template is always the first of its matches
  (``tests/clf/test_one_matcher.py`` checks it step by step along runs).
  :func:`find_matches` is the plain generator it replaced, kept as the tests' reference.
* :class:`Run` is the committed-choice driver: a seeded random or fair
  round-robin scheduler over an agenda of rules that might be enabled; a rule
  leaves the agenda when it fails to match and comes back only when a fact it
  could use is added (consumption never enables a rule), so quiescence is
  detected without rescanning.
* :func:`enabled_steps` and :func:`successor` are the explorer's API: every
  enabled step of a state and the state each one gives.
"""

from __future__ import annotations

import gc
import random
from dataclasses import dataclass, field
from typing import Callable, Iterator, Optional

from .builtins import BUILTINS
from .context import Context, CtxRule, add_count, take_count
from .rules import AFF, LIN, PERS, Template, positive_parts
from .terms import (BVar, Const, EVar, Lam, Lit, Meta, Node, Param, Root, Top, apply, subst, zonk, map_bvars, bvar,
                    next_param_id, skip_param_ids)

# ------------------------------------------------------------------ matching


def match(p: Node, t: Node, b: list, trail: list) -> bool:
    """One-way matching of pattern ``p`` (slots as :class:`Meta`) against ground ``t``."""
    if not p.metas:
        return p is t
    tp = type(p)
    if tp is Root:
        h = p.head
        if type(h) is Meta:
            i = h.index
            if not p.args:
                v = b[i]
                if v is None:
                    if t.maxb:  # would capture a variable bound inside the pattern
                        return False
                    b[i] = t
                    trail.append(i)
                    return True
                return v is t
            v = b[i]
            if v is not None:
                try:
                    return inst(p, b) is t
                except KeyError:
                    # the head is known (e.g. a name made by Exists) but an argument is still
                    # a slot (`rsp (L !B)` with L bound, B not): match the applied head
                    return match(apply(v, tuple(_inst_partial(a, b) for a in p.args)), t, b, trail)
            sol = _ho_solve(p.args, t)
            if sol is None:
                return False
            b[i] = sol
            trail.append(i)
            return True
        if type(t) is not Root or t.head is not h:
            return False
        pa = p.args
        ta = t.args
        if len(pa) != len(ta):
            return False
        for x, y in zip(pa, ta):
            if x is y:
                continue
            if not x.metas:
                return False  # both ground and hash-consed: equal only if identical
            if type(x) is Root and not x.args and type(x.head) is Meta:
                # a bare slot (the common case), inlined
                i = x.head.index
                v = b[i]
                if v is None:
                    if y.maxb:
                        return False
                    b[i] = y
                    trail.append(i)
                elif v is not y:
                    return False
                continue
            if not match(x, y, b, trail):
                return False
        return True
    if tp is Lam:
        return type(t) is Lam and match(p.body, t.body, b, trail)
    return False


def _ho_solve(args: tuple, t: Node) -> Optional[Node]:
    """Solve ``X a1..an = t`` where the ai are distinct bound variables (Miller pattern)."""
    idx = []
    for a in args:
        if type(a) is not Root or a.args or type(a.head) is not BVar or a.head.index in idx:
            return None
        idx.append(a.head.index)
    n = len(idx)
    newpos = {ix: n - 1 - k for k, ix in enumerate(idx)}

    class Escape(Exception):
        pass

    def fn(i: int, d: int) -> Node:
        j = i - d
        if j in newpos:
            return bvar(newpos[j] + d)
        raise Escape

    try:
        body = map_bvars(t, 0, fn) if t.maxb else t
    except Escape:
        return None
    for _ in range(n):
        body = Lam(body)
    return body


def _inst_partial(p: Node, b) -> Node:
    """Instantiate the bound slots of a pattern, leaving the unbound ones in place."""
    if not p.metas:
        return p
    tp = type(p)
    if tp is Root:
        args = tuple([_inst_partial(a, b) for a in p.args]) if p.args else ()
        h = p.head
        if type(h) is Meta:
            v = b[h.index]
            if v is None:
                return Root(h, args)
            return apply(v, args) if args else v
        return Root(h, args)
    if tp is Lam:
        return Lam(_inst_partial(p.body, b))
    return p


def inst(p: Node, b) -> Node:
    """Instantiate a pattern's slots with their values (beta-reducing applied slots)."""
    if not p.metas:
        return p
    tp = type(p)
    if tp is Root:
        args = tuple([inst(a, b) if a.metas else a for a in p.args]) if p.args else ()
        h = p.head
        if type(h) is Meta:
            v = b[h.index]
            if v is None:
                raise KeyError(f"slot {h.index} unbound")
            return apply(v, args) if args else v
        return Root(h, args)
    if tp is Lam:
        return Lam(inst(p.body, b))
    cls = type(p)
    return cls(*[inst(v, b) if isinstance(v, Node) else v for v in (getattr(p, f) for f in cls.fields)])


# Modes in which a fact may serve a premise, in preference order.
_SERVE = {LIN: (LIN, AFF, PERS), AFF: (AFF, PERS), PERS: (PERS,)}

Prover = Callable[[Context, Template, object, list, list], Iterator[None]]


def find_matches(ctx: Context, tpl: Template, b: list, start: int = -1,
                 prover: Optional[Prover] = None, all_modes: bool = False) -> Iterator[list]:
    """Yield the consumption list ``[(mode, fact), ...]`` of each match; ``b`` holds
    the bindings while the generator is suspended. ``start`` >= 0 rotates candidate
    lists (random or fair choice of instances).

    The plain enumeration, a generator suspended per premise: the engine matches with
    :func:`all_matches`; this is kept as the reference the tests compare it with."""
    plan, ctx_list, back = _plans(tpl)
    done = [False] * len(plan)
    used: dict = {}
    consumed: list = []
    trail: list = []
    ctx_prems = len(plan)
    index = ctx.index
    by_arg = ctx.by_arg
    lin, aff, pers = ctx.lin, ctx.aff, ctx.pers

    def go(k: int) -> Iterator[list]:
        if k == ctx_prems:
            if not back:
                yield consumed
                return
            if prover is None:
                return
            yield from _backward(0)
            return
        sel = _select(plan, done, b, index, by_arg)
        if sel is None:
            return
        best, best_bag, _n = sel
        p = ctx_list[best]
        done[best] = True
        pat = p.pattern
        it = best_bag.rotated(start) if start >= 0 else list(best_bag.items)
        for t in it:
            for mode in _SERVE[p.mode]:
                key = (mode, t)
                if not _available(key, lin, aff, pers, used):
                    continue
                mark = len(trail)
                if match(pat, t, b, trail):
                    if mode != PERS:
                        used[key] = used.get(key, 0) + 1
                    consumed.append((mode, t))
                    yield from go(k + 1)
                    consumed.pop()
                    if mode != PERS:
                        used[key] -= 1
                while len(trail) > mark:
                    b[trail.pop()] = None
                if not all_modes:
                    break
        done[best] = False

    def _backward(j: int) -> Iterator[list]:
        if j == len(back):
            yield consumed
            return
        p = back[j]
        mark = len(trail)
        for extra in prover(ctx, tpl, p, b, trail, consumed):
            if extra:  # facts a linear or affine premise's proof consumed
                consumed.extend(extra)
                yield from _backward(j + 1)
                del consumed[len(consumed) - len(extra):]
            else:
                yield from _backward(j + 1)
        while len(trail) > mark:
            b[trail.pop()] = None

    return go(0)



def _available(key: tuple, lin: dict, aff: dict, pers: dict, used: dict) -> bool:
    """Is one more copy of fact ``key[1]`` in mode ``key[0]`` left, after what this match used?"""
    mode, t = key
    if mode == PERS:
        return t in pers
    have = lin.get(t, 0) if mode == LIN else aff.get(t, 0)
    return have > used.get(key, 0)


_CONST, _SLOT, _PATTERN = 0, 1, 2


def _plans(tpl: Template) -> tuple:
    """(per context premise: (serve modes, family, arity, ((position, kind, value), ...), the
    index keys among them: those of constants and bare slots), the context premises, the
    proved premises), made once per template."""
    got = tpl.match_plan
    if got is None:
        ctx_list = tuple(p for p in tpl.premises if not p.backward)
        got = tpl.match_plan = (tuple(_premise_plan(p.mode, p.pattern) for p in ctx_list), ctx_list,
                                tuple(p for p in tpl.premises if p.backward))
    return got


def _premise_plan(mode: str, pat: Node) -> tuple:
    """How a premise is looked up and matched: each argument a constant (an index key), a
    bare slot (an index key once bound) or a pattern for :func:`match`."""
    args = []
    for j, a in enumerate(pat.args):
        if not a.metas:
            # a ground argument; one with a bound variable cannot be an index key
            args.append((j, _PATTERN if a.maxb else _CONST, a))
        elif type(a) is Root and not a.args and type(a.head) is Meta:
            args.append((j, _SLOT, a.head.index))
        else:
            args.append((j, _PATTERN, a))
    keyed = tuple(x for x in args if x[1] != _PATTERN)
    return _SERVE[mode], pat.head, len(pat.args), tuple(args), keyed


def _select(plan, done: list, b: list, index: dict, by_arg: dict):
    """The remaining premise with the fewest candidates (the first on ties) and its
    candidate bag; None when some premise has none (no match is possible).

    The scan stops at a premise with one candidate: no later one can have fewer but none,
    and a premise with none still has none once more slots are bound, so the search below
    finds no match either way (the matches, and their order, are those of a full scan)."""
    best = -1
    best_bag = None
    best_n = 0
    i = -1
    for _modes, fam, _arity, _args, keyed in plan:
        i += 1
        if done[i]:
            continue
        bag = None
        bag_n = 0
        if keyed:
            per = by_arg.get(fam)
            for j, kind, v in keyed:
                if kind == _SLOT:
                    v = b[v]
                    if v is None:
                        continue
                bag2 = per[j].get(v) if per is not None and j < len(per) else None
                if bag2 is None:
                    return None
                n2 = len(bag2.items)
                if not n2:
                    return None
                if bag is None or n2 < bag_n:
                    bag, bag_n = bag2, n2
        if bag is None:
            bag = index.get(fam)
            if bag is None:
                return None
            bag_n = len(bag.items)
            if not bag_n:
                return None
        if best < 0 or bag_n < best_n:
            best, best_bag, best_n = i, bag, bag_n
            if bag_n == 1:
                break
    return best, best_bag, best_n


def all_matches(ctx: Context, tpl: Template, b: list, prover: Optional[Prover] = None,
                first_only: bool = False, start: int = -1) -> list[tuple[tuple, tuple]]:
    """``(bindings, consumption)`` of every match of ``tpl`` in ``ctx`` (the first one only if
    ``first_only``): the one matcher of the engine, used by the explorer (every match) and by
    committed choice (:func:`first_match`, the first one). ``b`` holds the slots' initial values
    and is left as it was.

    The search: the remaining context premise with the fewest candidates first (through the
    argument index; the first on ties), its candidates in bag order (rotated to begin at
    ``start`` when ``start`` > 0: random or fair choice of instances), each candidate in every
    mode it can serve in, then the premises proved by ``prover``, in the order written. Each
    premise is matched through a per-template plan of its arguments (a constant, a bare slot
    or a pattern for :func:`match`), with plain recursion collecting the matches rather than a
    generator suspended per premise. The same order as :func:`find_matches` (the plain
    enumeration, kept as the tests' reference) with ``all_modes=True``."""
    ctx_plan, _ctx_list, back = _plans(tpl)
    if back and prover is None:
        return []
    out: list = []
    _search(ctx_plan, len(ctx_plan), [False] * len(ctx_plan), b, [], [], ctx, tpl, back, prover, out, first_only,
            start)
    return out


def first_match(ctx: Context, tpl: Template, b: list, start: int,
                prover: Optional[Prover] = None) -> Optional[list]:
    """The first match of a template (the committed-choice step): the first element of
    :func:`all_matches` with the same ``start``, by the same search stopped at its first match.
    On a match ``b`` receives the bindings and the consumption list is returned; None (``b``
    unchanged) when there is none."""
    found = all_matches(ctx, tpl, b, prover, True, start)
    if not found:
        return None
    bindings, consumed = found[0]
    b[:] = bindings
    return list(consumed)


def _search(plan, left, done, b, consumed, trail, ctx, tpl, back, prover, out, first_only, start) -> bool:
    """Extend the current partial match by the remaining context premises; True to stop
    (``first_only`` and a match was found).

    The last context premise of a rule with no proved premise records its matches in place
    (no call per match), and a context of linear facts only (a compiled ROAR model's) takes a
    loop without the modes: the same matches in the same order, for less interpretation."""
    if not left:
        if back:
            return _search_back(0, back, b, consumed, trail, ctx, tpl, prover, out, first_only)
        out.append((tuple(b), tuple(consumed)))
        return first_only
    sel = _select(plan, done, b, ctx.index, ctx.by_arg)
    if sel is None:
        return False
    best, best_bag, n = sel
    modes, _fam, arity, args, _keyed = plan[best]
    lin, aff, pers = ctx.lin, ctx.aff, ctx.pers
    lin_only = not aff and not pers
    if lin_only:   # (linear facts only, as in a compiled ROAR model: no other mode to try)
        if modes[0] != LIN:
            return False
    leaf = left == 1 and not back   # a match is complete once this premise is matched
    done[best] = True
    items = best_bag.items
    if start > 0 and n > 1 and start % n:
        first = start % n
        items = items[first:] + items[:first]
    stop = False
    if lin_only:
        # (the loop below, specialised: one mode and no per-mode counts; the matching of the
        # arguments is repeated inline rather than called, as this is the explorer's hottest loop)
        for t in items:
            targs = t.args
            if len(targs) != arity:
                continue
            # is one more copy of t left, after what this match used? (terms compare by identity)
            if consumed and lin.get(t, 0) <= consumed.count((LIN, t)):
                continue
            mark = len(trail)
            ok = True
            for j, kind, v in args:
                a = targs[j]
                if kind == _SLOT:
                    w = b[v]
                    if w is None:
                        if a.maxb:   # would capture a variable bound inside the pattern
                            ok = False
                            break
                        b[v] = a
                        trail.append(v)
                    elif w is not a:
                        ok = False
                        break
                elif kind == _CONST:
                    if a is not v:
                        ok = False
                        break
                elif not match(v, a, b, trail):
                    ok = False
                    break
            if ok:
                if leaf:
                    out.append((tuple(b), (*consumed, (LIN, t))))
                    stop = first_only
                else:
                    consumed.append((LIN, t))
                    stop = _search(plan, left - 1, done, b, consumed, trail, ctx, tpl, back, prover, out,
                                   first_only, start)
                    consumed.pop()
            while len(trail) > mark:
                b[trail.pop()] = None
            if stop:
                break
        done[best] = False
        return stop
    for t in items:
        targs = t.args
        if len(targs) != arity:
            continue
        for mode in modes:
            # is one more copy of t left in this mode, after what this match used?
            if mode == PERS:
                if t not in pers:
                    continue
            else:
                have = lin.get(t, 0) if mode == LIN else aff.get(t, 0)
                if not have:
                    continue
                if consumed and have <= consumed.count((mode, t)):   # (terms compare by identity)
                    continue
            mark = len(trail)
            ok = True
            for j, kind, v in args:
                a = targs[j]
                if kind == _SLOT:
                    w = b[v]
                    if w is None:
                        if a.maxb:   # would capture a variable bound inside the pattern
                            ok = False
                            break
                        b[v] = a
                        trail.append(v)
                    elif w is not a:
                        ok = False
                        break
                elif kind == _CONST:
                    if a is not v:
                        ok = False
                        break
                elif not match(v, a, b, trail):
                    ok = False
                    break
            if ok:
                if leaf:
                    out.append((tuple(b), (*consumed, (mode, t))))
                    stop = first_only
                else:
                    consumed.append((mode, t))
                    stop = _search(plan, left - 1, done, b, consumed, trail, ctx, tpl, back, prover, out,
                                   first_only, start)
                    consumed.pop()
            while len(trail) > mark:
                b[trail.pop()] = None
            if stop or not ok:
                break   # (a fact the pattern does not match fails in every mode alike)
        if stop:
            break
    done[best] = False
    return stop


def _search_back(k, back, b, consumed, trail, ctx, tpl, prover, out, first_only) -> bool:
    """The proved premises ``back[k:]``, in order, after the context premises matched."""
    if k == len(back):
        out.append((tuple(b), tuple(consumed)))
        return first_only
    mark = len(trail)
    quick = getattr(prover, "quick", None)
    if quick is not None:
        # a memoised answer (the same as the proof search below gives, without a generator)
        hit = quick(ctx, back[k], b)
        if hit is not None:
            found = hit[0]
            if found is None:
                return False
            for i, v in found:
                b[i] = v
                trail.append(i)
            stop = _search_back(k + 1, back, b, consumed, trail, ctx, tpl, prover, out, first_only)
            while len(trail) > mark:
                b[trail.pop()] = None
            return stop
    stop = False
    proofs = prover(ctx, tpl, back[k], b, trail, consumed)
    try:
        for extra in proofs:
            if extra:
                consumed.extend(extra)
            done = _search_back(k + 1, back, b, consumed, trail, ctx, tpl, prover, out, first_only)
            if extra:
                del consumed[len(consumed) - len(extra):]
            if done:
                stop = True
                break
    finally:
        if hasattr(proofs, "close"):
            proofs.close()
    while len(trail) > mark:
        b[trail.pop()] = None
    return stop


# ------------------------------------------------------------------ firing


@dataclass(slots=True)
class Step:
    """One committed forward step: which rule, with which facts, producing what."""

    rule: str
    template: Template
    bindings: tuple
    consumed: list  # [(mode, fact)]
    ctx_rule: Optional[int] = None  # uid of the context rule used, if any
    produced: list = field(default_factory=list)  # [(mode, fact or CtxRule)]


def fire(ctx: Context, tpl: Template, b: list, consumed: list, crule: Optional[CtxRule],
         general: bool = False) -> Step:
    """Apply a matched template to ``ctx`` (in place). ``general``: the match was made by the
    general path (its bindings and consumed facts may hold logic variables)."""
    step = Step(tpl.name, tpl, (), consumed, crule.uid if crule else None)  # bindings set below
    if general:
        for mode, t in consumed:
            ctx.remove_any(t, mode)
        for i, v in enumerate(b):
            if v is not None and v.evars:
                b[i] = zonk(v)
    else:
        for mode, t in consumed:
            ctx.remove_fact(t, mode)
    if crule is not None and crule.mode != PERS:
        ctx.remove_rule(crule)
    if tpl.open_slots:
        # Pi variables no premise determined: logic variables, as in Celf
        names = tpl.slot_names
        for s in tpl.open_slots:
            if b[s] is None:
                b[s] = Root(EVar(names[s] if s < len(names) else "X"), ())
        general = True
    produced = step.produced
    for act in tpl.head:
        kind = act[0]
        if kind == "fresh":
            b[act[1]] = Root(Param(act[2]), ())
        elif kind == "fact":
            if general:
                t = ctx.add_any(inst(act[2], b), act[1])
            else:
                t = inst(act[2], b)
                ctx.add_fact(t, act[1])
            produced.append((act[1], t))
        elif kind == "rule":
            _, mode, alts, src, envslots = act
            vals = [b[s] for s in reversed(envslots)]
            source = subst(src, vals) if vals else src
            r = ctx.add_rule(alts, tuple(b), mode, source)
            if general and (source.evars or any(v is not None and v.evars for v in b)):
                r.open = True
            produced.append((mode, r))
        else:
            ctx.inert.append((act[1], act[2]))
    step.bindings = tuple(b)
    return step


# ------------------------------------------------------------------ the general path


def general_match(ctx: Context, tpl: Template, b: list, start: int, u, prover) -> Optional[list]:
    """The first match of ``tpl`` by unification (Celf's semantics for contexts holding logic
    variables): every unbound slot is a fresh logic variable; the premises found in the
    context are taken the one with the fewest candidate facts first (as on the ground path),
    each unified with the facts of its family, ground (through the argument index once an
    argument is known) and open; then the premises proved by backward chaining, in the order
    written, go to the proof search. Committed to the first match. The bindings stay in the unifier ``u`` (undone by whoever owns it, e.g. the
    backtracking around a monad); ``b`` receives the slots' values. None when no match."""
    vals = list(b)
    names = tpl.slot_names
    for i, v in enumerate(vals):
        if v is None:
            vals[i] = Root(EVar(names[i] if i < len(names) else f"s{i}"), ())
    prems = tpl.premises
    consumed: list = []
    index = ctx.index
    by_arg = ctx.by_arg
    lin, aff, pers = ctx.lin, ctx.aff, ctx.pers
    bw = getattr(prover, "bw", None)

    def left(mode, t) -> bool:
        if mode == PERS:
            return True
        n = sum(1 for m, x in consumed if x is t and m == mode)
        if t.evars:
            return n == 0
        return (lin.get(t, 0) if mode == LIN else aff.get(t, 0)) > n

    ctx_prems = [p for p in prems if not p.backward]
    back_prems = [p for p in prems if p.backward]
    done = [False] * len(ctx_prems)
    nctx = len(ctx_prems)

    def pick() -> int:
        """The remaining context premise with the fewest candidate facts (-1: one has none)."""
        best, best_n = -2, 0
        for i, p in enumerate(ctx_prems):
            if done[i]:
                continue
            bag = index.get(p.family)
            n = (len(bag.items) if bag is not None else 0) + sum(1 for _m, t in ctx.open if t.head is p.family)
            if not n:
                return -1
            if best < 0 or n < best_n:
                best, best_n = i, n
        return best

    def go(k: int) -> bool:
        if k == len(prems):
            return True
        if k < nctx:
            i = pick()
            if i < 0:
                return False
            done[i] = True
            try:
                return ctx_premise(k, ctx_prems[i])
            finally:
                done[i] = False
        p = back_prems[k - nctx]
        goal = inst(p.pattern, vals)
        if p.backward:
            if p.family in BUILTINS:
                from .builtins import evaluate
                res = evaluate(BUILTINS[p.family], deref_args(goal))
                if res is None or res is False:
                    return False
                mark = u.mark()
                if res is True or u.unify(goal.args[-1], res):
                    if go(k + 1):
                        return True
                u.undo(mark)
                return False
            if bw is None:
                return False
            mark = u.mark()
            for extra in bw.prove_consuming(ctx, goal, p.mode, consumed):
                consumed.extend(extra)
                if go(k + 1):
                    return True
                del consumed[len(consumed) - len(extra):]
            u.undo(mark)
            return False
        return False

    def ctx_premise(k: int, p) -> bool:
        goal = inst(p.pattern, vals)
        fam = p.family
        serve = _SERVE[p.mode]
        # the ground facts: through the argument index when an argument is already known
        # (as on the ground path), else the family's bag; then the open facts of the family
        bag = index.get(fam)
        if bag is not None and type(goal) is Root and goal.args:
            per = by_arg.get(fam)
            for j, a in enumerate(goal.args):
                if a.evars:
                    a = zonk(a)
                if a.evars or a.maxb or per is None or j >= len(per):
                    continue
                b2 = per[j].get(a)
                if b2 is None:
                    bag = None
                    break
                if len(b2.items) < len(bag.items):
                    bag = b2
        items = bag.items if bag is not None else ()
        n = len(items)
        first = start % n if (start >= 0 and n) else 0
        for r in range(n):
            t = items[(first + r) % n]
            for mode in serve:
                if not ((t in pers) if mode == PERS else ((lin if mode == LIN else aff).get(t, 0) > 0)):
                    continue
                if not left(mode, t):
                    break
                mark = u.mark()
                if u.unify(goal, t):
                    consumed.append((mode, t))
                    if go(k + 1):
                        return True
                    consumed.pop()
                u.undo(mark)
                break
        for mode, t in ctx.open:
            if t.head is not fam or mode not in serve or not left(mode, t):
                continue
            mark = u.mark()
            if u.unify(goal, t):
                consumed.append((mode, t))
                if go(k + 1):
                    return True
                consumed.pop()
            u.undo(mark)
        return False

    mark = u.mark()
    if not go(0):
        u.undo(mark)
        return None
    if not u.solved():
        u.undo(mark)
        return None
    for i, v in enumerate(vals):
        b[i] = v
    return consumed


def deref_args(goal: Node) -> tuple:
    return tuple(zonk(a) for a in goal.args)


def open_families(templates, ctx: Context, program) -> tuple[set, set]:
    """Which families may hold open facts (facts with logic variables) in a run from ``ctx``,
    and which templates must therefore match by unification (the general path).

    Decided once per run, statically, by a closure over the rules: the families of the
    context's open facts and of the head facts of rules with an undetermined Pi variable
    are open; a rule with a premise of an open family (or proved from one: the families its
    clauses need) takes the general path, and the families its head produces become open
    too (its bindings may hold logic variables). Everything else keeps the ground fast path."""
    every: list = []

    def walk(t):
        every.append(t)
        for act in t.head:
            if act[0] == "rule":
                for sub in act[2]:
                    walk(sub)

    for t in templates:
        walk(t)
    for r in ctx.rules.values():
        for t in r.alts:
            walk(t)
    opened: set = {t.head for _m, t in ctx.open}
    seeded: list = [t for t in every if t.open_slots]
    for r in ctx.rules.values():
        if r.open:
            seeded.extend(r.alts)

    def heads(t, acc):
        for act in t.head:
            if act[0] == "fact":
                acc.add(act[2].head)
            elif act[0] == "rule":
                for sub in act[2]:
                    heads(sub, acc)

    for t in seeded:
        heads(t, opened)
    general: set = set()
    reads: dict = {}
    for t in every:
        fams = set()
        for p in t.premises:
            if p.family is None or p.family in BUILTINS:
                continue
            if p.backward and program is not None:
                fams.update(program.premise_families(p.family))
            else:
                fams.add(p.family)
        reads[id(t)] = fams
    changed = True
    while changed:
        changed = False
        for t in every:
            if t in general:
                continue
            if reads[id(t)] & opened:
                general.add(t)
                heads(t, opened)
                changed = True
    return opened, general


def _has_open_slots(templates) -> bool:
    stack = list(templates)
    while stack:
        t = stack.pop()
        if t.open_slots:
            return True
        for act in t.head:
            if act[0] == "rule":
                stack.extend(act[2])
    return False


# ------------------------------------------------------------------ drivers


def _const_leaves(pat: Node, depth: int = 2, path: tuple = ()):
    """(path, constant) for each argument of ``pat`` (and their arguments, to ``depth``) that is a constant-headed term."""
    if type(pat) is not Root or depth == 0:
        return
    for k, a in enumerate(pat.args):
        if type(a) is Root and type(a.head) is Const:
            yield path + (k,), a.head
            yield from _const_leaves(a, depth - 1, path + (k,))


def _discriminators(by_family: dict) -> dict:
    """Per family, argument paths at which the premises of its templates name constants, with the
    templates by (path, constant): a new fact wakes only those whose premise can match it.

    Each premise is keyed by one of its constant leaves, at the path that splits the family's
    premises into the most groups. Sound because the premise has that constant there, so a
    fact with another one (or none) cannot match it; a premise with no constant leaf is woken
    by every fact of the family. Returns family -> (paths, {(path, constant): templates},
    always-woken templates, all templates)."""
    out = {}
    for fam, tpls in by_family.items():
        if len(tpls) < 4:
            continue
        prems = []          # (template, leaves of one premise on fam)
        diversity: dict = {}
        for t in tpls:
            for p in t.premises:
                if p.backward or p.family is not fam:
                    continue
                leaves = dict(_const_leaves(p.pattern))
                prems.append((t, leaves))
                for path, c in leaves.items():
                    diversity.setdefault(path, set()).add(c)
        rank = sorted(diversity, key=lambda q: (-len(diversity[q]), len(q), q))
        table: dict = {}
        rest: dict = {}
        used: list = []
        for t, leaves in prems:
            path = next((q for q in rank if q in leaves), None)
            if path is None:
                rest[id(t)] = t
                continue
            if path not in used:
                used.append(path)
            table.setdefault((path, leaves[path]), {})[id(t)] = t
        if len(rest) == len({id(t) for t in tpls}):
            continue
        order = {id(t): i for i, t in enumerate(tpls)}
        full = {k: tuple(sorted(v.values(), key=lambda t: order[id(t)])) for k, v in table.items()}
        out[fam] = (tuple(used), full, tuple(rest.values()), tuple(tpls))
    return out


class Run:
    """Committed-choice forward chaining over a context, to quiescence or a step bound."""

    def __init__(self, templates: list[Template], ctx: Context, seed: Optional[int] = 0,
                 fair: bool = False, prover: Optional[Prover] = None,
                 on_step: Optional[Callable[[Step, Context], None]] = None):
        self.templates = [t for t in templates if t.forward]
        # The general (unification) path, for the rules that may meet logic variables in the
        # context: decided here, once, by a static closure over the rules (open_families);
        # None when no rule needs it (then every rule keeps the ground fast path).
        self.general: Optional[set] = None
        self.u = None
        bw = getattr(prover, "bw", None)
        program = getattr(bw, "program", None)
        has_open = None
        if program is not None:
            has_open = program.__dict__.get("_has_open_slots")
        if has_open is None:
            has_open = _has_open_slots(self.templates)
            if program is not None and templates is getattr(program, "templates", None):
                program.__dict__["_has_open_slots"] = has_open
        if has_open or ctx.open or any(r.open or _has_open_slots(r.alts) for r in ctx.rules.values()):
            _opened, self.general = open_families(self.templates, ctx, program)
            if bw is not None:
                self.u = bw.u
            else:
                from .unify import Unifier
                self.u = Unifier()
        self.ctx = ctx
        self.rng = random.Random(seed)
        self._random = self.rng.random  # bound once: the scheduler draws twice a step
        self._bits = self.rng.getrandbits
        self.fair = fair
        self.prover = prover
        self.on_step = on_step
        self.steps = 0
        self._rr = 0
        self.by_family: dict = {}
        self.always: list[Template] = []
        self.proved: list[Template] = []  # rules with a premise proved from clauses
        for t in self.templates:
            fams = {p.family for p in t.premises if not p.backward}
            # A premise proved by backward chaining is a function of the slots the context
            # premises bind, of the signature's clauses (fixed) and of the persistent facts
            # of the context (prove_premise's hypotheses): so such a rule is woken by the
            # facts its context premises match, like any other, and retried when a
            # persistent fact appears. A rule with no context premise is always retried.
            if any(p.backward and p.family not in BUILTINS for p in t.premises):
                self.proved.append(t)
            # a premise proved from the context's linear or affine facts may use facts of any
            # family its clauses need: such a rule (and any on the general path with a proved
            # premise) is retried after every step
            if not fams or any(p.backward and p.family not in BUILTINS and (
                    p.mode != PERS or (self.general and t in self.general)) for p in t.premises):
                self.always.append(t)
            for f in fams:
                self.by_family.setdefault(f, []).append(t)
        self.disc = _discriminators(self.by_family)
        from .context import Bag
        self.agenda = Bag()
        for t in self.templates:
            self.agenda.add(t)
        for r in ctx.rules.values():
            self.agenda.add(r)

    def _woken(self, x):
        """The templates a new fact ``x`` may enable: those with a premise of its family, less
        those whose premise needs another constant where ``x`` has one (see _discriminators)."""
        d = self.disc.get(x.head)
        if d is None:
            return self.by_family.get(x.head, ())
        paths, table, rest, every = d
        out = list(rest)
        for path in paths:
            sub = x
            for k in path:
                if type(sub) is not Root or len(sub.args) <= k:
                    return every
                sub = sub.args[k]
            if type(sub) is not Root or type(sub.head) is not Const:
                return every
            out.extend(table.get((path, sub.head), ()))
        return out

    def _pick(self):
        items = self.agenda.items
        if self.fair:
            self._rr += 1
            return items[self._rr % len(items)]
        return items[int(self._random() * len(items))]

    def _try(self, item) -> Optional[Step]:
        ctx = self.ctx
        start = self._rr if self.fair else self._bits(30)
        if type(item) is CtxRule:
            if item.uid not in ctx.rules:
                return None
            alts = item.alts
            order = range(len(alts))
            if len(alts) > 1 and not self.fair:
                order = self.rng.sample(range(len(alts)), len(alts))
            general = self.general
            for a in order:
                tpl = alts[a]
                if not tpl.forward:
                    continue
                b = list(item.env)
                if item.open or (general and tpl in general):
                    consumed = self._general_first(tpl, b, start)
                    if consumed is not None:
                        return fire(ctx, tpl, b, consumed, item, True)
                    continue
                consumed = self._first(tpl, b, start)
                if consumed is not None:
                    return fire(ctx, tpl, b, consumed, item)
            return None
        b = [None] * item.nslots
        general = self.general
        if general and item in general:
            consumed = self._general_first(item, b, start)
            if consumed is not None:
                return fire(ctx, item, b, consumed, None, True)
            return None
        consumed = self._first(item, b, start)
        if consumed is not None:
            return fire(ctx, item, b, consumed, None)
        return None

    def _general_first(self, tpl: Template, b: list, start: int) -> Optional[list]:
        if self.u is None:
            from .unify import Unifier
            self.u = Unifier()
        return general_match(self.ctx, tpl, b, start, self.u, self.prover)

    def _any_enabled(self) -> bool:
        """Is some rule enabled (the bound was reached: quiescent only if none is)? Matches
        found on the general path are undone."""
        general = self.general
        ctx = self.ctx
        if not general:
            return any(True for _ in enabled_steps(self.templates, ctx, self.prover, first_only=True))
        fast = [t for t in self.templates if t not in general]
        if any(True for _ in enabled_steps(fast, ctx, self.prover,
                                           first_only=True, rules=False)):
            return True
        u = self.u
        for t in self.templates:
            if t in general:
                mark = u.mark()
                found = general_match(ctx, t, [None] * t.nslots, 0, u, self.prover)
                u.undo(mark)
                if found is not None:
                    return True
        for r in list(ctx.rules.values()):
            for t in r.alts:
                if not t.forward:
                    continue
                b = list(r.env)
                if r.open or t in general:
                    mark = u.mark()
                    found = general_match(ctx, t, b, 0, u, self.prover)
                    u.undo(mark)
                else:
                    found = self._first(t, b, 0)
                if found is not None:
                    return True
        return False

    def _first(self, tpl: Template, b: list, start: int) -> Optional[list]:
        return first_match(self.ctx, tpl, b, start, self.prover)

    def external(self, consumed: list, produced: list, rule: str = "external") -> Step:
        """A step taken outside the signature (the functional layer answering a call):
        remove the linear facts ``consumed``, add the linear facts ``produced``, wake
        the rules they may enable. Returned as a :class:`Step` for traces."""
        ctx = self.ctx
        step = Step(rule, None, (), [(LIN, t) for t in consumed])
        for t in consumed:
            ctx.remove_fact(t, LIN)
        for t in produced:
            ctx.add_fact(t, LIN)
            step.produced.append((LIN, t))
            for tpl in self._woken(t):
                self.agenda.add(tpl)
            if ctx.rules:
                for uid in ctx.rules_woken_by(t):
                    r = ctx.rules.get(uid)
                    if r is not None:
                        self.agenda.add(r)
        for tpl in self.always:
            self.agenda.add(tpl)
        return step

    def run(self, max_steps: Optional[int] = None) -> bool:
        """Run; True if quiescent at the end, False if stopped by the bound.

        The cyclic garbage collector is paused meanwhile: a step makes no reference
        cycles (reference counting frees what it drops), and in a large context the
        collector's scans of the long-lived hash-consed terms cost about a fifth of
        the time (benchmark B2)."""
        was_enabled = gc.isenabled()
        gc.disable()
        try:
            return self._run(max_steps)
        finally:
            if was_enabled:
                gc.enable()

    def _run(self, max_steps: Optional[int]) -> bool:
        agenda = self.agenda
        ctx = self.ctx
        while max_steps is None or self.steps < max_steps:
            if not agenda.items:  # len(agenda), without the method call
                return True
            item = self._pick()
            step = self._try(item)
            if step is None:
                agenda.discard(item)
                continue
            self.steps += 1
            if type(item) is CtxRule and item.mode != PERS:
                agenda.discard(item)
            # a fact the step consumed and put back unchanged enables nothing new: every rule
            # that could use it was either still on the agenda or failed with it present
            back = None
            if step.consumed:
                back = {}
                for m, c in step.consumed:
                    back[m, c] = back.get((m, c), 0) + 1
            for mode, x in step.produced:
                if type(x) is CtxRule:
                    agenda.add(x)
                    continue
                if back and back.get((mode, x)):
                    back[mode, x] -= 1
                    continue
                for t in self._woken(x):
                    agenda.add(t)
                if ctx.rules:  # no live rule: nothing to wake
                    if x.evars:  # an open fact is not indexed by its arguments: wake every rule
                        for r in ctx.rules.values():
                            agenda.add(r)
                        continue
                    for uid in ctx.rules_woken_by(x):
                        r = ctx.rules.get(uid)
                        if r is not None:
                            agenda.add(r)
            for t in self.always:
                agenda.add(t)
            if self.proved and any(mode == PERS for mode, _x in step.produced):
                for t in self.proved:
                    agenda.add(t)
            if self.on_step is not None:
                self.on_step(step, ctx)
        # bound reached: quiescent only if nothing is enabled any more
        return not self._any_enabled()


@dataclass(frozen=True)
class Choice:
    """An enabled step of a state (explorer API)."""

    template: Template
    ctx_rule: Optional[int]
    bindings: tuple
    consumed: tuple

    @property
    def rule(self) -> str:
        return self.template.name


def enabled_steps(templates: list[Template], ctx: Context, prover: Optional[Prover] = None,
                  first_only: bool = False, rules: bool = True) -> Iterator[Choice]:
    """Every distinct enabled step of ``ctx`` (all rules, all matches, all fact modes).

    A template is tried only if every rigid path its premises require (see
    :func:`_rigid_paths`) occurs in some fact of the context: most of a compiled
    program's rules wait for a fact with a given constant a level or two down, and
    ruling them out this way costs a set inclusion instead of a failed match. The
    templates that remain are tried in the given order, so the steps' order is
    unchanged."""
    paths = _context_paths(ctx)
    pairs, unique = _filters(templates)
    seen_all: Optional[set] = None if unique else set()
    # a context of linear facts, each once (a compiled ROAR model's): rules with proved premises
    # that had no match on the same facts before have none now (see _zero_memo)
    zero_ok = (not first_only and not ctx.aff and not ctx.pers and not ctx.open
               and getattr(prover, "quick", None) is not None and len(ctx.lin) == sum(ctx.lin.values()))
    index = ctx.index
    for t, need in pairs:
        if not need <= paths:
            continue
        zkey = None
        if zero_ok:
            fams = t.__dict__.get("_zero_fams", False)
            if fams is False:
                fams = t._zero_fams = _zero_families(t)
            if fams is not None:
                key = [t]
                for f in fams:   # (one flat tuple, the families' facts each followed by None)
                    bag = index.get(f)
                    if bag is not None:
                        key += bag.items
                    key.append(None)
                zkey = tuple(key)
                ids = _zero_memo.get(zkey)
                if ids is None:
                    ids = _zero_older.get(zkey)
                    if ids is not None:
                        _zero_remember(zkey, ids)
                if ids is not None:
                    skip_param_ids(ids)   # the ids the proofs would have taken
                    continue
                first_id = next_param_id()
        found = all_matches(ctx, t, [None] * t.nslots, prover, first_only)
        if zkey is not None and not found:
            _zero_remember(zkey, next_param_id() - first_id)
        if seen_all is not None:   # a template listed twice: its matches are yielded once
            for bindings, consumed in found:
                key = (id(t), bindings, multiset_key(consumed))
                if key not in seen_all:
                    seen_all.add(key)
                    yield Choice(t, None, bindings, consumed)
                    if first_only:
                        return
            continue
        if len(found) == 1:
            bindings, consumed = found[0]
            yield Choice(t, None, bindings, consumed)
            if first_only:
                return
            continue
        seen: set = set()   # (matches of one template found in different premise orders)
        for bindings, consumed in found:
            key = (bindings, multiset_key(consumed))
            if key not in seen:
                seen.add(key)
                yield Choice(t, None, bindings, consumed)
    for r in (list(ctx.rules.values()) if rules else ()):
        for t in r.alts:
            if not t.forward:
                continue
            for bindings, consumed in all_matches(ctx, t, list(r.env), prover, first_only):
                yield Choice(t, r.uid, bindings, consumed)
                if first_only:
                    return


#: (template, the facts of each family its context premises read, in bag order) -> the ids its
#: proofs took, for a template that had no match on those facts. Why: a rule whose proved
#: premises fail (a compiled ROAR model's ``continued``, ``pause_forward``) joins its context
#: premises fully in state after state only to fail at the proofs, and the families it reads
#: often have the same facts as in the state expanded before. The answer (no match) depends on
#: those facts alone, counted once each (the matcher reads nothing else of a context of linear
#: facts, and a persistent premise's proof nothing of it); the ids are skipped as the proofs
#: would have taken them (each memoised proof takes as many as when it ran). Two generations of
#: at most _ZERO_MEMO_MAX entries each: the answers used lately are kept, the memory bounded.
_zero_memo: dict = {}
_zero_older: dict = {}
_ZERO_MEMO_MAX = 512


def _zero_remember(key: tuple, ids: int) -> None:
    global _zero_memo, _zero_older
    if len(_zero_memo) >= _ZERO_MEMO_MAX:
        _zero_older = _zero_memo
        _zero_memo = {}
    _zero_memo[key] = ids


def _zero_families(t: Template) -> Optional[tuple]:
    """The families of a template's context premises, in order, when a missing match of it may
    be memoised (it has proved premises, each persistent or built-in); None otherwise."""
    back = [p for p in t.premises if p.backward]
    if not back or any(p.mode != PERS and p.family not in BUILTINS for p in back):
        return None
    fams = tuple(dict.fromkeys(p.family for p in t.premises if not p.backward))
    if any(f is None for f in fams):
        return None
    return fams


#: templates list -> (the list, its length, what _filters returns): a program's list is read
#: in every state. Lists of a few templates (a caller
#: asking about one rule) are not kept.
_filter_memo: dict = {}


def _filters(templates) -> tuple:
    """(((template, rigid paths), ...) of the forward templates, whether no template is listed
    twice)."""
    got = _filter_memo.get(id(templates))
    if got is not None and got[0] is templates and got[1] == len(templates):
        return got[2]
    out = []
    for t in templates:
        if not t.forward:
            continue
        need = t.__dict__.get("_rigid")
        if need is None:
            need = t._rigid = _template_paths(t)
        out.append((t, need))
    out = (tuple(out), len({id(t) for t, _ in out}) == len(out))
    if len(templates) > 8 and isinstance(templates, list):
        if len(_filter_memo) > 64:
            _filter_memo.clear()
        _filter_memo[id(templates)] = (templates, len(templates), out)
    return out


#: how deep below a premise's (or fact's) arguments rigid heads are recorded
_PATH_DEPTH = 2

#: fact -> its rigid paths (facts are hash-consed and recur from state to state); the paths
#: themselves are interned, as most facts share them. Emptied when it reaches _PATHS_MAX facts
#: (the facts of the frontier's states are those asked for again; kept for every fact ever
#: seen, the table would grow by about 100 bytes per state visited, benchmark B8).
_fact_paths: dict = {}
_path_intern: dict = {}
_PATHS_MAX = 2048
#: a bag's paths -> itself: the live bags of one family (in the frontier's contexts) mostly have
#: the same. Emptied at _BAG_PATHS_MAX entries: kept for every bag ever made, it would grow by a
#: few hundred bytes per state visited (benchmark B8), as frozen states keep no bags
_bag_paths_intern: dict = {}
_BAG_PATHS_MAX = 512


def _rigid_paths(t: Node, prefix: tuple, depth: int, out: list) -> None:
    """Append ``prefix + (j, head)`` for each argument ``j`` of ``t`` whose head is a constant
    or literal, and so on below it, ``depth`` levels down. Matching a pattern against a
    fact compares such heads by identity, so a fact a pattern matches has every rigid path
    of the pattern."""
    j = 0
    for a in t.args:
        if type(a) is Root:
            h = a.head
            if type(h) is Const or type(h) is Lit:
                p = prefix + (j, h)
                out.append(p)
                if depth > 1 and a.args:
                    _rigid_paths(a, p, depth - 1, out)
        j += 1


def _template_paths(tpl: Template) -> frozenset:
    """The rigid paths some fact of the context must have for ``tpl`` to match: the family
    and the paths of each premise found in the context (proved premises add none)."""
    out: list = []
    for p in tpl.premises:
        pat = p.pattern
        if p.backward or type(pat) is not Root or type(pat.head) is not Const:
            continue
        out.append((pat.head,))
        _rigid_paths(pat, (pat.head,), _PATH_DEPTH, out)
    return frozenset(out)


def _context_paths(ctx: Context) -> set:
    """The rigid paths of every fact of ``ctx``, whatever its mode: the union over the family
    bags of the index (which hold each fact present once), each bag's union kept on the bag
    until it changes (most families do not change from a state to its successor)."""
    out: set = set()
    for bag in ctx.index.values():
        ps = bag.paths
        if ps is None:
            ps = _bag_paths(bag.items)
            intern = _bag_paths_intern
            if len(intern) >= _BAG_PATHS_MAX:
                intern.clear()
            ps = bag.paths = intern.setdefault(ps, ps)
        out |= ps
    return out


def _bag_paths(facts: list) -> frozenset:
    acc: set = set()
    memo = _fact_paths
    for t in facts:
        ps = memo.get(t)
        if ps is None:
            if len(memo) >= _PATHS_MAX:
                memo.clear()
                _path_intern.clear()
            got = [(t.head,)]
            _rigid_paths(t, (t.head,), _PATH_DEPTH, got)
            ps = memo[t] = tuple([_path_intern.setdefault(p, p) for p in got])
        acc.update(ps)
    return frozenset(acc)


def multiset_key(consumed) -> tuple:
    """The consumed facts as a multiset, independent of the order premises were matched in."""
    return tuple(sorted((m, id(t)) for m, t in consumed))


def successor(ctx: Context, choice: Choice) -> tuple[Context, Step]:
    """The state after taking ``choice`` (the given context is left unchanged)."""
    c = ctx.copy()
    crule = c.rules[choice.ctx_rule] if choice.ctx_rule is not None else None
    step = fire(c, choice.template, list(choice.bindings), list(choice.consumed), crule)
    return c, step


class FactsView:
    """The facts, rules and hypotheses of a successor not yet built (see :func:`plan_successor`):
    what ``state.canonical_key`` reads, without the matching indexes a context carries."""

    __slots__ = ("lin", "aff", "pers", "rules", "inert", "open", "_canon")

    def __init__(self, lin: dict, aff: dict, pers: dict, rules: dict, inert: list, open_: list):
        self.lin, self.aff, self.pers, self.rules, self.inert, self.open = lin, aff, pers, rules, inert, open_
        self._canon = None


def _plain_head(tpl: Template) -> bool:
    """Does the template's head only make fresh names and add facts (no rule, no inert
    hypothesis, no logic variable)? Decided once per template."""
    got = tpl.__dict__.get("_plain_head")
    if got is None:
        got = tpl._plain_head = not tpl.open_slots and all(act[0] in ("fresh", "fact") for act in tpl.head)
    return got


def plan_successor(ctx: Context, choice: Choice) -> Optional[tuple[FactsView, Step]]:
    """The step :func:`successor` would take and the facts of the state it gives, without
    building that state's context: ``(view, step)``, or None when the step is not a plain
    one (a context rule, a head adding rules or hypotheses, logic variables).

    Why: the explorer needs a successor's canonical key first, and most successors are states
    visited already; their indexes would be built only to be dropped. The facts' dictionaries
    change exactly as :func:`fire` changes them (so their order, which the key reads, is the
    same), and the fresh names are made in the same order; :func:`build_planned` makes the
    context when the state is new."""
    tpl = choice.template
    if choice.ctx_rule is not None or ctx.open or not _plain_head(tpl):
        return None
    lin = ctx.lin.copy()
    aff = ctx.aff.copy()
    pers = ctx.pers.copy()
    consumed = list(choice.consumed)
    for mode, t in consumed:
        take_count(lin, aff, mode, t)
    b = list(choice.bindings)
    produced = []
    for act in tpl.head:
        if act[0] == "fresh":
            b[act[1]] = Root(Param(act[2]), ())
            continue
        mode = act[1]
        t = inst(act[2], b)
        add_count(lin, aff, pers, mode, t)
        produced.append((mode, t))
    step = Step(tpl.name, tpl, tuple(b), consumed, None, produced)
    return FactsView(lin, aff, pers, ctx.rules, ctx.inert, ctx.open), step


def build_planned(ctx: Context, step: Step) -> Context:
    """The context of a step :func:`plan_successor` planned from ``ctx``: the one
    :func:`successor` gives (the same removals and additions in the same order)."""
    c = ctx.copy()
    for mode, t in step.consumed:
        c.remove_fact(t, mode)
    for mode, t in step.produced:
        c.add_fact(t, mode)
    return c


def load_positive(ctx: Context, s: Node, compile_fn, name: str = "init") -> list:
    """Add a closed positive type to the context (``Exists`` makes fresh names)."""
    added: list = []
    for mode, part in positive_parts(s, lambda hint, _ty: Root(Param(hint), ())):
        tp = type(part)
        if tp is Root:
            if part.evars:  # a fact holding logic variables (of a query): an open fact
                part = ctx.add_any(part, mode)
            else:
                ctx.add_fact(part, mode)
            added.append((mode, part))
        elif tp is Top:
            ctx.inert.append((mode, part))
        else:
            alts = compile_fn(name, part)
            nslots = alts[0].nslots if alts else 0
            r = ctx.add_rule(alts, tuple([None] * nslots), mode, part)
            if part.evars:
                r.open = True
            added.append((mode, r))
    return added
