"""Partial-order reduction for the general backend: stubborn sets from CLF's concurrent equality.

Two steps of a CLF computation are independent (they commute, CLF's
concurrent equality) when neither consumes a fact the other uses. Multiset
rewriting is monotone: producing a fact never disables a step and consuming
one never enables a step. So, at a state ``s``:

* an enabled step ``t`` can only be disturbed by a step that *consumes* one of
  the (linear or affine) facts ``t`` consumes;
* a disabled step can only be enabled by a step that *produces* a fact
  matching one of its premises.

:func:`Reducer.choose` computes a stubborn set ``T`` of steps at ``s`` by
closure, starting from one enabled step, over *abstract steps* ``(rule,
partial binding)`` (every ground instance of the rule agreeing with the
binding belongs to ``T``); bindings only record slots fixed to a ground
argument by a fact, everything else is "any value":

(A) for every enabled step ``t`` in ``T`` and every fact ``f`` it consumes
    (linear or affine; persistent facts are never consumed), every rule
    premise that consumes (mode linear or affine) and can match ``f`` puts the
    abstract step (that rule, binding from matching ``f``) into ``T``;
(B) for every abstract step ``(r, b)`` in ``T``, its possibly disabled
    instances need an enabling set: if some premise of ``r`` instantiated by
    ``b`` is a fully ground fact absent from ``s`` (in a mode that could serve
    it), the producers of that fact alone; else the cheaper of the producers
    of a premise no fact of ``s`` overlaps, or a split on a premise some facts
    overlap (one abstract step per such fact, with the binding it gives, plus
    the producers of the premise for the instances waiting on a new fact);
    otherwise the producers of every premise of ``r`` (as an abstract fact
    under ``b``). A producer is every rule whose head can make a fact
    overlapping it (abstract step with the binding read off the overlap,
    partial terms kept for the fresh names in them), except a rule that puts
    back the very fact it consumed.

Rules in the context: an abstract step is ``(template, binding, where)``,
``where`` naming the rule of the context it is a step of (its binding holds
that rule's slot values), or saying that it stands for rules of that template
not in the context yet: their enabling set is the steps that put them there
(a creator that would have to make fresh a name the binding fixes never
does). A step of a linear rule of the context uses the rule up: every step of
that rule joins the set.

The result is a stubborn set in Valmari's sense:

* **D1** (commutation). If ``t`` in ``T`` is enabled, no step outside ``T``
  ever consumes a fact ``t`` consumes (A), so ``t`` stays enabled along any
  sequence ``u1..un`` of steps outside ``T`` and commutes with each of them
  (they use disjoint facts: same resulting multiset, up to the renaming of
  fresh names that states are compared by): ``s -u1..un t-> s'`` implies
  ``s -t u1..un-> s'``. If ``t`` in ``T`` is disabled, every step that could
  produce a fact it is missing is in ``T`` (B), and consumption never
  enables: no sequence outside ``T`` enables it.
* **D2** (key step). Every enabled step of ``T`` stays enabled along any
  sequence outside ``T`` (by A), so each is a key step; ``T`` starts from an
  enabled step, so it has one.

D1 + D2 preserve every reachable quiescent state (deadlock or accepted
final): each quiescent state of the full graph is reachable in the reduced
graph, and the reduced graph has no other states than the full one. Hence the
deadlock verdict is the same; the counterexample is a real run but need not be
a shortest one of the full graph.

Further conditions (see ``docs/checking.md``, "Reductions"):

(C) a premise proved by backward chaining reads the clauses and the
    persistent facts of its family: the rules adding such facts join the set
    with a step that has one, and a step adding one brings in the rules
    whose proofs read it;
observers: the rules of an invariant (patterns that must never match) are
    in every set, so by (B) nothing outside the set can make them match
    (the system where such a rule stops everything has the violations as the
    states before its deadlocks, which D1 + D2 keep);
visible families: every rule touching a family a Python-computed property
    or monitor reads is in every set;
progress steps are visible: a set with an enabled one is given up (full
    expansion); with the explorer's cycle proviso this keeps every cycle
    without progress. Weak fairness is judged with the groups of the steps a
    reduced expansion left out (``StateGraph.hidden_enabled``); a "holds"
    under weak fairness is confirmed without reduction by the job runner.

Overlap tests are conservative (slots stand for anything; repeated slots are
not compared). Where the analysis does not apply (open facts or rules, a
premise proved from a goal that is not an atom), the state is expanded
fully, and so it is when the closure grows past ``max_abstract`` abstract
steps. At most ``max_seeds`` seeds are tried; the smallest set wins, and a
set that covers every enabled step is no reduction.
"""

