"""Backward chaining outside the monad: depth-first proof search with backtracking.

Resources follow the input/output model: hypotheses live in one list with a
``used`` flag, a linear hypothesis is consumed by setting the flag (recorded on
a trail and undone on backtracking), and a scope that introduced a linear
hypothesis checks on exit that it was consumed. No context is ever split
nondeterministically. ``A & B`` solves both halves from the same resources and
requires they consume the same ones; a persistent premise (``->``) may use no
linear or affine hypothesis from outside; ``{S}`` runs the forward engine on
the unused hypotheses, committed, and then matches ``S`` against what is left
(backtracking only over that match). Premises of a clause are solved last
first: ``C o- A o- B`` solves A, then B.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterator, Optional

from . import terms
from .builtins import BUILTINS, BuiltinError, evaluate, input_values
from .context import Context
from .forward import Run, inst, load_positive, match
from .rules import AFF, LIN, PERS, positive_parts
from .terms import (TypeNode, NUMBER, Aff, Bang, Const, EVar, Imp, Lam, Lit, Meta, Monad, Node, Param, Pi, Root, Top, With, deref,
                    num_term, param_term, string_term, subst, subst1, zonk)
from .unify import Unifier


@dataclass(eq=False)
class Hyp:
    ty: Node
    mode: str
    used: bool = False
    name: str = "_"  # the proof variable standing for this hypothesis (for proof terms)


class _NotTabled(Exception):
    """A goal holds a term :func:`_variant` does not key (a lambda, a type)."""


def _variant(t: Node, seen: dict):
    """A key of a first-order term equal for two terms exactly when one is the other with its
    logic variables renamed: each logic variable by its order of first occurrence."""
    if not t.evars:
        return t
    if type(t) is Root:
        h = t.head
        args = tuple([_variant(a, seen) for a in t.args])
        if type(h) is EVar:
            return ("?", seen.setdefault(h, len(seen)), args)
        return (h, args)
    raise _NotTabled


#: the deepest nesting of goals a proof search takes: a goal costs about eight Python frames, and
#: ``query.with_big_stack`` allows 200,000, so the search stops itself (SearchLimit, located by its
#: caller) before the interpreter does (a RecursionError deep in nested generators is fragile: a
#: second one while the first unwinds kills the process)
MAX_DEPTH = 20000


class SearchLimit(Exception):
    """Raised when the proof search exceeds its depth bound."""


class Backward:
    """Proof search over a program's clauses and a context of hypotheses."""

    def __init__(self, program, seed: Optional[int] = 0, monad_depth: Optional[int] = None,
                 max_depth: int = MAX_DEPTH, fair: bool = False):
        self.program = program
        self.u = Unifier()
        self.hyps: list[Hyp] = []
        self.htrail: list[Hyp] = []
        self.seed = seed
        self.fair = fair
        self.monad_depth = monad_depth
        self.max_depth = max_depth
        self.depth = 0
        self.monad_runs: list[Run] = []
        self.on_monad: Optional[Callable[[Run], None]] = None
        self.proofs = False  # build monadic proof terms (names for every fact in the monad)
        # a T was proved in the current scope (Celf's slack): the linear hypotheses in scope that are
        # left over may be taken as consumed by it, whenever the scope checks them
        self.slack = False
        self._names = 0
        # families whose goals are tabled (see _tabled_answers): set by a caller that asks only
        # whether a goal has a proof, never for the proof
        self.tabled: frozenset = frozenset()
        self._table: dict = {}
        self._tabling: set = set()

    def prove_consuming(self, ctx: Context, goal: Node, mode: str, consumed=()) -> Iterator[list]:
        """A forward rule's backward premise proved on ``ctx`` (:func:`prove_consuming`): the forward
        engine calls it through the prover it is given, so that it does not import this module."""
        return prove_consuming(self, ctx, goal, mode, consumed)

    def fresh_name(self, base: str = "X") -> str:
        self._names += 1
        return f"{base}{self._names}"

    # -------------------------------------------------------------- helpers
    def _use(self, h: Hyp) -> None:
        h.used = True
        self.htrail.append(h)

    def undo(self, mark: tuple, hmark: int) -> None:
        """Back to ``(self.u.mark(), len(self.htrail))`` as taken before a search (a caller
        that stops a search early undoes what it bound)."""
        self._undo(mark, hmark)

    def _undo(self, mark: tuple, hmark: int) -> None:
        self.u.undo(mark)
        while len(self.htrail) > hmark:
            self.htrail.pop().used = False

    def _push(self, ty: Node, mode: str) -> list[Hyp]:
        """Assume a (possibly positive) type; returns the hypotheses added."""
        added: list[Hyp] = []

        def fresh(hint: str, dom: Node) -> Root:
            added.append(Hyp(dom, PERS, name=self.fresh_name(hint)))  # the new name is usable as a proof
            return param_term(Param(hint))

        for m, part in positive_parts(ty, fresh, mode):
            added.append(Hyp(part, m, name=self.fresh_name()))
        self.hyps.extend(added)
        return added

    def _pop(self, added: list[Hyp]) -> None:
        del self.hyps[len(self.hyps) - len(added):]

    # -------------------------------------------------------------- goals
    def solve(self, goal: Node, floor: int = 0, aff_ok: bool = True) -> Iterator[tuple]:
        """Solve ``goal``, yielding a proof term (see :func:`show_proof`) per solution;
        hypotheses below index ``floor`` may only be used persistently (or affinely,
        when ``aff_ok``)."""
        self.depth += 1
        if self.depth > self.max_depth:
            self.depth -= 1
            raise SearchLimit(f"proof search deeper than {self.max_depth}")
        try:
            yield from self._solve(deref(goal), floor, aff_ok)
        finally:
            self.depth -= 1

    def _solve(self, goal: Node, floor: int, aff_ok: bool) -> Iterator[None]:
        tg = type(goal)
        if tg is Root:
            yield from self._atom(goal, floor, aff_ok)
        elif tg is Pi:
            p = Param(goal.hint)
            added = self._push(goal.dom, PERS)
            added[0].name = goal.hint if not any(h.name == goal.hint for h in self.hyps[:-1]) else added[0].name
            try:
                for pf in self.solve(subst1(goal.body, param_term(p)), floor, aff_ok):
                    yield ("lam", f"\\!{added[0].name}.", pf)   # (a Pi's argument is persistent)
            finally:
                self._pop(added)
        elif tg is Imp:
            added = self._push(goal.dom, goal.mode)
            binder = {LIN: "\\", PERS: "\\!", AFF: "\\@"}[goal.mode]
            try:
                for pf in self.solve(goal.body, floor, aff_ok):
                    # (a T proved inside may have taken what is left: slack)
                    if self.slack or all(h.used or h.mode != LIN for h in added):
                        for h in reversed(added):
                            pf = ("lam", f"{binder}{h.name}.", pf)
                        yield pf
            finally:
                self._pop(added)
        elif tg is With:
            yield from self._with(goal, floor, aff_ok)
        elif tg is Top:
            # Celf's slack (OpSem: Top consumes nothing and sets slack): the resources left over
            # when their scope ends are T's, so goals solved after it may still use them
            old, self.slack = self.slack, True
            yield ("top",)
            self.slack = old
        elif tg is Monad:
            yield from self._monad(goal.body, floor)
        else:
            raise AssertionError(f"unexpected goal {goal!r}")

    def _with(self, goal: With, floor: int, aff_ok: bool) -> Iterator[None]:
        """Both halves from the same resources, consuming the same ones; a half that proved T
        (slack) may have consumed fewer, the other's extra being its T's (Celf's additive rule
        with slack)."""
        mark, hmark = self.u.mark(), len(self.htrail)
        outer_slack = self.slack
        self.slack = False
        for pl in self.solve(goal.left, floor, aff_ok):
            left_slack = self.slack
            left_used = frozenset(id(h) for h in self.htrail[hmark:])
            # redo the right half from the same resources
            saved = self.htrail[hmark:]
            for h in saved:
                h.used = False
            mark2 = len(self.htrail)
            self.slack = False
            for pr in self.solve(goal.right, floor, aff_ok):
                right_slack = self.slack
                right_used = frozenset(id(h) for h in self.htrail[mark2:])
                if right_used == left_used or (left_slack and left_used <= right_used) \
                        or (right_slack and right_used <= left_used) or (left_slack and right_slack):
                    extra = [h for h in saved if id(h) not in right_used]   # the left half's, taken by the right's T
                    for h in extra:
                        h.used = True
                    self.slack = outer_slack or (left_slack and right_slack)
                    yield ("pair", pl, pr)
                    self.slack = right_slack
                    for h in extra:
                        h.used = False
            while len(self.htrail) > mark2:
                self.htrail.pop().used = False
            for h in saved:
                h.used = True
            self.slack = False
        self._undo(mark, hmark)
        self.slack = outer_slack

    # -------------------------------------------------------------- atoms
    def _atom(self, goal: Root, floor: int, aff_ok: bool) -> Iterator[None]:
        fam = goal.head
        bi = BUILTINS.get(fam)
        if bi is not None:
            yield from self._builtin(bi, goal)
            return
        if self.tabled and type(fam) is Const and fam.name in self.tabled:
            got = self._tabled_answers(goal, floor, aff_ok)
            if got is not None:
                for answer in got:
                    mark = self.u.mark()
                    if self.u.unify(goal, answer):
                        yield ("app", "tabled", [])
                    self.u.undo(mark)
                return
        yield from self._atom_search(goal, floor, aff_ok)

    def _tabled_answers(self, goal: Root, floor: int, aff_ok: bool) -> Optional[list]:
        """Every distinct instance of ``goal`` that has a proof, each once, computed on the first
        call for a goal of its shape (up to renaming of its logic variables) under the same
        hypotheses; None when the goal cannot be tabled (a linear or affine hypothesis is in
        scope, an answer keeps a logic variable, or the same goal is being tabled further up).

        Why: a clause such as transitivity, ``hyp (s N) (eq A C) <- hyp N (eq A B) <- hyp N (eq B
        C)``, proves the same subgoals again for every proof of the one before, so an exhaustive
        search (a goal with no proof) costs exponentially more at each level of its bound (the
        ROAR compiler's entailment queries took 6 s for one constraint with a where clause).
        Tabled, each subgoal is solved once and its answers reused. The answers are those of
        the search; their proofs are not kept, so only a caller that asks whether a proof exists
        sets ``tabled``."""
        scope = []
        for h in self.hyps:
            if h.used:
                continue
            if h.mode != PERS:
                return None
            ty = zonk(h.ty) if h.ty.evars else h.ty   # (bound logic variables read through)
            if ty.evars:
                return None
            scope.append(ty)
        g = zonk(goal)
        try:
            key = (_variant(g, {}), tuple(scope))
        except _NotTabled:
            return None
        got = self._table.get(key)
        if got is not None:
            return got
        if key in self._tabling:
            return None
        self._tabling.add(key)
        answers: list = []
        seen: set = set()
        mark, hmark = self.u.mark(), len(self.htrail)
        search = self._atom_search(goal, floor, aff_ok)
        try:
            for _pf in search:
                a = zonk(goal)
                if a.evars:
                    return None
                if a not in seen:
                    seen.add(a)
                    answers.append(a)
        finally:
            search.close()
            self._undo(mark, hmark)
            self._tabling.discard(key)
        self._table[key] = answers
        return answers

    def _atom_search(self, goal: Root, floor: int, aff_ok: bool) -> Iterator[None]:
        """An atom's proofs by the hypotheses in scope, then the program's clauses."""
        fam = goal.head
        hyps = self.hyps
        for i in range(len(hyps) - 1, -1, -1):
            h = hyps[i]
            if h.used:
                continue
            if h.mode != PERS and i < floor and not (h.mode == AFF and aff_ok):
                continue
            if fam not in head_families(h.ty):
                continue
            mark, hmark = self.u.mark(), len(self.htrail)
            if h.mode != PERS:
                self._use(h)
            yield from self._clause(h.ty, goal, floor, aff_ok, h.name)
            self._undo(mark, hmark)
        args = goal.args
        for name, ty, skel in self.program.indexed_clauses(fam):
            if skel is not None and not _fits(skel, args):
                continue   # the clause's head cannot unify with the goal (first-argument indexing, generalised)
            mark, hmark = self.u.mark(), len(self.htrail)
            yield from self._clause(ty, goal, floor, aff_ok, name)
            self._undo(mark, hmark)

    def _builtin(self, bi, goal: Root) -> Iterator[tuple]:
        """A goal of a built-in family, decided natively (at most one solution; hypotheses
        of the family are not consulted: none can be declared)."""
        res = evaluate(bi, goal.args)
        if res is None or res is False:
            return
        if res is True:
            yield ("app", bi.name, [])
            return
        mark = self.u.mark()
        if self.u.unify(goal.args[-1], res):
            yield ("app", bi.name, [])
        self.u.undo(mark)

    def _clause(self, ty: Node, goal: Root, floor: int, aff_ok: bool, head: str) -> Iterator[tuple]:
        # the common shape, Pi xs. A1 -> ... -> An -> head, is instantiated with one substitution
        # per premise and one for the head (not one pass over the whole type per binder)
        evs: list = []
        raw: list = []
        pis: list = []   # (premises before it, its logic variable) of each explicit Pi, for the proof term
        implicit = self.program.implicit.get(Const(head), 0) if self.proofs else 0
        t = ty
        while True:
            tt = type(t)
            if tt is Pi:
                evs.append(Root(EVar(t.hint, subst(t.dom, evs[::-1]) if evs else t.dom), ()))
                if self.proofs and len(evs) > implicit:
                    pis.append((len(raw), evs[-1]))
                t = t.body
            elif tt is Imp:
                raw.append((t.mode, t.dom, len(evs)))
                t = t.body
            else:
                break
        if type(t) is Root:
            rev = evs[::-1]
            prems = [(m, subst(d, rev[len(rev) - k:]) if k else d) for m, d, k in raw]
            yield from self._clause_rest(subst(t, rev) if evs else t, prems, goal, floor, aff_ok, head, pis)
            return
        prems: list[tuple[str, Node]] = []
        while True:
            tt = type(ty)
            if tt is Pi:
                x = EVar(ty.hint, ty.dom)
                ty = subst1(ty.body, Root(x, ()))
            elif tt is Imp:
                prems.append((ty.mode, ty.dom))
                ty = ty.body
            elif tt is With:  # use either half: the clause is (Pi xs. prems -o L) & (... R)
                for half in (ty.left, ty.right):
                    yield from self._clause_rest(half, prems, goal, floor, aff_ok, head)
                return
            else:
                break
        yield from self._clause_rest(ty, prems, goal, floor, aff_ok, head)

    def _clause_rest(self, ty: Node, prems: list, goal: Root, floor: int, aff_ok: bool,
                     head: str, pis: list = ()) -> Iterator[tuple]:
        prems = list(prems)
        while True:
            tt = type(ty)
            if tt is Pi:
                x = EVar(ty.hint, ty.dom)
                ty = subst1(ty.body, Root(x, ()))
            elif tt is Imp:
                prems.append((ty.mode, ty.dom))
                ty = ty.body
            elif tt is With:
                for half in (ty.left, ty.right):
                    yield from self._clause_rest(half, prems, goal, floor, aff_ok, head)
                return
            else:
                break
        if type(ty) is not Root:
            return
        mark = self.u.mark()
        if not self.u.unify(ty, goal):
            self.u.undo(mark)
            return
        marks = {PERS: "!", AFF: "@", LIN: ""}
        for args in self._premises(prems, len(prems) - 1, floor, aff_ok):
            # args were solved last premise first; print them in declaration order
            out = [(marks[m], a) for (m, _), a in zip(prems, reversed(args))]
            for k, x in reversed(pis):   # an explicit Pi's argument, where it is declared (Celf: q !z)
                out.insert(k, ("!", ("term", self.program.show(zonk(x)))))
            yield ("app", head, out)
        self.u.undo(mark)

    def _premises(self, prems, k: int, floor: int, aff_ok: bool) -> Iterator[list]:
        if k < 0:
            yield []
            return
        mode, a = prems[k]
        if mode == PERS:
            sub = self.solve(a, len(self.hyps), False)
        elif mode == AFF:
            sub = self.solve(a, len(self.hyps), True)
        else:
            sub = self.solve(a, floor, aff_ok)
        if mode == LIN:
            for pf in sub:
                for rest in self._premises(prems, k - 1, floor, aff_ok):
                    yield [pf] + rest
            return
        # a persistent or affine premise is proved from the hypotheses above the floor only: a T
        # in it takes none of the outer ones (its slack stays inside)
        outer = self.slack
        self.slack = False
        for pf in sub:
            inner, self.slack = self.slack, outer
            for rest in self._premises(prems, k - 1, floor, aff_ok):
                yield [pf] + rest
            self.slack = inner
        self.slack = outer

    # -------------------------------------------------------------- the monad
    def _monad(self, s: Node, floor: int) -> Iterator[None]:
        mark, hmark = self.u.mark(), len(self.htrail)
        ctx = Context()
        ctx.implicit = getattr(self.program, "implicit", None)
        names = _Names(self) if self.proofs else None
        for i, h in enumerate(self.hyps):
            if h.used:
                continue
            if h.mode != PERS and i < floor:
                continue
            ty = zonk(h.ty)
            # a hypothesis mentioning logic variables enters as an open fact (or rule): the
            # rules that may read it match by unification (forward.Run's general path)
            added = load_positive(ctx, ty if h.mode == LIN else (Bang(ty) if h.mode == PERS else Aff(ty)),
                                  self.program.compile_context_rule)
            if names is not None:
                for _m, x in added:
                    names.bind(x, h.name)
            if h.mode != PERS:
                self._use(h)
        run = Run(self.program.templates, ctx, seed=self.seed, fair=self.fair,
                  prover=self.program.prover(self), on_step=names.step if names is not None else None)
        quiescent = run.run(self.monad_depth)
        self.monad_runs.append(run)
        if self.on_monad is not None:
            self.on_monad(run)
        del quiescent
        witnesses: list = []   # (leaves before it, its logic variable) per Exists of the goal
        for used in self._match_pos(s, ctx, witnesses):
            if names is None:
                yield ("monad", None, None)
            else:
                saved = {k: list(v) for k, v in names.facts.items()}
                final = [{LIN: "", AFF: "@", PERS: "!"}[m] + names.name_at(m, t, k) for m, t, k in used]
                # each Exists witness where its binder stands (Celf: {... [!p, X4]} for {Exists p. a p})
                for at, w in reversed(witnesses):
                    final.insert(at, "!" + self.program.show(zonk(w)).replace("#", "_"))
                names.facts = saved
                yield ("monad", list(names.lets), final)
        self._undo(mark, hmark)

    def _match_pos(self, s: Node, ctx: Context, witnesses: Optional[list] = None) -> Iterator[list]:
        """Match the positive type ``s`` against the final context; linear leftovers fail. The
        logic variables of its Exists binders are appended to ``witnesses``."""
        evs: list = []

        def witness(hint, dom):
            evs.append(Root(EVar(hint, dom), ()))
            return evs[-1]
        at: list = []
        items = positive_parts(s, witness, positions=at)
        if witnesses is not None:
            witnesses.extend(zip(at, evs))
        # Each hypothesis occurrence is a separate candidate (as in Celf): two identical
        # linear facts matched by two goal atoms give two solutions.
        # [mode, fact, used, which occurrence of the fact it is]: the proof term names the one used
        occ: list[list] = []
        for t, n in ctx.lin.items():
            occ.extend([LIN, t, False, k] for k in range(n))
        for t, n in ctx.aff.items():
            occ.extend([AFF, t, False, k] for k in range(n))
        pers = list(ctx.pers)
        for m, t in ctx.open:
            if m == PERS:
                pers.append(t)
            else:
                occ.append([m, t, False, sum(1 for o in occ if o[1] is t)])
        serve = {LIN: (LIN, AFF), AFF: (AFF,), PERS: ()}

        chosen: list = []

        def go(k: int) -> Iterator[list]:
            if k == len(items):
                if (not any(o[0] == LIN and not o[2] for o in occ) and not ctx.rules_linear_left()
                        and not ctx.inert_linear_left()):
                    yield list(chosen)
                return
            m, a = items[k]
            a = deref(a)
            if type(a) is not Root:
                return  # matching rules in the final context is not supported
            for o in occ:
                if o[2] or o[0] not in serve[m] or o[1].head is not a.head:
                    continue
                mark = self.u.mark()
                if self.u.unify(a, o[1]):
                    o[2] = True
                    chosen.append((o[0], o[1], o))
                    yield from go(k + 1)
                    chosen.pop()
                    o[2] = False
                self.u.undo(mark)
            for t in pers:
                if t.head is not a.head:
                    continue
                mark = self.u.mark()
                if self.u.unify(a, t):
                    chosen.append((PERS, t, None))
                    yield from go(k + 1)
                    chosen.pop()
                self.u.undo(mark)

        for used in go(0):
            yield [(m, t, o[3] if o is not None else 0) for m, t, o in used]


