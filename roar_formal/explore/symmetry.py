"""Symmetry reduction: states identified up to a verified group of permutations of constants.

A model may be symmetric: a permutation of its constants (two identical processes, and
everything named after them) maps every declaration of its signature onto a declaration and
its start state onto itself up to renaming of fresh names. Such a permutation maps every
transition onto a transition (the rules are the signature's, the matching is syntactic), so
it is an automorphism of the state graph that fixes the start state. The states of one orbit
(the images of a state under the group) then have the same future up to the permutation:
the quotient graph, whose states are orbits, has the same deadlocks and reaches the same
states *as far as a property that cannot tell the images of a state apart* (a predicate
invariant under the group) is concerned (Emerson and Sistla, Ip and Dill).

This module is generic (it knows CLF, not ROAR):

* :class:`ConstPerm` renames constants in terms, types and contexts;
* :func:`close_group` generates a group from permutations (refused above ``MAX_ORDER``);
* :func:`verify` checks a permutation on a program's signature and a start state, and says
  which declaration it fails on: a permutation is never trusted by its names;
* :func:`discover_clf` proposes, for a plain CLF program, the permutations of interchangeable
  constants (of one type, mentioned by no declaration), verified on the start state;
* :class:`SymmetricSystem` wraps a transition system: a state's key is the least key over its
  images, so the explorer keeps one state per orbit. Its discovery tree stays concrete: the
  first state of an orbit reached is kept as the orbit's representative, exactly as reached
  from its (concrete) parent, so every path of parent pointers is a real path of the model and
  replays as one. Only edges into orbits already visited lead to an image of the state kept;
  :func:`concrete_lasso` turns a cycle of the quotient into a real one.

The explorer meets the wrapper as any system (``explore/system.py``'s protocol).
"""

from __future__ import annotations

import itertools
from collections import Counter
from dataclasses import dataclass, field
from typing import Callable, Iterable, Optional

from ..clf.context import Context
from ..clf.state import canonical_key
from ..clf.terms import Const, Lam, Node, Root
from ..errors import RoarError

#: the largest group enumerated (7!): a state's key is the least of |G| keys
MAX_ORDER = 5040


class ConstPerm:
    """A permutation of constants (``{name: name}``, every name mapped to one of the same set).

    ``rules`` maps declaration (rule) names to their images, as :func:`verify` found them."""

    def __init__(self, mapping: dict[str, str], rules: Optional[dict[str, str]] = None):
        self.mapping = {a: b for a, b in mapping.items() if a != b}
        if sorted(self.mapping) != sorted(self.mapping.values()):
            raise ValueError("not a permutation: " + repr(self.mapping))
        self.consts = {Const(a): Const(b) for a, b in self.mapping.items()}
        self.rules = dict(rules or {})
        self._memo: dict = {}

    def __bool__(self) -> bool:
        return bool(self.mapping)

    def __repr__(self) -> str:
        return "ConstPerm(" + ", ".join(f"{a}->{b}" for a, b in sorted(self.mapping.items())) + ")"

    def key(self) -> tuple:
        return tuple(sorted(self.mapping.items()))

    def compose(self, other: "ConstPerm") -> "ConstPerm":
        """``self`` after ``other``."""
        names = set(self.mapping) | set(other.mapping)
        m = {n: self.mapping.get(other.mapping.get(n, n), other.mapping.get(n, n)) for n in names}
        rnames = set(self.rules) | set(other.rules)
        r = {n: self.rules.get(other.rules.get(n, n), other.rules.get(n, n)) for n in rnames}
        return ConstPerm(m, {a: b for a, b in r.items() if a != b})

    def rule(self, name: str) -> str:
        return self.rules.get(name, name)

    def name(self, name: str) -> str:
        return self.mapping.get(name, name)

    def term(self, t):
        """The image of a term, type or kind (hash-consed: a node without a permuted constant
        is itself)."""
        if not isinstance(t, Node):
            return t
        memo = self._memo
        r = memo.get(t)
        if r is not None:
            return r
        tt = type(t)
        if tt is Root:
            h = t.head
            h2 = self.consts.get(h, h) if type(h) is Const else h
            args = tuple(self.term(a) for a in t.args)
            r = t if h2 is h and all(a is b for a, b in zip(args, t.args)) else Root(h2, args)
        elif tt is Lam:
            b = self.term(t.body)
            r = t if b is t.body else Lam(b)
        else:
            vals = [getattr(t, f) for f in tt.fields]
            new = [self.term(v) if isinstance(v, Node) else v for v in vals]
            r = t if all(a is b for a, b in zip(vals, new)) else tt(*new)
        if len(memo) > 400_000:
            memo.clear()
        memo[t] = r
        return r

    @staticmethod
    def _renamable(ctx: Context) -> None:
        if ctx.rules or ctx.open:
            raise RoarError("symmetry reduction: a state holds rules or facts with logic variables, "
                            "which symmetry reduction does not rename")

    def context(self, ctx: Context) -> Context:
        """The image of a state (its facts renamed: enough for its key and its description)."""
        self._renamable(ctx)
        out = Context()
        out.implicit = ctx.implicit
        f = self.term
        out.lin = {f(t): n for t, n in ctx.lin.items()}
        out.aff = {f(t): n for t, n in ctx.aff.items()}
        out.pers = {f(t): None for t in ctx.pers}
        out.inert = [(m, f(t)) for m, t in ctx.inert]
        return out

    def full_context(self, ctx: Context) -> Context:
        """The image of a state as a context the engine can step (indexes built)."""
        self._renamable(ctx)
        out = Context()
        out.implicit = ctx.implicit
        for mode, t, n in ctx.facts():
            for _ in range(n):
                out.add_fact(self.term(t), mode)
        out.inert = [(m, self.term(t)) for m, t in ctx.inert]
        return out


