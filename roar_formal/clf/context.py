"""The forward-chaining context: linear, affine and persistent facts and rules.

Facts are hash-consed ground atoms, counted as a multiset per mode. Every fact
is indexed by its family and by (family, position, argument) for each
argument, so a premise whose argument is already known is matched by one
dictionary lookup rather than a scan: that is what keeps a step's cost flat as
the context grows. Rules in the context (continuations) are closures, indexed
by the facts that could wake them.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Iterator, Optional

from .builtins import BUILTINS
from .rules import AFF, LIN, PERS, Template
from .terms import Meta, Node, Root, zonk

_rule_ids = itertools.count(1)


class Bag:
    """An insertion-ordered set with O(1) add, remove and random access.

    Most argument bags of a large context hold one or two facts, so a bag keeps
    its position dictionary only once it grows past ``SMALL`` items; below that,
    membership and removal scan the short list (identity comparisons). That
    keeps the index small enough to stay in cache as the context grows
    (benchmark B2)."""

    __slots__ = ("items", "pos", "paths")
    SMALL = 8

    def __init__(self) -> None:
        self.items: list = []
        self.pos: Optional[dict] = None
        self.paths = None   # forward._context_paths' union of its facts' rigid paths (None: not known)

    def add(self, x) -> None:
        self.paths = None
        pos = self.pos
        items = self.items
        if pos is None:
            for y in items:
                if y is x:
                    return
            items.append(x)
            if len(items) > Bag.SMALL:
                self.pos = {y: i for i, y in enumerate(items)}
            return
        if x not in pos:
            pos[x] = len(items)
            items.append(x)

    def discard(self, x) -> None:
        self.paths = None
        pos = self.pos
        items = self.items
        if pos is None:
            for i, y in enumerate(items):
                if y is x:
                    last = items.pop()
                    if i < len(items):
                        items[i] = last
                    return
            return
        i = pos.pop(x, None)
        if i is None:
            return
        last = items.pop()
        if i < len(items):
            items[i] = last
            pos[last] = i

    def __len__(self) -> int:
        return len(self.items)

    def __contains__(self, x) -> bool:
        pos = self.pos
        if pos is None:
            return any(y is x for y in self.items)
        return x in pos

    def __iter__(self) -> Iterator:
        return iter(self.items)

    def rotated(self, start: int) -> Iterator:
        """Iterate from position ``start`` cyclically (random scheduling without a scan).

        Lazy: the first element costs O(1) however large the bag (the committed-choice
        driver usually takes the first candidate). The positions are fixed when the
        iteration starts, as with a snapshot; the bag must not change while the
        iterator is in use (the matcher is never resumed after its caller fires).
        """
        items = self.items
        n = len(items)
        if n == 0:
            return iter(())
        start %= n
        return _rotation(items, start, n)


def _rotation(items: list, start: int, n: int) -> Iterator:
    for i in range(start, n):
        yield items[i]
    for i in range(start):
        yield items[i]


@dataclass(eq=False)
class CtxRule:
    """A live rule in the context: alternatives of one hypothesis plus its slot values."""

    uid: int
    alts: list[Template]
    env: tuple  # slot values of the parent firing (size = the templates' nslots)
    mode: str
    source: Node  # the rule's type (instantiated), for printing and backward use
    keys: tuple = ()
    open: bool = False  # its slot values or type hold logic variables: matched by the general path

    def __hash__(self) -> int:
        return self.uid


class Context:
    """A multiset of facts and rules with indexes for matching.

    Facts are indexed by family, and by family, argument position and argument
    in nested dictionaries: the innermost is keyed by the argument term itself
    (hash-consed, so hashed and compared by identity), which keeps a lookup in a
    large context to a couple of memory accesses (benchmark B2)."""

    def __init__(self) -> None:
        self.lin: dict[Node, int] = {}
        self.aff: dict[Node, int] = {}
        self.pers: dict[Node, None] = {}
        self.index: dict = {}  # family -> Bag of facts
        self.by_arg: dict = {}  # family -> [per argument position: {argument: Bag of facts}]
        self.rules: dict[int, CtxRule] = {}
        self.rule_index: dict = {}  # family | (family, i, arg) | None -> Bag of rule uids
        self.inert: list[tuple[str, Node]] = []  # hypotheses only backward chaining can use
        # facts holding logic variables, [(mode, fact)] (a list: a multiset by repetition, compared
        # by identity). They are not hash-consed nor indexed: only the rules that may read them
        # (forward.Run's general path, decided per rule) look here, matching by unification.
        self.open: list[tuple[str, Node]] = []
        self.implicit: Optional[dict] = None  # the program's implicit-argument counts, for printing
        self._canon = None  # state.canonical_key's cached result; every mutator clears it
        # For copy(): families whose bags may not be in the order re-adding the facts would
        # give (None: not tracked, as for any context not made by copy); families whose index
        # entries another context may share (cloned before they change); families whose
        # argument dictionaries are this context's own but whose bags may be shared, and the
        # ids of the bags that are this context's own (a bag is cloned before it changes).
        self._dirty: Optional[set] = None
        self._shared: set = set()
        self._cow: set = set()
        self._owned: set = set()
        self._rebuilt: Optional[tuple] = None  # copy()'s rebuild of the dirty families, for the next copy

    # -------------------------------------------------------------- facts
    def count(self, t: Node, mode: str) -> int:
        if mode == LIN:
            return self.lin.get(t, 0)
        if mode == AFF:
            return self.aff.get(t, 0)
        return 1 if t in self.pers else 0

    def present(self, t: Node) -> bool:
        return t in self.lin or t in self.aff or t in self.pers

    def add_fact(self, t: Root, mode: str) -> bool:
        """Add a fact; returns True when the atom is new to the context (index updated)."""
        self._canon = None
        lin, aff, pers = self.lin, self.aff, self.pers
        new = not (t in lin or t in aff or t in pers)  # self.present(t), inlined
        if mode == LIN:
            n = lin.get(t, 0)
            lin[t] = n + 1
        elif mode == AFF:
            n = aff.get(t, 0)
            aff[t] = n + 1
        else:
            if t in pers:
                return False
            pers[t] = None
            n = 0
        if not n and self._dirty is not None:
            self._dirty.add(t.head)  # a new key of a mode: the order facts() gives has changed
            self._rebuilt = None
        if new:
            idx = self.index
            fam = t.head
            if fam in self._shared:
                self._unshare(fam)
            b = idx.get(fam)
            if b is None:
                b = idx[fam] = Bag()
            b.add(t)
            args = t.args
            if args:
                per = self.by_arg.get(fam)
                if per is None or len(per) < len(args):
                    per = self.by_arg[fam] = (per or []) + [{} for _ in range(len(args) - len(per or ()))]
                if fam in self._cow:
                    self._add_args_cow(t, per, args)
                    return True
                for d, a in zip(per, args):
                    b = d.get(a)
                    if b is None:
                        b = d[a] = Bag()
                        b.items.append(t)
                    else:
                        b.add(t)
        return True

    def _add_args_cow(self, t: Root, per: list, args: tuple) -> None:
        owned = self._owned
        for d, a in zip(per, args):
            b = d.get(a)
            if b is None:
                b = d[a] = Bag()
                b.items.append(t)
                owned.add(id(b))
            else:
                if id(b) not in owned:
                    b = d[a] = _clone(b)
                    owned.add(id(b))
                b.add(t)

    def add_any(self, t: Root, mode: str) -> Root:
        """Add a fact that may hold logic variables: once instantiated ones are replaced by their
        values, a ground fact joins the index (``add_fact``), any other the open facts. Returns
        the fact as stored."""
        if t.evars:
            t = zonk(t)
            if t.evars:
                self._canon = None
                if mode == PERS and any(m == PERS and u is t for m, u in self.open):
                    return t
                self.open.append((mode, t))
                return t
        self.add_fact(t, mode)
        return t

    def remove_any(self, t: Root, mode: str) -> None:
        """Remove a fact that ``add_any`` stored (an open one by identity)."""
        if t.evars:
            if mode == PERS:
                return
            self._canon = None
            for i, (m, u) in enumerate(self.open):
                if u is t and m == mode:
                    del self.open[i]
                    return
            raise KeyError("open fact not in the context")
        self.remove_fact(t, mode)

    def open_of(self, fam) -> list:
        """The open facts of family ``fam``, [(mode, fact)] (their head followed)."""
        return [(m, t) for m, t in self.open if t.head is fam]

    def remove_fact(self, t: Root, mode: str) -> None:
        self._canon = None
        lin, aff = self.lin, self.aff
        if mode == LIN:
            n = lin[t] - 1
            if n:
                lin[t] = n
                return  # still present: the index is unchanged
            del lin[t]
        elif mode == AFF:
            n = aff[t] - 1
            if n:
                aff[t] = n
                return
            del aff[t]
        else:
            return  # persistent facts are never consumed
        if self._dirty is not None:
            self._dirty.add(t.head)
            self._rebuilt = None
        if not (t in lin or t in aff or t in self.pers):  # self.present(t), inlined
            fam = t.head
            if fam in self._shared:
                self._unshare(fam)
            self.index[fam].discard(t)
            args = t.args
            if args:
                owned = self._owned if fam in self._cow else None
                for d, a in zip(self.by_arg[fam], args):
                    b = d[a]
                    if len(b.items) == 1:
                        # t was the only fact with this argument: drop the bag (a missing
                        # key reads as an empty bag; arguments are often one-off terms,
                        # and the index would otherwise keep a bag for every argument)
                        del d[a]
                    else:
                        if owned is not None and id(b) not in owned:
                            b = d[a] = _clone(b)
                            owned.add(id(b))
                        b.discard(t)

    def _unshare(self, fam) -> None:
        """Give this context its own index entries for ``fam`` before they change: the
        family's bag and argument dictionaries now, each argument bag when it changes."""
        b = self.index.get(fam)
        if b is not None:
            self.index[fam] = _clone(b)
        per = self.by_arg.get(fam)
        if per is not None:
            self.by_arg[fam] = [d.copy() for d in per]
            self._cow.add(fam)
        self._shared.discard(fam)

    def candidates(self, fam, position: int, arg: Node) -> Optional[Bag]:
        """The facts of family ``fam`` with ``arg`` at ``position`` (None: there are none)."""
        per = self.by_arg.get(fam)
        if per is None or position >= len(per):
            return None
        return per[position].get(arg)

    # -------------------------------------------------------------- rules
    def add_rule(self, alts: list[Template], env: tuple, mode: str, source: Node,
                 uid: Optional[int] = None) -> CtxRule:
        self._canon = None
        r = CtxRule(uid or next(_rule_ids), alts, env, mode, source)
        keys = []
        for t in alts:
            for p in t.premises:
                if p.family in BUILTINS:
                    continue  # decided by the bindings alone: never the reason to wake a rule
                if p.backward or p.family is None:
                    keys.append(None)
                    continue
                keys.append(_wake_key(p.pattern, env))
        r.keys = tuple(dict.fromkeys(keys))
        for k in r.keys:
            b = self.rule_index.get(k)
            if b is None:
                b = self.rule_index[k] = Bag()
            b.add(r.uid)
        self.rules[r.uid] = r
        return r

    def remove_rule(self, r: CtxRule) -> None:
        self._canon = None
        del self.rules[r.uid]
        for k in r.keys:
            self.rule_index[k].discard(r.uid)

    def rules_woken_by(self, t: Root) -> Iterator[int]:
        ri = self.rule_index
        fam = t.head
        b = ri.get(fam)
        if b:
            yield from b.items
        for i, a in enumerate(t.args):
            b = ri.get((fam, i, a))
            if b:
                yield from b.items
        b = ri.get(None)
        if b:
            yield from b.items

    def rules_linear_left(self) -> bool:
        """Is a linear rule still waiting (a monad cannot end with one)?"""
        return any(r.mode == LIN for r in self.rules.values())

    def inert_linear_left(self) -> bool:
        return any(m == LIN for m, _ in self.inert)

    # -------------------------------------------------------------- views
    def facts(self) -> Iterator[tuple[str, Node, int]]:
        for t, n in self.lin.items():
            yield LIN, t, n
        for t, n in self.aff.items():
            yield AFF, t, n
        for t in self.pers:
            yield PERS, t, 1

    def size(self) -> int:
        return (sum(self.lin.values()) + sum(self.aff.values()) + len(self.pers) + len(self.rules) + len(self.inert)
                + len(self.open))

    def _facts_in_order(self) -> list:
        """Each fact once, in the order facts() first gives it."""
        lin, aff, pers = self.lin, self.aff, self.pers
        order = list(lin)
        if aff:
            order += [t for t in aff if t not in lin]
        if pers:
            order += [t for t in pers if t not in lin and t not in aff]
        return order

    def in_order(self) -> "Context":
        """This context with every bag in the order re-adding its facts gives (the order a copy,
        or a frozen context thawed, has): itself when it is so already, else a copy. Why: a removal
        moves a bag's last item into the gap, so a context changed in place enumerates its
        matches in another order than the same context frozen and thawed; the explorer keeps
        every state in this order, so that freezing one never changes what it enumerates."""
        return self if self._dirty is not None and not self._dirty else self.copy()

    def copy(self) -> "Context":
        """An independent copy whose bags are in the order re-adding the facts one by one
        (linear, then affine, then persistent) would give.

        That order, not this context's (a removal moves a bag's last item into the gap),
        is what the explorer's order of enabled steps, hence its state numbering and
        counterexamples, follows. The index entries of a family whose facts have not
        changed since this context was itself made by ``copy`` are already in that order:
        they are shared, and cloned by whichever context changes them first; only the
        other families are rebuilt, once for all the copies made before the next change."""
        c = Context.__new__(Context)
        c.lin = self.lin.copy()
        c.aff = self.aff.copy()
        c.pers = self.pers.copy()
        dirty = self._dirty
        if dirty is None:
            c.index, c.by_arg = _build_index(self._facts_in_order())
            c._shared = set()
        else:
            index = dict(self.index)
            by_arg = dict(self.by_arg)
            shared = set(self.index)
            if dirty:
                shared.difference_update(dirty)
                for fam in dirty:
                    index.pop(fam, None)
                    by_arg.pop(fam, None)
                rebuilt = self._rebuilt
                if rebuilt is None:
                    # the dirty families in order, made once and shared by every copy of this context
                    rank = {t: i for i, t in enumerate(self._facts_in_order())}
                    redo = []
                    for fam in dirty:
                        b = self.index.get(fam)
                        if b is not None:
                            redo.extend(b.items)
                    redo.sort(key=rank.__getitem__)
                    rebuilt = self._rebuilt = _build_index(redo)
                index.update(rebuilt[0])
                by_arg.update(rebuilt[1])
            self._shared.update(shared)
            self._owned.clear()  # the bags this context owned may now be the copy's too
            c.index = index
            c.by_arg = by_arg
            c._shared = set(index)
        c._dirty = set()
        c._cow = set()
        c._owned = set()
        c._rebuilt = None
        rules: dict = {}
        rule_index: dict = {}
        for r in self.rules.values():
            rules[r.uid] = CtxRule(r.uid, r.alts, r.env, r.mode, r.source, r.keys, r.open)
            for k in r.keys:
                b = rule_index.get(k)
                if b is None:
                    b = rule_index[k] = Bag()
                b.add(r.uid)
        c.rules = rules
        c.rule_index = rule_index
        c.inert = list(self.inert)
        c.open = list(self.open)
        c.implicit = self.implicit
        c._canon = None
        return c