from __future__ import annotations

from typing import Optional

from ..clf.builtins import BUILTINS
from ..clf.context import Context
from ..clf.rules import AFF, LIN, PERS, Template
from ..clf.forward import match
from ..clf.terms import Const, Lam, Meta, Node, Param, Root

# An abstract fact: (family, args) where each arg is a ground Node, a term whose remaining
# slots (Metas) stand for anything, or None ("any").
_ANY = None


def _abstract(pattern: Node, binding: dict) -> tuple:
    """A pattern as an abstract fact under a partial binding of its slots."""
    args = []
    for a in pattern.args:
        if not a.metas:
            args.append(a if not a.maxb else _ANY)
        elif type(a) is Root and not a.args and type(a.head) is Meta:
            args.append(binding.get(a.head.index, _ANY))
        else:
            args.append(_partial(a, binding))
    return pattern.head, tuple(args)


def _partial(t: Node, binding: dict) -> Node:
    """``t`` with the bound slots replaced by their values (the others stay wildcards)."""
    if not t.metas:
        return t
    if type(t) is Root:
        h = t.head
        if type(h) is Meta:
            if not t.args and h.index in binding:
                return binding[h.index]
            return t  # unbound, or applied (higher-order): a wildcard
        return Root(h, tuple(_partial(a, binding) for a in t.args))
    return t


#: a term standing for any term: a slot no rule has (bindings hold partial terms with these)
_WILD = Root(Meta(-1), ())


def _wildcards(t: Node) -> Node:
    """``t`` as a partial term one rule's binding may hold: each slot (and applied slot)
    replaced by :data:`_WILD`, so that it is not read as the other rule's, and each subterm
    naming no fresh name too. What a partial binding is for is the fresh names (which request,
    which activation a step is about); keeping the rest would let a chain of producers build
    ever longer terms (a statement list preceded by any statement, and so on)."""
    if type(t) is Root:
        h = t.head
        if type(h) is Param:
            return t
        if type(h) is Meta or not t.args:
            return _WILD
        args = tuple(_wildcards(a) for a in t.args)
        if all(a is _WILD for a in args):
            return _WILD
        return Root(h, args)
    return _WILD


def _agrees(b: dict, values) -> bool:
    """Do the slot values ``values`` (a step's bindings) fit the abstract binding ``b``?"""
    for i, v in b.items():
        w = values[i]
        if w is not v and (not v.metas or w is None or not _overlap(v, w)):
            return False
    return True


def _wild(t: Node) -> bool:
    return type(t) is Root and type(t.head) is Meta


def _overlap(x: Node, y: Node, fresh: frozenset = frozenset()) -> bool:
    """Could the two terms have a common instance (slots on either side standing for
    anything; repeated slots are not checked against each other: conservative)? A slot of
    ``x`` in ``fresh`` holds a name the step makes: it is no term given now (only a wildcard)."""
    if fresh and type(x) is Root and type(x.head) is Meta and x.head.index in fresh and not x.args:
        return _wild(y)
    if x is y or _wild(x) or _wild(y):
        return True
    tx, ty = type(x), type(y)
    if tx is Root and ty is Root:
        if x.head is not y.head or len(x.args) != len(y.args):
            return False  # heads are interned constants, names or bound variables
        return all(_overlap(a, b, fresh) for a, b in zip(x.args, y.args))
    if tx is Lam and ty is Lam:
        return _overlap(x.body, y.body, fresh)
    return bool(x.metas or y.metas)  # other shapes: only identical ground terms are equal