_SKEL_DEPTH = 3


def clause_skeleton(ty: Node):
    """The rigid part of a clause's head, for filtering clauses before instantiating them.

    A tuple with one entry per head argument: ``(head, args)`` for a constant or a
    literal (``args`` None below the depth limit), None for anything that could
    unify with more than one head (a bound variable, a lambda). None for a clause
    with an ``&`` (two heads)."""
    while True:
        tt = type(ty)
        if tt is Pi or tt is Imp:
            ty = ty.body
        elif tt is Root:
            return tuple(_skel(a, _SKEL_DEPTH) for a in ty.args)
        else:
            return None


def _skel(t: Node, depth: int):
    if type(t) is not Root or not isinstance(t.head, (Const, Lit)):
        return None
    if depth == 0 or not t.args:
        return (t.head, None)
    return (t.head, tuple(_skel(a, depth - 1) for a in t.args))


def _fits(skel: tuple, args: tuple) -> bool:
    for sk, a in zip(skel, args):
        if sk is None:
            continue
        a = deref(a)
        if type(a) is not Root:
            continue
        h = a.head
        if isinstance(h, (Const, Lit)):
            if h is not sk[0]:
                return False
            sub = sk[1]
            if sub is not None and len(sub) == len(a.args) and not _fits(sub, a.args):
                return False
        elif isinstance(h, Param):
            return False   # a fresh name unifies with no constant
    return True