class FrozenContext:
    """A context kept only to be read back: its facts, rules and hypotheses without the
    matching indexes (which :meth:`thaw` rebuilds). The explorer keeps visited states this way:
    a few hundred bytes each instead of a context's tens of kilobytes (benchmark B8)."""

    __slots__ = ("lin", "aff", "pers", "rules", "inert", "open", "implicit", "canon")

    def __init__(self, ctx: "Context"):
        # a multiset as its facts repeated (one pointer a fact; the order of first occurrence kept)
        self.lin = tuple([t for t, n in ctx.lin.items() for _ in range(n)] if len(ctx.lin) < sum(ctx.lin.values())
                         else ctx.lin)
        self.aff = tuple([t for t, n in ctx.aff.items() for _ in range(n)]) if ctx.aff else ()
        self.pers = tuple(ctx.pers) if ctx.pers else ()
        self.rules = tuple(ctx.rules.values()) if ctx.rules else ()
        self.inert = tuple(ctx.inert) if ctx.inert else ()
        self.open = tuple(ctx.open) if ctx.open else ()
        self.implicit = ctx.implicit
        self.canon = ctx._canon[2] if ctx._canon is not None and ctx._canon[1] == len(ctx.inert) else None

    def thaw(self) -> "Context":
        """A context equal to the frozen one, its indexes built in the order its facts were added."""
        return _rebuild(_counts(self.lin), _counts(self.aff), dict.fromkeys(self.pers), self.rules, self.inert,
                        self.open, self.implicit, self.canon)