def _bind(pattern: Node, fact_args: tuple, fresh: frozenset = frozenset()) -> Optional[dict]:
    """The slot binding under which ``pattern`` may produce or match an abstract fact with
    these arguments, or None when they cannot overlap. A ``fresh`` slot holds a name made
    by the step itself, which equals no term given now."""
    if len(pattern.args) != len(fact_args):
        return None
    b: dict = {}
    for a, v in zip(pattern.args, fact_args):
        if v is _ANY:
            continue
        if not a.metas:
            if a.maxb:
                continue
            if v.metas:
                if not _overlap(a, v):
                    return None
            elif a is not v:
                return None
        elif type(a) is Root and not a.args and type(a.head) is Meta:
            i = a.head.index
            if i in fresh:
                if not v.metas:
                    return None
                continue
            if v.metas:
                # a partial term: the slot holds some instance of it (its own slots, the other
                # rule's, stand for anything here)
                v = _wildcards(v)
                if v is _WILD:
                    continue
                w = b.get(i)
                if w is None:
                    b[i] = v
                elif not _overlap(w, v):
                    return None
                continue
            w = b.get(i)
            if w is None or w.metas:
                if w is not None and not _overlap(w, v):
                    return None
                b[i] = v
            elif w is not v:
                return None
        elif not _overlap(a, v, fresh):
            return None
    return b


def _match_binding(tpl: Template, pattern: Node, fact: Node, env: tuple = ()) -> Optional[dict]:
    """The slots a consuming premise binds when it matches ``fact``, or None if it cannot; with
    ``env`` (a rule of the context's slot values), those slots are set first and the binding
    returned holds them too."""
    b: list = [None] * max(tpl.nslots, 1)
    b[:len(env)] = env
    trail: list = []
    if not match(pattern, fact, b, trail):
        return None
    if env:
        return {i: v for i, v in enumerate(b) if v is not None}
    return {i: b[i] for i in trail}


def _nested(tpl: Template):
    """The templates of the rules ``tpl``'s head puts in the context, at any depth."""
    for a in tpl.head:
        if a[0] == "rule":
            for alt in a[2]:
                yield alt
                yield from _nested(alt)