def premise_atoms(ty: Node) -> set:
    """Families of the atomic types a clause mentions (its premises, at any depth)."""
    out: set = set()
    stack = [ty]
    while stack:
        t = stack.pop()
        if type(t) is Root:
            if isinstance(t.head, Const):
                out.add(t.head)
        elif isinstance(t, TypeNode):
            stack.extend(v for v in (getattr(t, f) for f in type(t).fields) if isinstance(v, Node))
    return out


def head_families(ty: Node) -> set:
    """Families a hypothesis can conclude (both halves of an ``&``)."""
    out: set = set()
    stack = [ty]
    while stack:
        t = stack.pop()
        tt = type(t)
        if tt is Pi or tt is Imp:
            stack.append(t.body)
        elif tt is With:
            stack.extend((t.left, t.right))
        elif tt is Root:
            out.add(t.head)
    return out


def context_hyps(ctx: Context, fams, mode: str, consumed=()) -> list:
    """The facts of the families ``fams`` as hypotheses for proving a forward rule's premise of
    mode ``mode``: linear, affine and persistent facts for a linear premise, affine and
    persistent ones for an affine premise, persistent ones for a persistent premise (as Celf
    does); the copies ``consumed`` (what the match took so far) are left out. An open fact
    (one holding logic variables) is a hypothesis like any other."""
    used: dict = {}
    for m, t in consumed:
        used[m, t] = used.get((m, t), 0) + 1
    out: list = []
    lin, aff, pers = ctx.lin, ctx.aff, ctx.pers
    for f in fams:
        bag = ctx.index.get(f)
        if bag:
            for t in bag.items:
                if mode == LIN:
                    out.extend(Hyp(t, LIN) for _ in range(lin.get(t, 0) - used.get((LIN, t), 0)))
                if mode != PERS:
                    out.extend(Hyp(t, AFF) for _ in range(aff.get(t, 0) - used.get((AFF, t), 0)))
                if t in pers:
                    out.append(Hyp(t, PERS))
    if ctx.open:
        fams = set(fams)
        for m, t in ctx.open:
            if t.head not in fams or (m == LIN and mode != LIN) or (m == AFF and mode == PERS):
                continue
            if m != PERS and used.get((m, t)):
                used[m, t] -= 1
                continue
            out.append(Hyp(t, m))
    return out


