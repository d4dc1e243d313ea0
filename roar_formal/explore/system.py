"""Transition systems the explorer searches: CLF programs seen through the engine.

:class:`TransitionSystem` is how the explorer meets a model: it knows nothing
of ROAR or of the robot. :class:`ClfSystem` wraps a :class:`~roar_formal.clf.program.Program` and a
start context; its successors are exactly the engine's enumerated steps
(``Program.steps`` / ``Program.successor``), its states are compared up to
renaming of fresh names (``canonical_key``). Each step carries a fairness
group (which process moved) and a progress flag, both set by the property
file's options.
"""

from __future__ import annotations

import fnmatch
from dataclasses import dataclass, field
from typing import Any, Callable, Hashable, Optional, Protocol, Sequence, runtime_checkable

from ..clf.context import Context, FrozenContext, replay
from ..clf.forward import Step, build_planned, inst, plan_successor
from ..clf.program import Program
from ..clf.query import show_context
from ..clf.rules import PERS
from ..clf.state import canonical_key


@dataclass
class Options:
    """How steps are classified for liveness properties."""

    progress_rules: tuple[str, ...] = ()  # rule names (globs) whose steps are progress events
    fairness: str = "first-argument"  # 'first-argument' | 'rule' | 'none'
    canonical: bool = True  # identify states up to renaming of fresh names
    reduction: bool = False  # partial-order reduction (stubborn sets, see reduction.py)
    observers: tuple = ()  # templates a safety property reads: every reduced set keeps them (reduction.py)
    visible_families: frozenset = frozenset()  # families a property computed in Python reads


@dataclass
class Successor:
    label: str
    group: str
    progress: bool
    state: Context
    step: object = field(repr=False, default=None)


@runtime_checkable
class TransitionSystem(Protocol):
    """What the explorer (search.py, properties.py) needs of a model.

    States are opaque to it. ``key`` identifies a state (equal keys, one visited state);
    each :class:`Successor` names its step, its fairness group (who moved) and whether it is
    progress; ``reduced_successors`` is a partial-order-reduced expansion: (the chosen
    successors, a function giving the others or None when none were left out, the others'
    fairness groups); ``describe``/``describe_step`` say a state
    and a step in facts and rule names, for counterexamples and traces. A front end (the ROAR
    compiler's :class:`~roar_formal.roar.explore.RoarSystem`, the robot-backed
    :class:`~roar_formal.robot.explore.RobotSystem`) supplies one; events in its own terms are
    its business, not the explorer's."""

    def initial(self) -> Any: ...

    def key(self, state: Any) -> Hashable: ...

    def successors(self, state: Any) -> list["Successor"]: ...

    def reduced_successors(self, state: Any) \
            -> tuple[list["Successor"], Optional[Callable[[], list["Successor"]]], Sequence[str]]: ...

    def describe(self, state: Any) -> list[str]: ...

    def describe_step(self, step: Any) -> dict: ...