def _rebuild(lin: dict, aff: dict, pers: dict, rules, inert, open_, implicit, canon=None) -> "Context":
    """A context of these facts and hypotheses, its indexes built in the order the facts were added
    (what :meth:`FrozenContext.thaw` gives)."""
    c = Context()
    c.lin = lin
    c.aff = aff
    c.pers = pers
    c.index, c.by_arg = _build_index(c._facts_in_order())
    for r0 in rules:
        r = c.rules[r0.uid] = CtxRule(r0.uid, r0.alts, r0.env, r0.mode, r0.source, r0.keys, r0.open)
        for k in r.keys:
            b = c.rule_index.get(k)
            if b is None:
                b = c.rule_index[k] = Bag()
            b.add(r.uid)
    c.inert = list(inert)
    c.open = list(open_)
    c.implicit = implicit
    c._dirty = set()   # its bags are in the order re-adding the facts gives: copies share them
    if canon is not None:
        c._canon = (c.inert, len(c.inert), canon)
    return c


def replay(base, steps) -> "Context":
    """The state ``steps`` lead to from ``base`` (a context, or one frozen), each step one that
    only consumes and adds facts (what ``forward.plan_successor`` plans), as
    :meth:`FrozenContext.thaw` would give it had it been frozen: its facts in the order the
    steps' removals and additions leave them (those of ``Context.remove_fact`` and ``add_fact``),
    the indexes built in that order. Why: the explorer keeps such a state as nothing at all
    and rebuilds it from an ancestor kept frozen (benchmark B8: bytes per state)."""
    if isinstance(base, FrozenContext):
        lin, aff, pers = _counts(base.lin), _counts(base.aff), dict.fromkeys(base.pers)
        rules, inert, open_ = base.rules, base.inert, base.open
    else:
        lin, aff, pers = base.lin.copy(), base.aff.copy(), base.pers.copy()
        rules, inert, open_ = tuple(base.rules.values()), tuple(base.inert), tuple(base.open)
    for step in steps:
        for mode, t in step.consumed:
            take_count(lin, aff, mode, t)
        for mode, t in step.produced:
            add_count(lin, aff, pers, mode, t)
    return _rebuild(lin, aff, pers, rules, inert, open_, base.implicit)


