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

from .context import Context
from .forward import Run, load_positive
from .rules import AFF, LIN, PERS
from .terms import (Aff, Bang, EVar, Exists, Imp, Monad, Node, One, Param, Pi, Root, Tensor, Top, With, deref,
                    param_term, subst1, zonk)
from .unify import Unifier


@dataclass(eq=False)
class Hyp:
    ty: Node
    mode: str
    used: bool = False


class SearchLimit(Exception):
    """Raised when the proof search exceeds its depth bound."""


class Backward:
    """Proof search over a program's clauses and a context of hypotheses."""

    def __init__(self, program, seed: Optional[int] = 0, monad_depth: Optional[int] = None,
                 max_depth: int = 100_000, fair: bool = False):
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

    # -------------------------------------------------------------- helpers
    def _use(self, h: Hyp) -> None:
        h.used = True
        self.htrail.append(h)

    def _undo(self, mark: tuple, hmark: int) -> None:
        self.u.undo(mark)
        while len(self.htrail) > hmark:
            self.htrail.pop().used = False

    def _push(self, ty: Node, mode: str) -> list[Hyp]:
        """Assume a (possibly positive) type; returns the hypotheses added."""
        added: list[Hyp] = []

        def go(t: Node, m: str) -> None:
            tt = type(t)
            if tt is Tensor:
                go(t.left, m)
                go(t.right, m)
            elif tt is One:
                pass
            elif tt is Exists:
                p = Param(t.hint)
                h = Hyp(t.dom, PERS)
                added.append(h)
                go(subst1(t.body, param_term(p)), m)
            elif tt is Bang:
                go(t.body, PERS)
            elif tt is Aff:
                go(t.body, AFF if m != PERS else PERS)
            else:
                h = Hyp(t, m)
                added.append(h)

        go(ty, mode)
        self.hyps.extend(added)
        return added

    def _pop(self, added: list[Hyp]) -> None:
        del self.hyps[len(self.hyps) - len(added):]

    # -------------------------------------------------------------- goals
    def solve(self, goal: Node, floor: int = 0, aff_ok: bool = True) -> Iterator[None]:
        """Solve ``goal``; hypotheses below index ``floor`` may only be used persistently
        (or affinely, when ``aff_ok``)."""
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
            try:
                yield from self.solve(subst1(goal.body, param_term(p)), floor, aff_ok)
            finally:
                self._pop(added)
        elif tg is Imp:
            added = self._push(goal.dom, goal.mode)
            try:
                for _ in self.solve(goal.body, floor, aff_ok):
                    if all(h.used or h.mode != LIN for h in added):
                        yield
            finally:
                self._pop(added)
        elif tg is With:
            yield from self._with(goal, floor, aff_ok)
        elif tg is Top:
            mark, hmark = self.u.mark(), len(self.htrail)
            for i in range(floor, len(self.hyps)):
                h = self.hyps[i]
                if not h.used and h.mode != PERS:
                    self._use(h)
            yield
            self._undo(mark, hmark)
        elif tg is Monad:
            yield from self._monad(goal.body, floor)
        else:
            raise AssertionError(f"unexpected goal {goal!r}")

    def _with(self, goal: With, floor: int, aff_ok: bool) -> Iterator[None]:
        mark, hmark = self.u.mark(), len(self.htrail)
        for _ in self.solve(goal.left, floor, aff_ok):
            left_used = frozenset(id(h) for h in self.htrail[hmark:])
            # redo the right half from the same resources
            saved = self.htrail[hmark:]
            for h in saved:
                h.used = False
            mark2 = len(self.htrail)
            for _ in self.solve(goal.right, floor, aff_ok):
                right_used = frozenset(id(h) for h in self.htrail[mark2:])
                if right_used == left_used:
                    yield
            while len(self.htrail) > mark2:
                self.htrail.pop().used = False
            for h in saved:
                h.used = True
        self._undo(mark, hmark)

    # -------------------------------------------------------------- atoms
    def _atom(self, goal: Root, floor: int, aff_ok: bool) -> Iterator[None]:
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
            yield from self._clause(h.ty, goal, floor, aff_ok)
            self._undo(mark, hmark)
        for _name, ty in self.program.clauses.get(fam, ()):
            mark, hmark = self.u.mark(), len(self.htrail)
            yield from self._clause(ty, goal, floor, aff_ok)
            self._undo(mark, hmark)

    def _clause(self, ty: Node, goal: Root, floor: int, aff_ok: bool) -> Iterator[None]:
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
                    yield from self._clause_rest(half, prems, goal, floor, aff_ok)
                return
            else:
                break
        yield from self._clause_rest(ty, prems, goal, floor, aff_ok)

    def _clause_rest(self, ty: Node, prems: list, goal: Root, floor: int, aff_ok: bool) -> Iterator[None]:
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
                    yield from self._clause_rest(half, prems, goal, floor, aff_ok)
                return
            else:
                break
        if type(ty) is not Root:
            return
        mark = self.u.mark()
        if not self.u.unify(ty, goal):
            self.u.undo(mark)
            return
        yield from self._premises(prems, len(prems) - 1, floor, aff_ok)
        self.u.undo(mark)

    def _premises(self, prems, k: int, floor: int, aff_ok: bool) -> Iterator[None]:
        if k < 0:
            yield
            return
        mode, a = prems[k]
        if mode == PERS:
            sub = self.solve(a, len(self.hyps), False)
        elif mode == AFF:
            sub = self.solve(a, len(self.hyps), True)
        else:
            sub = self.solve(a, floor, aff_ok)
        for _ in sub:
            yield from self._premises(prems, k - 1, floor, aff_ok)

    # -------------------------------------------------------------- the monad
    def _monad(self, s: Node, floor: int) -> Iterator[None]:
        mark, hmark = self.u.mark(), len(self.htrail)
        ctx = Context()
        ctx.implicit = getattr(self.program, "implicit", None)
        for i, h in enumerate(self.hyps):
            if h.used:
                continue
            if h.mode != PERS and i < floor:
                continue
            ty = zonk(h.ty)
            if ty.evars:
                # a hypothesis mentioning unsolved logic variables cannot enter the monad
                continue
            load_positive(ctx, ty if h.mode == LIN else (Bang(ty) if h.mode == PERS else Aff(ty)),
                          self.program.compile_context_rule)
            if h.mode != PERS:
                self._use(h)
        run = Run(self.program.templates, ctx, seed=self.seed, fair=self.fair,
                  prover=self.program.prover(self))
        quiescent = run.run(self.monad_depth)
        self.monad_runs.append(run)
        if self.on_monad is not None:
            self.on_monad(run)
        del quiescent
        yield from self._match_pos(s, ctx)
        self._undo(mark, hmark)

    def _match_pos(self, s: Node, ctx: Context) -> Iterator[None]:
        """Match the positive type ``s`` against the final context; linear leftovers fail."""
        items: list[tuple[str, Node]] = []

        def flatten(t: Node, m: str) -> None:
            tt = type(t)
            if tt is Tensor:
                flatten(t.left, m)
                flatten(t.right, m)
            elif tt is One:
                pass
            elif tt is Exists:
                x = EVar(t.hint, t.dom)
                flatten(subst1(t.body, Root(x, ())), m)
            elif tt is Bang:
                flatten(t.body, PERS)
            elif tt is Aff:
                flatten(t.body, AFF)
            else:
                items.append((m, t))

        flatten(s, LIN)
        # Each hypothesis occurrence is a separate candidate (as in Celf): two identical
        # linear facts matched by two goal atoms give two solutions.
        occ: list[list] = []  # [mode, fact, used]
        for t, n in ctx.lin.items():
            occ.extend([LIN, t, False] for _ in range(n))
        for t, n in ctx.aff.items():
            occ.extend([AFF, t, False] for _ in range(n))
        pers = list(ctx.pers)
        serve = {LIN: (LIN, AFF), AFF: (AFF,), PERS: ()}

        def go(k: int) -> Iterator[None]:
            if k == len(items):
                if (not any(o[0] == LIN and not o[2] for o in occ) and not ctx.rules_linear_left()
                        and not ctx.inert_linear_left()):
                    yield
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
                    yield from go(k + 1)
                    o[2] = False
                self.u.undo(mark)
            for t in pers:
                if t.head is not a.head:
                    continue
                mark = self.u.mark()
                if self.u.unify(a, t):
                    yield from go(k + 1)
                self.u.undo(mark)

        yield from go(0)


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


def prove_premise(bw: Backward, ctx: Context, tpl, p, b: list, trail: list) -> Iterator[None]:
    """Solve a forward rule's backward premise: slots unbound so far become logic variables,
    persistent facts of the context serve as hypotheses; committed to the first proof."""
    from .forward import inst
    evs: dict[int, Root] = {}
    vals = list(b)
    for i, v in enumerate(vals):
        if v is None:
            x = Root(EVar(f"s{i}"), ())
            evs[i] = x
            vals[i] = x
    goal = inst(p.pattern, vals)
    fam = goal.head if type(goal) is Root else None
    added = []
    if fam is not None:
        bag = ctx.index.get(fam)
        if bag:
            for t in bag.items:
                if t in ctx.pers:
                    added.append(Hyp(t, PERS))
    saved = bw.hyps
    bw.hyps = added
    mark, hmark = bw.u.mark(), len(bw.htrail)
    try:
        for _ in bw.solve(goal):
            ok = True
            for i, x in evs.items():
                v = zonk(x)
                if v is not x and not v.evars:
                    b[i] = v
                    trail.append(i)
            if ok:
                yield
            return
    finally:
        bw._undo(mark, hmark)
        bw.hyps = saved