def prove_consuming(bw: Backward, ctx: Context, goal: Node, mode: str, consumed=()) -> Iterator[list]:
    """Prove ``goal`` (a premise of mode ``mode`` of a forward rule, its slots already logic
    variables) by proof search over the context's facts of the families it may need and the
    signature's clauses; committed to the first proof, whose bindings are kept (the caller
    undoes them through ``bw.u``). Yields once, the facts the proof consumed ``[(mode, fact)]``."""
    fam = goal.head if type(goal) is Root else None
    fams = bw.program.premise_families(fam) if fam is not None else tuple(ctx.index) + tuple(
        {t.head for _m, t in ctx.open})
    hyps = context_hyps(ctx, fams, mode, consumed)
    saved = bw.hyps
    bw.hyps = hyps
    hmark = len(bw.htrail)
    used = None
    proofs = bw.solve(goal)
    try:
        for _ in proofs:
            used = [(h.mode, h.ty) for h in hyps if h.used and h.mode != PERS]
            break
    finally:
        # keep the unifier's bindings (the first proof is committed); release the hypotheses
        proofs.close()
        bw.hyps = saved
        while len(bw.htrail) > hmark:
            bw.htrail.pop().used = False
    if used is not None:
        yield used


def prove_premise(bw: Backward, ctx: Context, tpl, p, b: list, trail: list, consumed=()) -> Iterator:
    """Solve a forward rule's backward premise: slots unbound so far become logic variables,
    the context's facts serve as hypotheses (persistent ones for a persistent premise; a
    linear premise may also consume linear and affine facts, an affine one affine facts);
    committed to the first proof. Yields once per proof (the facts it consumed, or None).

    The proof search is finished (and undone) before the bindings are handed over, so a
    premise's answer is a function of the premise, the values of its slots and the
    persistent facts of its family: outside other proof searches it is memoised per
    program under that key (the explorer proves the same premises in state after state),
    unless the search ran a monad or assumed hypotheses (it then made fresh names)."""
    bi = BUILTINS.get(p.family)
    if bi is not None:
        yield from _builtin_premise(bi, tpl, p, b, trail)
        return
    if p.mode != PERS or ctx.open:
        yield from _prove_with_context(bw, ctx, p, b, trail, consumed)
        return
    pat = p.pattern
    memo = key = None
    if bw.depth == 0 and type(pat) is Root and type(pat.head) is not Meta:
        memo = _premise_memo(bw.program)
    if memo is not None:
        key = premise_key(bw, ctx, p, b)
        hit = memo.get(key)
        if hit is not None:
            found, used_ids = hit
            # the ids the logic variables below and the search would have taken
            _skip_param_ids(b.count(None) + used_ids)
            if found is not None:
                for i, v in found:
                    b[i] = v
                    trail.append(i)
                yield
            return
    evs: dict[int, Root] = {}
    vals = list(b)
    for i, v in enumerate(vals):
        if v is None:
            x = Root(EVar(f"s{i}"), ())
            evs[i] = x
            vals[i] = x
    goal = inst(pat, vals)
    fam = goal.head if type(goal) is Root else None
    added = []
    if fam is not None:
        # the persistent facts a proof of the premise may use: those of its family and of
        # every family its clauses' premises may need (decided once per program)
        for f in bw.program.premise_families(fam):
            bag = ctx.index.get(f)
            if bag:
                for t in bag.items:
                    if t in ctx.pers:
                        added.append(Hyp(t, PERS))
    found = None
    names, runs = bw._names, len(bw.monad_runs)
    first_id = _next_param_id() if memo is not None else None
    saved = bw.hyps
    bw.hyps = added
    mark, hmark = bw.u.mark(), len(bw.htrail)
    proofs = bw.solve(goal)
    try:
        for _ in proofs:
            found = []
            for i, x in evs.items():
                v = zonk(x)
                if v is not x and not v.evars:
                    found.append((i, v))
            break
    finally:
        proofs.close()
        bw._undo(mark, hmark)
        bw.hyps = saved
    if first_id is not None and bw._names == names and len(bw.monad_runs) == runs:
        if len(memo) >= _PREMISE_MEMO_MAX:
            memo.clear()
        memo[key] = (found, _next_param_id() - first_id)
    if found is not None:
        for i, v in found:
            b[i] = v
            trail.append(i)
        yield