class Reducer:
    """Stubborn-set computation for one program (static tables built once).

    ``observers`` are the rules a safety property reads (an invariant's forbidden
    patterns as rules that must never be enabled); ``visible_families`` are the
    families a property computed in Python reads or is updated from (a monitor);
    ``progress`` tells the steps that are progress events (livelock's visible
    steps). See the module docstring for what each adds to a set."""

    def __init__(self, templates: list[Template], observers: tuple = (), visible_families: frozenset = frozenset(),
                 progress=None, premise_families=None):
        """``premise_families(family)``: the families a proof of a goal of that family may read
        (the program's clauses, transitively; ``Program.premise_families``). Without it, a rule
        with a premise proved from clauses makes the program unanalyzable."""
        self.templates = [t for t in templates if t.forward]
        self.analyzable = True
        self.premise_families = premise_families
        self.consumers: dict = {}  # family -> [(template, pattern)] of consuming premises
        self.producers: dict = {}  # family -> [(template, pattern, fresh slots)] of head facts
        # family -> the same for head facts that put back a fact the rule consumed (a read): no
        # producer of a linear fact, unless such a premise may be served by a persistent or an
        # affine fact (then the head makes a new linear copy): see _producer_steps
        self.readers: dict = {}
        self.extra_modes: set = set()   # families some rule adds as persistent or affine facts
        self.proved: dict = {}  # template -> families its proofs from clauses may read
        self.provers_of: dict = {}  # family -> templates with a premise whose proofs may read that family
        self.pers_heads: dict = {}  # template -> families it adds as persistent facts
        self.progress = progress
        # template of a rule put in the context -> [(the template whose head puts it there, the
        # slots that head makes fresh)]
        self.creators: dict = {}
        self.nested: set = set()  # id() of the templates of rules put in the context
        self.known: set = set()   # id() of every template learnt (program rules, nested, start rules)
        for top in self.templates:
            self._learn(top, nested=False)
        # abstract steps every set holds: the observers, and every rule touching a visible family
        self.always: list = [(o, {}) for o in observers]
        for o in observers:
            if any(p.backward and p.family not in BUILTINS for p in o.premises):
                self.analyzable = False
        self.visible_families = visible_families
        if visible_families:
            for t in self.templates + [t for top in self.templates for t in _nested(top)]:
                fams = {p.family for p in t.premises} | {a[2].head for a in t.head if a[0] == "fact"}
                if fams & visible_families:
                    self.always.append((t, {}))
        # a closure that grows past this many abstract steps is abandoned (full expansion, which
        # is always sound): the analysis must cost less than the states it saves
        self.max_abstract = 300
        self.producer_memo: dict = {}   # see _producer_steps (the answers depend on the arguments alone)
        self.split = True   # refine an abstract step by the facts that may serve a premise ((B))
        self.max_seeds = 4
        # closures from a template that keep growing past max_abstract are not tried again, and
        # a reducer that has reduced fewer than one state in 20 after `give_up_after` tries stops
        # analysing (full
        # expansion is always sound; the analysis must not cost more than it saves)
        self.costly: dict[int, int] = {}   # id(template) -> closures from it abandoned as too costly
        self.closed: set[int] = set()      # id(template) of seeds whose closure completed once
        self.max_costly = 8
        self.give_up_after = 400
        self.tries = 0
        self.gave_up = False
        self.too_costly = False
        # statistics
        self.reduced = 0
        self.full = 0

    # ------------------------------------------------------------ the closure
    def choose(self, ctx: Context, choices: list) -> Optional[list[int]]:
        """Indices of a stubborn subset of ``choices`` (the enabled steps of ``ctx``), or None
        for full expansion."""
        if len(choices) < 2 or not self.analyzable or ctx.open or self.gave_up \
                or any(r.open for r in ctx.rules.values()):
            return None
        self.tries += 1
        if self.tries > self.give_up_after and self.reduced * 20 < self.tries:
            self.gave_up = True
            return None
        best: Optional[list[int]] = None
        tried = 0
        for seed in range(len(choices)):
            if tried >= self.max_seeds:
                break
            if self.progress is not None and self.progress(choices[seed]):
                continue  # a set with an enabled progress step must be full: no seed
            t = id(choices[seed].template)
            if t not in self.closed and self.costly.get(t, 0) >= self.max_costly:
                continue  # its closures always grew too large
            tried += 1
            self.too_costly = False
            got = self._closure(ctx, choices, seed, len(choices) if best is None else len(best))
            if self.too_costly:
                self.costly[t] = self.costly.get(t, 0) + 1
            if got is None:
                continue
            self.closed.add(t)
            if best is None or len(got) < len(best):
                best = got
                if len(best) == 1:
                    break
        if best is None or len(best) >= len(choices):
            self.full += 1
            return None
        self.reduced += 1
        return sorted(best)

    def _learn(self, top: Template, nested: bool) -> None:
        """The static tables for a template and the templates of the rules its head puts in the
        context (``nested``: ``top`` is itself one, e.g. a rule of the start state)."""
        if id(top) in self.known:
            return
        for t in [top, *_nested(top)]:
            self.known.add(id(t))
            if nested or t is not top:
                self.nested.add(id(t))
            for a in t.head:
                if a[0] == "rule":
                    fresh_here = frozenset(x[1] for x in t.head if x[0] == "fresh")
                    for alt in a[2]:
                        self.nested.add(id(alt))
                        self.creators.setdefault(alt, []).append((t, fresh_here))
            fresh = frozenset(a[1] for a in t.head if a[0] == "fresh")
            for p in t.premises:
                if p.backward:
                    if p.family in BUILTINS:
                        continue  # a function of the bindings alone
                    pat = p.pattern
                    if (t is not top or nested or type(pat) is not Root or not isinstance(pat.head, Const)
                            or p.mode != PERS or self.premise_families is None):
                        # a proof that may consume facts (a linear or affine goal: its clauses may
                        # use up linear facts), or whose reads are not known: not analyzed
                        self.analyzable = False
                        continue
                    for fam in self.premise_families(pat.head):
                        self.proved.setdefault(t, set()).add(fam)
                        self.provers_of.setdefault(fam, []).append(t)
                elif p.family is None:
                    self.analyzable = False
                elif p.mode in (LIN, AFF):
                    self.consumers.setdefault(p.family, []).append((t, p.pattern))
            used: list = [(p.mode, p.pattern) for p in t.premises if not p.backward]
            for a in t.head:
                if a[0] == "fact":
                    if a[1] in (PERS, AFF):
                        self.extra_modes.add(a[2].head)
                    if (a[1], a[2]) in used:
                        # it consumes this very fact and puts it back (a read), as many times as
                        # it consumes it: it makes no new one (unless it read a persistent or an
                        # affine one, see readers)
                        used.remove((a[1], a[2]))
                        self.readers.setdefault(a[2].head, []).append((t, a[2], fresh))
                        continue
                    self.producers.setdefault(a[2].head, []).append((t, a[2], fresh))
                    if a[1] == PERS:
                        self.pers_heads.setdefault(t, set()).add(a[2].head)

    def _producer_steps(self, fam, args: tuple, memo: dict, reads: bool = False) -> list:
        """The abstract steps producing a fact of ``fam`` overlapping ``args``: [(template,
        binding, key)] (memoised in ``memo``: the terms are hash-consed, and the same arguments
        recur from state to state). ``reads``: with the rules that put back a fact of ``fam``
        they consumed (a fact of ``fam`` may be persistent or affine, and such a rule reading it
        adds a linear one)."""
        key = (fam, args, reads)
        got = memo.get(key)
        if got is None:
            got = []
            for table in ((self.producers, self.readers) if reads else (self.producers,)):
                for ptpl, pat, fresh in table.get(fam, ()):
                    pb = _bind(pat, args, fresh)
                    if pb is not None:
                        got.append((ptpl, pb, (id(ptpl), None, tuple(sorted((k, id(v)) for k, v in pb.items())))))
            memo[key] = got
        return got

    def _new_producers(self, fam, args: tuple, seen_abs: set, memo: dict, reads: bool = False) -> int:
        """How many abstract steps producing a fact of ``fam`` overlapping ``args`` are not in
        the set yet (the cost of taking that fact as the one a disabled step waits for)."""
        n = 0
        for _ptpl, pb, key in self._producer_steps(fam, args, memo, reads):
            if key not in seen_abs:
                n += 1 if pb else UNBOUND_COST
        return n

    def _closure(self, ctx: Context, choices: list, seed: int, limit: int) -> Optional[list[int]]:
        """The closure from one enabled step; None once it reaches ``limit`` enabled steps
        (no better than full expansion, or than the best set found so far), or when it takes
        in a progress step (visible: the set would have to be full).

        An abstract step is ``(template, binding, where)``: ``where`` is None for a rule of the
        program, the uid of a rule of the context for that rule (its binding holds the rule's
        slot values), or ``_FUTURE`` for the rules with that template not in the context yet
        (rules in the context, see the module docstring)."""
        in_set: set[int] = set()
        seen_abs: set = set()
        work_steps = [seed]
        work_abs: list = []
        in_set.add(seed)
        progress = self.progress
        for r in ctx.rules.values():   # rules of the start state: learnt as rules of the context
            for t in r.alts:
                if id(t) not in self.known:
                    self._learn(t, nested=True)
                    self.producer_memo.clear()
                    for u in [t, *_nested(t)]:
                        fams = {p.family for p in u.premises} | {a[2].head for a in u.head if a[0] == "fact"}
                        if fams & self.visible_families:
                            self.always.append((u, {}))
        if not self.analyzable:
            return None
        memo = self.producer_memo   # (family, abstract arguments, reads) -> the abstract steps producing such a fact
        if len(memo) > 100_000:
            memo.clear()
        extra: dict = {}

        def reads_of(fam) -> bool:
            """May a rule reading a fact of ``fam`` (consuming and putting it back) add a new linear
            one? When such a fact may be persistent or affine (a rule adds one, or the state has one)."""
            got = extra.get(fam)
            if got is None:
                got = fam in self.extra_modes
                if not got:
                    bag = ctx.index.get(fam)
                    got = bag is not None and any(f in ctx.pers or f in ctx.aff for f in bag.items)
                extra[fam] = got
            return got
        live: dict = {}   # id(template) -> the rules of the context with it as an alternative
        for r in ctx.rules.values():
            for t in r.alts:
                live.setdefault(id(t), []).append(r)

        def push(tpl: Template, b: dict, where) -> None:
            key = (id(tpl), where, tuple(sorted((k, id(v)) for k, v in b.items())))
            if key not in seen_abs:
                seen_abs.add(key)
                work_abs.append((tpl, b, where))

        def add_abs(tpl: Template, b: dict) -> None:
            """Every step of ``tpl`` agreeing with ``b``: of the program's rule, or of the rules
            of the context with this template (each with its slot values) and of those that
            may be put there later."""
            if id(tpl) not in self.nested:
                push(tpl, b, None)
                return
            for r in live.get(id(tpl), ()):
                env = _with_env(r.env, b)
                if env is not None:
                    push(tpl, env, r.uid)
            push(tpl, b, _FUTURE)

        def add_consumer(tpl: Template, pat: Node, f: Node) -> None:
            """The steps of ``tpl`` whose premise ``pat`` may consume the fact ``f``."""
            if id(tpl) not in self.nested:
                b = _match_binding(tpl, pat, f)
                if b is not None:
                    push(tpl, b, None)
                return
            for r in live.get(id(tpl), ()):
                b = _match_binding(tpl, pat, f, r.env)
                if b is not None:
                    push(tpl, b, r.uid)
            b = _match_binding(tpl, pat, f)
            if b is not None:
                push(tpl, b, _FUTURE)

        for tpl, b in self.always:
            add_abs(tpl, b)
        while work_steps or work_abs:
            if len(in_set) >= limit:
                return None  # no better than what we have
            if len(seen_abs) > self.max_abstract:
                self.too_costly = True
                return None  # too costly to close: expand fully
            if work_steps:
                c = choices[work_steps.pop()]
                if progress is not None and progress(c):
                    return None
                tpl = c.template
                for mode, f in c.consumed:  # (A)
                    if mode == PERS:
                        continue
                    for ctpl, pat in self.consumers.get(f.head, ()):
                        add_consumer(ctpl, pat, f)
                if c.ctx_rule is not None:
                    # (A) for the rule itself: a step of a linear rule of the context uses it up,
                    # so every step of that rule is in the set
                    r = ctx.rules[c.ctx_rule]
                    if r.mode != PERS:
                        for alt in r.alts:
                            push(alt, _with_env(r.env, {}), r.uid)
                # (C) proofs: a persistent fact of a family a proof reads may change the proof
                # this step committed to, and a persistent fact this step adds may change the
                # proofs of others
                for fam in self.proved.get(tpl, ()):
                    for ptpl, _pat, _fresh in self.producers.get(fam, ()):
                        if fam in self.pers_heads.get(ptpl, ()):
                            add_abs(ptpl, {})
                for fam in self.pers_heads.get(tpl, ()):
                    for qtpl in self.provers_of.get(fam, ()):
                        add_abs(qtpl, {})
                continue
            tpl, b, where = work_abs.pop()
            if where is _FUTURE:
                # no such rule in the context: before any of its steps, a step putting it there
                # (that alone enables none, but every enabling sequence starts with one). A
                # creator that would have to make a name of the binding fresh never makes it.
                for ptpl, fresh in self.creators.get(tpl, ()):
                    pb = {i: v for i, v in b.items() if i < tpl.nouter}
                    if any(i in fresh and not v.metas for i, v in pb.items()):
                        continue
                    add_abs(ptpl, pb)
                continue
            # enabled instances of the abstract step join the set
            for j, c in enumerate(choices):
                if j in in_set or c.template is not tpl or c.ctx_rule != where:
                    continue
                if _agrees(b, c.bindings):
                    in_set.add(j)
                    work_steps.append(j)
            # (B) enabling sets of its disabled instances
            premises = [p for p in tpl.premises if not p.backward]
            facts = [(p.mode, _abstract(p.pattern, b)) for p in premises]
            needed = None
            for mode, (fam, args) in facts:
                if all(a is not _ANY and not a.metas for a in args):
                    g = Root(fam, args)
                    if not _present(ctx, g, mode):
                        needed = [(fam, args)]
                        break
            if needed is None:
                # Otherwise the cheapest of: a premise no fact of the state can serve, whatever
                # the binding's open slots are (every instance is disabled by it: only a producer
                # of such a fact enables one); or splitting on a premise that facts of the state
                # may serve (the instances taking such a fact are abstract steps with the binding
                # it gives, each looked at again; the others need a fact for it that is not there,
                # so a producer of one). Cost: the abstract steps added, one that binds nothing
                # counted as UNBOUND_COST (it brings in every step of its rule).
                cost = None
                split_on = None
                for p, (mode, (fam, args)) in zip(premises, facts):
                    got = _serving(ctx, fam, args)
                    if not got:
                        n = self._new_producers(fam, args, seen_abs, memo, reads_of(fam))
                        if cost is None or n < cost:
                            needed, cost, split_on = [(fam, args)], n, None
                    elif self.split and not all(a is not _ANY and not a.metas for a in args):
                        n = len(got) + self._new_producers(fam, args, seen_abs, memo, reads_of(fam))
                        if cost is None or n < cost:
                            needed, cost, split_on = [(fam, args)], n, (p, got)
                if split_on is not None:
                    p, got = split_on
                    for f in got:
                        fb = _extend(tpl, p.pattern, f, b)
                        if fb is not None:
                            push(tpl, fb, where)
            if needed is None:
                needed = [fa for _, fa in facts]
                # a premise proved from clauses and persistent facts of its family may become
                # provable when such a fact appears
                for fam in self.proved.get(tpl, ()):
                    needed.append((fam, None))
            for fam, args in needed:
                if args is None:
                    for ptpl, _pat, _fresh in self.producers.get(fam, ()):
                        if fam in self.pers_heads.get(ptpl, ()):
                            add_abs(ptpl, {})
                    continue
                for ptpl, pb, _key in self._producer_steps(fam, args, memo, reads_of(fam)):
                    add_abs(ptpl, pb)
        return sorted(in_set)