class ClfSystem:
    """A CLF program and a start context, stepped by the engine's enumeration driver."""

    def __init__(self, program: Program, start: Context, options: Optional[Options] = None):
        self.program = program
        self.start = start
        self.options = options or Options()
        self.reducer = None

    def initial(self) -> Context:
        return self.start

    def key(self, state: Context):
        return canonical_key(state) if self.options.canonical else _plain_key(state)

    def successors(self, state: Context) -> list[Successor]:
        return [self._successor(state, choice) for choice in self.program.steps(state)]

    def lazy_successors(self, state: Context) -> Optional[list]:
        """The successors with their keys, each state built only when asked for: ``[(successor,
        key, view)]`` where a successor whose ``state`` is None is built by
        :meth:`build_successor` from its ``view``; None when this system cannot (the explorer
        then calls :meth:`successors`). The same successors, keys and fresh names as
        ``successors`` gives, in the same order: the explorer builds only the new states (most
        successors are states visited already, whose matching indexes would be thrown away)."""
        planned = self.planned_successors(state)
        if planned is None:
            return None
        return [(succ, self.key(succ.state), None) if view is None else (succ, canonical_key(view), view)
                for succ, view in planned]

    def planned_successors(self, state: Context) -> Optional[list]:
        """The successors as :meth:`lazy_successors` gives them, without their keys: ``[(successor,
        view)]``, a successor whose ``state`` is None having its facts in ``view`` (a process that
        only sends the successors on, as the distributed search's, needs no key and no built
        state); None when this system cannot."""
        if not self._lazy_ok():
            return None
        out = []
        for choice in self.program.steps(state):
            planned = plan_successor(state, choice)
            if planned is None:
                out.append((self._successor(state, choice), None))
                continue
            view, step = planned
            out.append((Successor(choice.rule, self._group_of(state, choice), self._progress(choice.rule), None, step),
                        view))
        return out

    def build_successor(self, state: Context, succ: Successor, view) -> Context:
        """The state of a successor :meth:`lazy_successors` left unbuilt (its key kept on it)."""
        nxt = build_planned(state, succ.step).in_order()
        nxt._canon = (nxt.inert, len(nxt.inert), view._canon[2])
        return nxt

    def _lazy_ok(self) -> bool:
        """May successors be built lazily? Only where the steps, keys and successors are this
        class's own (a subclass that changes them opts in itself) and keys are canonical."""
        return self.options.canonical and unchanged_system(self, ClfSystem)

    frozen_type = FrozenContext

    def freeze(self, state: Context) -> FrozenContext:
        """A visited state as the explorer keeps it (without matching indexes)."""
        return FrozenContext(state)

    def thaw(self, frozen: FrozenContext) -> Context:
        return frozen.thaw()

    def rebuild(self, base, steps: list) -> Context:
        """The state the successors built by :meth:`build_successor` along ``steps`` reach from
        ``base`` (a state, or one frozen), as :meth:`thaw` gives it had it been frozen."""
        return replay(base, steps)

    def pack_step(self, step):
        """A step as the explorer keeps it (one per transition): an engine :class:`Step` as one
        flat tuple whose (mode, fact) pairs are shared with every other step that has them (the
        facts recur from transition to transition); any other step as it is. The bindings are
        not kept: what reads a transition's step (describing it, the ROAR narration and
        events, replay, reduction) reads its rule, template and facts, never its slot values
        (a step read back unpacked has none, as a step shipped by the distributed search)."""
        if type(step) is not Step:
            return step
        consumed = step.consumed
        pairs = _pairs
        if len(pairs) >= _PAIRS_MAX or len(_packed) >= _PAIRS_MAX:
            pairs.clear()
            _packed.clear()
        out = [step.rule, step.template, step.ctx_rule, len(consumed)]
        for pr in consumed:
            out.append(pairs.setdefault(pr, pr) if type(pr) is tuple else pr)
        for pr in step.produced:
            out.append(pairs.setdefault(pr, pr) if type(pr) is tuple else pr)
        packed = PackedStep(out)
        # one step taken from several states (interleavings of independent steps: the same
        # rule on the same facts) is kept once
        return _packed.setdefault(packed, packed)

    def unpack_step(self, packed):
        """The step ``pack_step`` packed (a new :class:`Step` equal to the one taken)."""
        if type(packed) is not PackedStep:
            return packed
        n = packed[3]
        return Step(packed[0], packed[1], (), list(packed[4:4 + n]), packed[2], list(packed[4 + n:]))

    def _successor(self, state: Context, choice) -> Successor:
        nxt, step = self.program.successor(state, choice)
        return Successor(choice.rule, self._group(choice), self._progress(choice.rule), nxt.in_order(), step)

    def reduced_successors(self, state: Context):
        """Successors by a stubborn subset of the enabled steps, a function giving the others
        (None when the subset is every enabled step), and the fairness groups of the others
        (weak fairness reads which groups a state enables, expanded or not). The explorer
        applies the cycle proviso; without ``options.reduction`` this is full expansion."""
        choices = self.program.steps(state)
        pick = None
        if self.options.reduction:
            if self.reducer is None:
                from .reduction import Reducer
                self.reducer = Reducer(self.program.templates, self.options.observers,
                                       self.options.visible_families,
                                       lambda c: self._progress(c.rule), self.program.premise_families)
            pick = self.reducer.choose(state, choices)
        if pick is None:
            return [self._successor(state, c) for c in choices], None, ()
        chosen = set(pick)
        rest = [c for i, c in enumerate(choices) if i not in chosen]
        return ([self._successor(state, choices[i]) for i in pick],
                lambda: [self._successor(state, c) for c in rest],
                [self._group_of(state, c) for c in rest])

    def _group_of(self, state: Context, choice) -> str:
        """The fairness group of an enabled step, without taking it."""
        return self._group(choice)

    def _progress(self, rule: str) -> bool:
        memo = self.__dict__.get("_progress_memo")
        if memo is None or memo[0] != self.options.progress_rules:
            memo = self._progress_memo = (self.options.progress_rules, {})
        got = memo[1].get(rule)
        if got is None:
            got = memo[1][rule] = is_progress(self.options, rule)
        return got

    def _group(self, choice) -> str:
        return step_group(self.program, self.options, choice)

    def describe(self, state: Context) -> list[str]:
        return show_context(state)

    def describe_step(self, step) -> dict:
        """What a step consumed and produced, printed (for counterexamples and traces)."""
        show = self.program.show
        consumed = [_mode(m) + show(t) for m, t in step.consumed if m != PERS]
        produced = []
        for m, x in step.produced:
            produced.append(_mode(m) + (show(x) if not hasattr(x, "source") else "(" + show(x.source) + ")"))
        return {"rule": step.rule, "consumed": consumed, "produced": produced}