def _prove_with_context(bw: Backward, ctx: Context, p, b: list, trail: list, consumed) -> Iterator[list]:
    """A premise proved with the context's facts as hypotheses (a linear or affine premise,
    or any premise when the context holds open facts): the ground bindings it finds are
    handed to the slots, and the facts it consumed to the caller."""
    evs: dict[int, Root] = {}
    vals = list(b)
    for i, v in enumerate(vals):
        if v is None:
            x = Root(EVar(f"s{i}"), ())
            evs[i] = x
            vals[i] = x
    goal = inst(p.pattern, vals)
    mark = bw.u.mark()
    found = None
    used = None
    for used in prove_consuming(bw, ctx, goal, p.mode, consumed):
        found = []
        for i, x in evs.items():
            v = zonk(x)
            if v is not x and not v.evars:
                found.append((i, v))
        break
    bw.u.undo(mark)
    if found is not None:
        for i, v in found:
            b[i] = v
            trail.append(i)
        yield used


#: entries kept per program before the premise memo starts afresh (bounds its memory)
_PREMISE_MEMO_MAX = 200_000


#: the id the next fresh name or logic variable will get; skip ids (see terms.py). A memoised
#: answer skips the ids the search would have used, so the fresh names made afterwards (and
#: printed in traces) are numbered as without the memo.
_next_param_id = terms.next_param_id
_skip_param_ids = terms.skip_param_ids