#: what an abstract step that binds no slot counts for when (B) chooses what a disabled step
#: waits for (it brings in every step of its rule, and their producers in turn)
UNBOUND_COST = 1000

#: the ``where`` of an abstract step of the rules of a template not in the context yet
_FUTURE = "future"


def _with_env(env: tuple, b: dict) -> Optional[dict]:
    """A binding ``b`` joined with the slot values of a rule in the context, or None when they
    disagree."""
    out = {i: v for i, v in enumerate(env) if v is not None}
    for i, v in b.items():
        w = out.get(i)
        if w is None:
            out[i] = v
        elif w is not v and not (v.metas and _overlap(v, w)) and (v.metas or w != v):
            return None
    return out


def _serving(ctx: Context, fam, args: tuple) -> list:
    """The facts of ``fam`` in ``ctx`` (in any mode) that may be instances of the abstract fact
    ``args``."""
    bag = ctx.index.get(fam)
    if bag is None:
        return []
    return [f for f in bag.items if all(a is _ANY or _overlap(a, x) for a, x in zip(args, f.args))]


def _extend(tpl: Template, pattern: Node, fact: Node, b: dict) -> Optional[dict]:
    """The binding ``b`` extended by matching ``pattern`` with ``fact``, or None if they do not
    match."""
    bl: list = [None] * max(tpl.nslots, 1)
    for i, v in b.items():
        if not v.metas:
            bl[i] = v
    if not match(pattern, fact, bl, []):
        return None
    out = {i: v for i, v in enumerate(bl) if v is not None}
    for i, v in b.items():
        if v.metas:
            w = out.get(i)
            if w is None:
                out[i] = v
            elif not _overlap(v, w):
                return None
    return out


def _present(ctx: Context, g: Node, mode: str) -> bool:
    """Could the ground fact ``g`` serve a premise of this mode in ``ctx`` now?"""
    if mode == LIN:
        return g in ctx.lin or g in ctx.aff or g in ctx.pers
    if mode == AFF:
        return g in ctx.aff or g in ctx.pers
    return g in ctx.pers