def close_group(gens: Iterable[ConstPerm], limit: int = MAX_ORDER) -> list[ConstPerm]:
    """Every element of the group the permutations generate, the identity first; a group of more
    than ``limit`` elements is refused (a state's key would cost that many keys)."""
    gens = [g for g in gens if g]
    ident = ConstPerm({})
    seen = {ident.key(): ident}
    frontier = [ident]
    while frontier:
        nxt = []
        for x in frontier:
            for g in gens:
                y = g.compose(x)
                k = y.key()
                if k not in seen:
                    seen[k] = y
                    nxt.append(y)
                    if len(seen) > limit:
                        raise RoarError(f"symmetry reduction: the group of symmetries has more than {limit:,} "
                                        f"elements (each state's key is the least over the group's images); "
                                        f"turn symmetry off, or make fewer agents interchangeable")
        frontier = nxt
    return list(seen.values())


def factorial_order(sizes: Iterable[int]) -> int:
    out = 1
    for k in sizes:
        for i in range(2, k + 1):
            out *= i
    return out


def transpositions(blocks: list[list[dict[str, str]]]) -> list[ConstPerm]:
    """Generators of the product of the symmetric groups of ``blocks``: each block lists k
    interchangeable members, each member a ``{role: constant name}`` with the same roles; the
    transpositions of consecutive members generate the block's k! permutations."""
    out = []
    for members in blocks:
        for a, b in zip(members, members[1:]):
            m = {}
            for role, x in a.items():
                y = b[role]
                m[x], m[y] = y, x
            out.append(ConstPerm(m))
    return out


# ---------------------------------------------------------------- verification


@dataclass
class Check:
    """What :func:`verify` found: ``ok``, the reason it failed, and the rule renaming."""

    ok: bool
    reason: str = ""
    rules: dict = field(default_factory=dict)
    decl: Optional[str] = None   # the declaration it failed on, if one (a front end may name its source)