def take_count(lin: dict, aff: dict, mode, t) -> None:
    """One copy of fact ``t`` fewer in the counts (as :meth:`Context.remove_fact`; persistent
    facts stay): the count tables a successor is planned or a state rebuilt on."""
    if mode == LIN:
        n = lin[t] - 1
        if n:
            lin[t] = n
        else:
            del lin[t]
    elif mode == AFF:
        n = aff[t] - 1
        if n:
            aff[t] = n
        else:
            del aff[t]


def add_count(lin: dict, aff: dict, pers: dict, mode, t) -> None:
    """One copy of fact ``t`` more in the counts (as :meth:`Context.add_fact`)."""
    if mode == LIN:
        lin[t] = lin.get(t, 0) + 1
    elif mode == AFF:
        aff[t] = aff.get(t, 0) + 1
    elif t not in pers:
        pers[t] = None


def _counts(facts: tuple) -> dict:
    d: dict = {}
    for t in facts:
        d[t] = d.get(t, 0) + 1
    return d


def _clone(b: Bag) -> Bag:
    c = _new_bag(Bag)
    c.items = b.items.copy()
    c.pos = b.pos.copy() if b.pos is not None else None
    c.paths = b.paths
    return c


_new_bag = Bag.__new__


def _build_index(order: list) -> tuple[dict, dict]:
    """``index`` and ``by_arg`` for distinct facts added in the order given (as add_fact would
    build them, without its membership tests)."""
    index: dict = {}
    by_arg: dict = {}
    big: list = []  # bags past Bag.SMALL: they get their position dictionary at the end
    new_bag = _new_bag
    small1 = Bag.SMALL + 1

    def put(d: dict, key, t) -> None:
        b = d.get(key)
        if b is None:
            b = d[key] = new_bag(Bag)
            b.items = [t]
            b.pos = None
            b.paths = None
        else:
            items = b.items
            items.append(t)
            if len(items) == small1:
                big.append(b)

    for t in order:
        fam = t.head
        put(index, fam, t)
        args = t.args
        if args:
            per = by_arg.get(fam)
            if per is None:
                per = by_arg[fam] = [{} for _ in args]
            elif len(per) < len(args):
                per.extend({} for _ in range(len(args) - len(per)))
            for d, a in zip(per, args):
                put(d, a, t)
    for b in big:
        b.pos = {y: i for i, y in enumerate(b.items)}
    return index, by_arg


def _wake_key(pattern: Node, env: tuple):
    """The most selective index key under which a premise can be woken."""
    fam = pattern.head
    for i, a in enumerate(pattern.args):
        v = ground_value(a, env)
        if v is not None:
            return (fam, i, v)
    return fam


def ground_value(a: Node, b) -> Optional[Node]:
    """The value of a pattern argument if the bindings already determine it."""
    if not a.metas:
        return a if not (a.maxb or a.evars) else None  # a logic variable is no index key
    if type(a) is Root and not a.args and type(a.head) is Meta:
        return b[a.head.index]
    return None