def premise_key(bw: Backward, ctx: Context, p, b: list) -> tuple:
    """The premise memo's key of a persistent premise (an atom of a constant family): the
    premise, the values of its slots and the persistent facts of the families its proof may
    read (see :func:`prove_premise`)."""
    got = p.__dict__.get("_memo_plan")
    if got is None or got[0] is not bw.program:
        pat = p.pattern
        got = p._memo_plan = (bw.program, _slots_of(pat), bw.program.premise_families(pat.head))
    _prog, slots, fams = got
    pers = ctx.pers
    if not pers:
        facts = ()   # (the common case: a context of linear facts only)
    elif len(fams) == 1:
        bag = ctx.index.get(fams[0])
        facts = tuple([t for t in bag.items if t in pers]) if bag else ()
    else:
        acc = []
        for f in fams:
            bag = ctx.index.get(f)
            if bag:
                acc.extend([t for t in bag.items if t in pers])
        facts = tuple(acc)
    return p, tuple([b[i] for i in slots]), facts


def memo_answer(bw: Backward, ctx: Context, p, b: list):
    """:func:`prove_premise`'s memoised answer for a premise, without a generator: ``(found,
    ids)`` (``found`` the slot values a proof gives, None when there is no proof; ``ids``
    the fresh ids the search took), or None when the premise is not memoised or not yet
    answered (the caller then runs :func:`prove_premise`). The matcher's hot path (the
    explorer proves the same premises in state after state)."""
    if p.mode != PERS or ctx.open or bw.depth:
        return None
    pat = p.pattern
    if type(pat) is not Root or type(pat.head) is Meta or p.family in BUILTINS:
        return None
    memo = bw.program.__dict__.get("_premise_memo") if hasattr(bw.program, "__dict__") else None
    if not memo:
        return None
    return memo.get(premise_key(bw, ctx, p, b))