def verify(sig, start: Context, perm: ConstPerm, labels: Optional[dict[str, int]] = None) -> Check:
    """Does ``perm`` map the signature ``sig`` (every declaration: families, constants, rules,
    clauses) onto itself and the start context onto itself (up to renaming of fresh names)?

    ``labels`` names label families (family -> the position of its label argument, as in
    ``task_id T 3``): declarations of them are compared without their label, and the labels
    must be told apart by the permutation exactly as before (``label(x) == label(y)`` iff
    ``label(perm x) == label(perm y)``): the caller vouches that the model reads such labels only
    by comparing two of them. Returns the rule renaming (declaration name -> the name of its
    image) on success."""
    labels = labels or {}
    infos = [i for i in sig.consts.values() if not getattr(i, "builtin", False)]
    by_name = {i.name: i for i in infos}
    for a, b in perm.mapping.items():
        if a not in by_name or b not in by_name:
            return Check(False, f"'{a if a not in by_name else b}' is not a constant of the model")
        ia, ib = by_name[a], by_name[b]
        if ib.classifier is not perm.term(ia.classifier) or ia.is_family != ib.is_family:
            return Check(False, f"'{a}' and '{b}' are not declared alike")
    label_of: dict = {}   # (family, labelled constant) -> label

    def item(info, image: bool):
        cl = perm.term(info.classifier) if image else info.classifier
        df = info.definition
        if df is not None and image:
            df = perm.term(df)
        if not info.is_family and df is None and type(cl) is Root and type(cl.head) is Const \
                and cl.head.name in labels:
            pos = labels[cl.head.name]
            if pos < len(cl.args):
                args = list(cl.args)
                if not image:
                    label_of[(cl.head.name, tuple(a for i, a in enumerate(args) if i != pos))] = args[pos]
                args[pos] = None
                return ("label", cl.head.name, tuple(args))
        return (info.is_family, cl, df)

    mine = Counter(item(i, False) for i in infos)
    image_of: dict = {}
    for i in infos:
        it = item(i, True)
        image_of[i.name] = it
    got = Counter(image_of.values())
    if got != mine:
        for i in infos:
            if mine.get(image_of[i.name], 0) < got[image_of[i.name]]:
                return Check(False, f"declaration '{i.name}' has no image: the permutation maps it onto "
                                    f"nothing the model declares", decl=i.name)
        return Check(False, "the permutation does not map the declarations onto themselves")
    # labels: equal exactly when their images' are
    for fam in labels:
        keyed = {k[1]: v for k, v in label_of.items() if k[0] == fam}
        items = list(keyed.items())
        for (ka, la), (kb, lb) in itertools.combinations(items, 2):
            ia = keyed.get(tuple(perm.term(x) for x in ka))
            ib = keyed.get(tuple(perm.term(x) for x in kb))
            if ia is None or ib is None or ((la is lb) != (ia is ib)):
                return Check(False, f"the labels of {fam} are not told apart alike under the permutation")
    # the rule renaming: each declaration's name -> one declaration with its image (a bijection)
    free: dict = {}
    for i in infos:
        free.setdefault(item(i, False), []).append(i.name)
    rules = {}
    for i in infos:
        it = image_of[i.name]
        if it == item(i, False):
            continue
        names = free[it]
        target = perm.name(i.name) if perm.name(i.name) in names else names[0]
        names.remove(target)
        if target != i.name:
            rules[i.name] = target
    try:
        same = canonical_key(perm.context(start)) == canonical_key(start)
    except RoarError as exc:
        return Check(False, exc.message)
    if not same:
        return Check(False, "the start state is not mapped onto itself")
    return Check(True, "", rules)