def unchanged_system(system, cls) -> bool:
    """Are ``system``'s successors, keys and successor construction those of class ``cls`` (not
    overridden by a subclass of it or on the instance)?"""
    own = type(system)
    return not ({"successors", "key", "_successor"} & system.__dict__.keys()) and all(
        getattr(own, name) is getattr(cls, name) for name in ("successors", "key", "_successor"))


class PackedStep(tuple):
    """An engine step packed by :meth:`ClfSystem.pack_step`: (rule, template, context rule,
    number consumed, *consumed pairs, *produced pairs). A tuple of its own type, so
    that it is told from a step a system keeps as it is."""

    __slots__ = ()


#: (mode, fact) -> itself: the pairs packed steps share; a packed step -> itself (a transition
#: is often the step of another one, taken from another state). Both emptied when either
#: reaches _PAIRS_MAX.
_pairs: dict = {}
_packed: dict = {}
_PAIRS_MAX = 200_000


def _mode(m: str) -> str:
    return {"1": "", "@": "@", "!": "!"}[m]


def is_progress(options: Options, rule: str) -> bool:
    """Is a step of ``rule`` a progress event (the property file's globs)?"""
    return any(fnmatch.fnmatchcase(rule, pat) for pat in options.progress_rules)


def step_group(program: Program, options: Options, choice) -> str:
    """The fairness group (process) a step belongs to."""
    mode = options.fairness
    if mode == "none":
        return "*"
    if mode == "rule":
        return choice.rule
    # the process is named by the first argument of the fact the rule's first consuming premise
    # (in the order written) matched: the order the matcher found the facts in depends on
    # the state's index sizes, so it must not decide
    b = list(choice.bindings)
    for p in choice.template.premises:
        if p.backward or p.mode == PERS:
            continue
        try:
            fact = inst(p.pattern, b)
        except KeyError:
            continue
        if fact.args:
            return program.show(fact.args[0])
    for m, fact in choice.consumed:
        if m != PERS and fact.args:
            return program.show(fact.args[0])
    return choice.rule


def _plain_key(ctx: Context):
    from collections import Counter

    c: Counter = Counter()
    for mode, t, n in ctx.facts():
        c[(mode, t)] += n
    for r in ctx.rules.values():
        c[("rule", id(r.alts[0]) if r.alts else 0, r.env, r.mode)] += 1
    return frozenset(c.items())