def _premise_memo(program) -> Optional[dict]:
    d = getattr(program, "__dict__", None)
    if d is None:
        return None
    memo = d.get("_premise_memo")
    if memo is None:
        memo = d["_premise_memo"] = {}
    return memo


def _slots_of(pattern: Node) -> tuple:
    """The slot indices a premise's pattern mentions, in a fixed order."""
    out: dict = {}
    stack = [pattern]
    while stack:
        x = stack.pop()
        if not x.metas:
            continue
        tx = type(x)
        if tx is Root:
            if type(x.head) is Meta:
                out[x.head.index] = None
            stack.extend(x.args)
        elif tx is Lam:
            stack.append(x.body)
        else:
            stack.extend(v for v in (getattr(x, f) for f in tx.fields) if isinstance(v, Node))
    return tuple(sorted(out))


def _builtin_premise(bi, tpl, p, b: list, trail: list) -> Iterator[None]:
    """A built-in premise of a forward rule, evaluated directly on the slot values: the
    inputs must be bound; the output is matched against the computed value (binding
    its slot, or comparing it with the value the slot already has)."""
    args = p.pattern.args
    vals = []
    terms = []
    for i in range(bi.n_inputs):
        a = args[i]
        if a.metas:
            try:
                a = inst(a, b)
            except KeyError:
                raise BuiltinError(f"built-in '{bi.name}' in rule '{tpl.name}': its inputs must be ground "
                                   f"(argument {i + 1} is not determined when the premise is tried); "
                                   f"mode {bi.name} {bi.mode}") from None
        terms.append(a)
        h = a.head if type(a) is Root else None
        if type(h) is Lit and h.family is bi.arg_types[i]:
            vals.append(h.value)
            continue
        try:  # not a literal of the right type: let the common check say why
            input_values(bi, tuple(terms) + args[i + 1:])
        except BuiltinError as e:
            raise BuiltinError(f"{e.message} (in rule '{tpl.name}')") from None
        raise AssertionError("input_values accepted a non-literal")
    r = bi.fn(*vals)
    if not bi.output:
        if r:
            yield
        return
    if r is None:
        return
    res = num_term(r) if bi.arg_types[-1] is NUMBER else string_term(r)
    mark = len(trail)
    if match(args[-1], res, b, trail):
        yield
    while len(trail) > mark:
        b[trail.pop()] = None