def discover_clf(program, start: Context) -> tuple[list[list[dict[str, str]]], list[str]]:
    """Interchangeable constants of a plain CLF program: for each type, its constants (``c : t.``
    with ``t`` an atomic type) that no other declaration mentions. Each such set whose every
    transposition maps the start state onto itself is a block (a group of k! permutations);
    returns (blocks, notes on the sets refused)."""
    sig = program.sig
    infos = [i for i in sig.consts.values() if not getattr(i, "builtin", False)]
    mentioned: Counter = Counter()

    def consts_in(t, out: set):
        if not isinstance(t, Node):
            return
        if type(t) is Root:
            if type(t.head) is Const:
                out.add(t.head.name)
            for a in t.args:
                consts_in(a, out)
        elif type(t) is Lam:
            consts_in(t.body, out)
        else:
            for f in type(t).fields:
                consts_in(getattr(t, f), out)
    for i in infos:
        s: set = set()
        consts_in(i.classifier, s)
        consts_in(i.definition, s)
        for n in s:
            mentioned[n] += 1
    by_type: dict = {}
    for i in infos:
        cl = i.classifier
        if i.is_family or i.definition is not None or type(cl) is not Root or cl.args:
            continue
        if mentioned.get(i.name, 0):
            continue
        by_type.setdefault(cl.head.name, []).append(i.name)
    blocks, notes = [], []
    for fam, names in by_type.items():
        if len(names) < 2:
            continue
        members = [{"": n} for n in names]
        gens = transpositions([members])
        bad = [g for g in gens if not verify(sig, start, g).ok]
        if bad:
            notes.append(f"{', '.join(names)} (of type {fam}) are not interchangeable: the start state "
                         f"tells them apart")
            continue
        blocks.append(members)
    return blocks, notes


# ---------------------------------------------------------------- the quotient search


class SymmetricSystem:
    """A transition system whose states are keyed by the least key over their images under
    ``group`` (a list of :class:`ConstPerm`, the identity first): the explorer keeps one state
    per orbit. Everything else is the wrapped system's (successors are those of the state kept,
    which the explorer reached by a real path)."""

    def __init__(self, inner, group: list[ConstPerm], description: str = ""):
        self.inner = inner
        self.group = group
        self.description = description
        self.options = getattr(inner, "options", None)

    def __getattr__(self, name):
        if name in ("lazy_successors", "planned_successors", "build_successor"):   # keys must be the symmetric ones
            raise AttributeError(name)
        return getattr(self.inner, name)

    def initial(self):
        return self.inner.initial()

    def key(self, state):
        base = self.inner.key(state)
        if len(self.group) == 1:
            return base
        best = base
        for g in self.group[1:]:
            k = self.inner.key(g.context(state))
            if k < best:
                best = k
        return best

    def successors(self, state):
        return self.inner.successors(state)

    def reduced_successors(self, state):
        return self.inner.reduced_successors(state)

    def describe(self, state):
        return self.inner.describe(state)

    def describe_step(self, step):
        return self.inner.describe_step(step)

    def orbit_size(self, state) -> int:
        """How many distinct states (up to renaming of fresh names) the orbit of ``state`` has."""
        return len({self.inner.key(g.context(state)) for g in self.group})


def concrete_lasso(system: SymmetricSystem, prefix_states: list, cycle_keys: list,
                   step_filter: Optional[Callable] = None, max_laps: Optional[int] = None):
    """A real lasso from a cycle of the quotient. ``prefix_states`` ends at a concrete state c0
    of the cycle's first orbit; ``cycle_keys`` are the symmetric keys of the orbits the cycle
    visits after it, the last one c0's. The cycle is followed from c0 by real steps (at each
    orbit a successor whose symmetric key is the next one's), lap after lap: the laps end in
    states of c0's orbit, which has at most |G| states, so within |G| + 1 laps one repeats.
    Returns (the real steps before the repeated state, the real steps of the cycle from it), or
    None when no real successor matches (the cycle was not a cycle of the quotient)."""
    laps_max = (max_laps or len(system.group)) + 1
    inner = system.inner
    cur = prefix_states[-1]
    seen = {inner.key(cur): 0}
    steps: list = []
    marks = [0]
    for lap in range(1, laps_max + 1):
        for k in cycle_keys:
            succ = next((s for s in inner.successors(cur)
                         if (step_filter is None or step_filter(s)) and system.key(s.state) == k), None)
            if succ is None:
                return None
            steps.append(succ)
            cur = succ.state
        marks.append(len(steps))
        kk = inner.key(cur)
        if kk in seen:
            first = marks[seen[kk]]
            return steps[:first], steps[first:]
        seen[kk] = lap
    return None
