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
    it), the producers of that fact alone; otherwise the producers of every
    premise of ``r`` (as an abstract fact under ``b``). A producer is every
    rule whose head can make a fact overlapping it (abstract step with the
    binding read off the overlap).

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

Overlap tests are conservative: a pattern argument that is not a ground term
or a bound slot (a compound term with variables, a fresh name) matches
anything. Where the analysis does not apply, the state is expanded fully: when
the context holds rules (continuations), or the program has rules with
premises proved by backward chaining or rules in their heads. The seed that
gives the fewest enabled steps wins; a set that covers every enabled step is
no reduction.

The explorer adds the cycle proviso (a reduced expansion that reaches an
already visited state is replaced by the full one) and the job runner turns
the reduction off when livelock is checked: weak fairness is judged from the
steps each state enables, which a reduced graph does not show (see
``docs/checking.md``, "Reductions").
"""

from __future__ import annotations

from typing import Optional

from ..clf.context import Context
from ..clf.rules import AFF, LIN, PERS, Template
from ..clf.terms import Meta, Node, Root

# An abstract fact: (family, args) where each arg is a ground Node or None ("any").
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
            args.append(_ANY)
    return pattern.head, tuple(args)


def _bind(pattern: Node, fact_args: tuple, fresh: frozenset = frozenset()) -> Optional[dict]:
    """The slot binding under which ``pattern`` may produce or match an abstract fact with
    these arguments, or None when they cannot overlap."""
    if len(pattern.args) != len(fact_args):
        return None
    b: dict = {}
    for a, v in zip(pattern.args, fact_args):
        if not a.metas:
            if a.maxb or v is _ANY:
                continue
            if a is not v:
                return None
        elif type(a) is Root and not a.args and type(a.head) is Meta:
            i = a.head.index
            if v is _ANY or i in fresh:
                continue
            w = b.get(i)
            if w is None:
                b[i] = v
            elif w is not v:
                return None
    return b


class Reducer:
    """Stubborn-set computation for one program (static tables built once)."""

    def __init__(self, templates: list[Template]):
        self.templates = [t for t in templates if t.forward]
        self.analyzable = True
        self.consumers: dict = {}  # family -> [(template, pattern)] of consuming premises
        self.producers: dict = {}  # family -> [(template, pattern, fresh slots)] of head facts
        for t in self.templates:
            fresh = frozenset(a[1] for a in t.head if a[0] == "fresh")
            for p in t.premises:
                if p.backward or p.family is None:
                    self.analyzable = False
                elif p.mode in (LIN, AFF):
                    self.consumers.setdefault(p.family, []).append((t, p.pattern))
            for a in t.head:
                if a[0] == "rule":
                    self.analyzable = False
                elif a[0] == "fact":
                    self.producers.setdefault(a[2].head, []).append((t, a[2], fresh))
        # statistics
        self.reduced = 0
        self.full = 0

    # ------------------------------------------------------------ the closure
    def choose(self, ctx: Context, choices: list) -> Optional[list[int]]:
        """Indices of a stubborn subset of ``choices`` (the enabled steps of ``ctx``), or None
        for full expansion."""
        if len(choices) < 2 or not self.analyzable or ctx.rules:
            return None
        best: Optional[list[int]] = None
        for seed in range(len(choices)):
            got = self._closure(ctx, choices, seed, len(choices) if best is None else len(best))
            if got is None:
                continue
            if best is None or len(got) < len(best):
                best = got
                if len(best) == 1:
                    break
        if best is None or len(best) >= len(choices):
            return None
        return sorted(best)

    def _closure(self, ctx: Context, choices: list, seed: int, limit: int) -> Optional[list[int]]:
        """The closure from one enabled step; None once it reaches ``limit`` enabled steps
        (no better than full expansion, or than the best set found so far)."""
        in_set: set[int] = set()
        seen_abs: set = set()
        work_steps = [seed]
        work_abs: list = []
        in_set.add(seed)

        def add_abs(tpl: Template, b: dict) -> None:
            key = (id(tpl), tuple(sorted((k, id(v)) for k, v in b.items())))
            if key not in seen_abs:
                seen_abs.add(key)
                work_abs.append((tpl, b))

        while work_steps or work_abs:
            if len(in_set) >= limit:
                return None
            if work_steps:
                c = choices[work_steps.pop()]
                for mode, f in c.consumed:  # (A)
                    if mode == PERS:
                        continue
                    for tpl, pat in self.consumers.get(f.head, ()):
                        b = _bind(pat, f.args)
                        if b is not None:
                            add_abs(tpl, b)
                continue
            tpl, b = work_abs.pop()
            # enabled instances of the abstract step join the set
            for j, c in enumerate(choices):
                if j in in_set or c.template is not tpl:
                    continue
                cb = c.bindings
                if all(cb[i] is v for i, v in b.items()):
                    in_set.add(j)
                    work_steps.append(j)
            # (B) enabling sets of its disabled instances
            facts = [(p.mode, _abstract(p.pattern, b)) for p in tpl.premises]
            needed = None
            for mode, (fam, args) in facts:
                if all(a is not _ANY for a in args):
                    g = Root(fam, args)
                    if not _present(ctx, g, mode):
                        needed = [(fam, args)]
                        break
            if needed is None:
                needed = [fa for _, fa in facts]
            for fam, args in needed:
                for ptpl, pat, fresh in self.producers.get(fam, ()):
                    pb = _bind(pat, args, fresh)
                    if pb is not None:
                        add_abs(ptpl, pb)
        return sorted(in_set)


def _present(ctx: Context, g: Node, mode: str) -> bool:
    """Could the ground fact ``g`` serve a premise of this mode in ``ctx`` now?"""
    if mode == LIN:
        return g in ctx.lin or g in ctx.aff or g in ctx.pers
    if mode == AFF:
        return g in ctx.aff or g in ctx.pers
    return g in ctx.pers