class _Names:
    """Proof variables for the facts and rules of one monad, and its ``let`` bindings."""

    def __init__(self, bw: Backward):
        self.bw = bw
        self.facts: dict = {}  # (mode, fact) -> list of names (a multiset of occurrences)
        self.rules: dict[int, str] = {}  # context rule uid -> name
        self.lets: list[tuple[list[str], str, list[str]]] = []

    def bind(self, x, name: str) -> None:
        if hasattr(x, "uid"):
            self.rules[x.uid] = name
        else:
            self.facts.setdefault(x, []).append(name)

    def _take(self, mode: str, t) -> str:
        q = self.facts.get(t)
        if not q:
            return "_"
        return q[0] if mode == PERS else q.pop(0)

    def name_at(self, mode: str, t, k: int) -> str:
        """The name of occurrence ``k`` of fact ``t`` (two equal facts are told apart by their names)."""
        q = self.facts.get(t)
        if not q:
            return "_"
        return q[0] if mode == PERS else q[k] if k < len(q) else q[-1]

    def _premise_args(self, step, ctx) -> Optional[list]:
        """The arguments of a step whose rule has premises proved by backward chaining, in the
        order the premises are written: a context premise by the name of the fact it used, a
        proved one by its proof (found again over the facts the step consumed for it and the
        persistent facts, named), as Celf prints them: ``r (b_from_a X1)``."""
        tpl = step.template
        b = list(step.bindings)
        left = list(step.consumed)
        marks = {LIN: "", AFF: "@", PERS: "!"}
        out: list = []
        backs = []
        for p in tpl.premises:
            if p.backward:
                backs.append(p)
                out.append(p)
                continue
            try:
                want = zonk(inst(p.pattern, b))
            except KeyError:
                return None
            for k, (m, t) in enumerate(left):
                if t is want or zonk(t) is want:
                    out.append(marks[p.mode] + self._take(m, t))
                    del left[k]
                    break
            else:
                return None
        for i, p in enumerate(out):
            if type(p) is str:
                continue
            bi = BUILTINS.get(p.family)
            if bi is not None:
                out[i] = "!" + bi.name
                continue
            try:
                goal = zonk(inst(p.pattern, b))
            except KeyError:
                return None
            hyps = []
            for m, t in left:
                hyps.append(Hyp(t, m, name=(self.facts.get(t) or ["_"])[0]))
            fam = goal.head if type(goal) is Root else None
            for f in (self.bw.program.premise_families(fam) if fam is not None else ()):
                bag = ctx.index.get(f)
                for t in (bag.items if bag else ()):
                    if t in ctx.pers:
                        hyps.append(Hyp(t, PERS, name=(self.facts.get(t) or ["_"])[0]))
            bw = Backward(self.bw.program, seed=self.bw.seed)
            bw.hyps = hyps
            pf = None
            proofs = bw.solve(goal)
            try:
                for pf in proofs:
                    break
            finally:
                proofs.close()
            if pf is None:
                return None
            for h in hyps:
                if h.used and h.mode != PERS:
                    self._take(h.mode, h.ty)
            s = show_proof(pf)
            if pf[0] == "lam" or (pf[0] == "app" and pf[2]):
                s = f"({s})"
            out[i] = marks[p.mode] + s
        return out

    def step(self, step, ctx) -> None:
        args = None
        if step.template is not None and step.template.backward_premises:
            args = self._premise_args(step, ctx)
        if args is None:   # (Celf marks a persistent argument '!', an affine one '@')
            marks = {LIN: "", AFF: "@", PERS: "!"}
            args = [marks[m] + self._take(m, t) for m, t in step.consumed]
        tpl = step.template
        if tpl is not None and tpl.pi_slots:   # the explicit Pis' arguments, where they are declared
            skip = 0 if step.ctx_rule is not None else self.bw.program.implicit.get(Const(step.rule), 0)
            for k, slot in reversed(tpl.pi_slots[skip:]):
                b = step.bindings[slot] if slot < len(step.bindings) else None
                shown = "_" if b is None else self.bw.program.show(zonk(b)).replace("#", "_")
                args.insert(k, "!" + (f"({shown})" if " " in shown else shown))
        head = self.rules.get(step.ctx_rule, "_") if step.ctx_rule is not None else step.rule
        pattern = []
        for act in step.template.head:
            if act[0] == "fresh":
                b = step.bindings[act[1]]
                pattern.append("!" + self.bw.program.show(b).replace("#", "_"))
        for mode, x in step.produced:
            n = self.bw.fresh_name()
            self.bind(x, n)
            pattern.append({LIN: "", AFF: "@", PERS: "!"}[mode] + n)
        self.lets.append((pattern, head, args))


def show_proof(p) -> str:
    """Render a proof term in Celf's style: ``\\X1. {let {[d1, X2]} = r X1 in X2}``."""
    kind = p[0]
    if kind == "lam":
        return f"{p[1]} {show_proof(p[2])}"
    if kind == "top":
        return "<>"
    if kind == "term":   # an explicit Pi's argument, an index term
        return p[1]
    if kind == "pair":
        return f"<{show_proof(p[1])}, {show_proof(p[2])}>"
    if kind == "app":
        parts = [p[1]]
        for mark, a in p[2]:
            s = show_proof(a)
            if a[0] == "term":
                s = f"({s})" if " " in s and not s.startswith("(") else s
            elif a[0] != "app" or a[2]:
                s = f"({s})" if a[0] in ("app", "lam") and (a[0] == "lam" or a[2]) else s
            parts.append(mark + s)
        return " ".join(parts)
    if kind == "monad":
        if p[1] is None:
            return "{...}"
        out = []
        for pattern, head, args in p[1]:
            pat = "1" if not pattern else pattern[0] if len(pattern) == 1 else "[" + ", ".join(pattern) + "]"
            out.append(f"let {{{pat}}} = {' '.join([head] + args)} in ")
        final = "1" if not p[2] else p[2][0] if len(p[2]) == 1 else "[" + ", ".join(p[2]) + "]"
        return "{" + "".join(out) + final + "}"
    return repr(p)
