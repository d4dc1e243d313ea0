"""Stateful testing: a hypothesis ``RuleBasedStateMachine`` over a spec's executable model.

The machine holds one state of the compiled model (the model the explorer
checks: primitives answer with their declared outcomes). Its rules take one
engine step at a time:

* ``agent_step``: an agent (drawn among those with an enabled step) takes one
  of its enabled steps;
* ``primitive_outcome``: a pending call of the functional layer ends in one of
  its declared outcomes;
* ``quiescent``: nothing is enabled (the run is over); nothing changes.

After every step the model's invariants are checked: no deadlock (a quiescent
state where a request is not final or a recipe is live), no variable written
by two live where clauses (``exclusive_writes``), the sequential achievement
of ``make A; make B`` pairs (``sequential_achievement``), the ``never``
patterns, and the subclass's own ``@invariant()`` methods. Hypothesis shrinks a
failing run to a short sequence of steps; the failure message lists the ROAR
events of that run as ``roar-verify check`` prints a counterexample::

    class PickMachine(RoarMachine):
        spec = load_spec("pick.roar")
        request = "cell::lifted == true"

        @invariant()
        def the_gripper_is_free_when_all_is_done(self):
            if self.quiescent:
                assert self.value("gripper::busy") is False, "gripper busy at the end"

    TestPick = PickMachine.TestCase

Driving the reference robot in lockstep with the model is not done here
(docs/testing.md, "Not yet available").
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar, Optional, Sequence, Union

from hypothesis import settings as Settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, precondition, rule

from ..errors import Pos, RoarError
from .api import AgentSpec, load_spec

__all__ = ["RoarMachine"]


def _class_pos(cls: type) -> Pos:
    """Where a machine class is written: its ``never`` patterns are reported there."""
    import inspect
    try:
        return Pos(inspect.getsourcefile(cls) or "<python>", inspect.getsourcelines(cls)[1], 1)
    except (OSError, TypeError):
        return Pos(cls.__module__, 1, 1)


class _Setup:
    """What every run of one machine class shares: the compiled model, its start state, the checks."""

    def __init__(self, cls: type["RoarMachine"]):
        from ..clf.signature import ExecDirective
        from ..verify.check import make_never
        from ..explore.system import Options
        from ..roar.explore import PROGRESS_RULES, RoarSystem, sequential_pairs
        spec = cls.spec
        if spec is None or cls.request is None:
            raise RoarError(f"{cls.__name__}: set the class attributes 'spec' (an AgentSpec or a path) and "
                            f"'request'")
        if not isinstance(spec, AgentSpec):
            spec = load_spec(Path(spec))
        self.spec = spec
        self.model = spec.compile(cls.request, "abstract")
        program = self.model.program()
        start_d = next(d for d in program.sig.directives if isinstance(d, ExecDirective))
        self.start = program.start_context(start_d.start)
        pairs = sequential_pairs(self.model) if cls.sequential_achievement else []
        self.system = RoarSystem(self.model, self.start, Options(progress_rules=PROGRESS_RULES, fairness="agent"),
                                 pairs)
        never = list(cls.never)
        self.never = make_never(self.model.text, str(spec.path or spec.name),
                                [(p, _class_pos(cls)) for p in never]) if never else None
        self.outcome_rules = {}
        for fc, (owner, name) in self.model.functions.items():
            self.outcome_rules[f"outcome_{fc}_"] = f"{owner}::{name}" if owner else name
        # a state is a function of the choices that led to it: shrinking replays the same prefixes
        # again and again, so successors and enabled steps are cached by path
        self.states: dict[tuple, tuple] = {}
        self.moves: dict[tuple, list] = {}

    def outcome_of(self, rule_name: str) -> Optional[str]:
        """``f -> OUTCOME`` for a step that answers a pending call of f, else None."""
        for prefix, fn in self.outcome_rules.items():
            if rule_name.startswith(prefix):
                return f"{fn} -> {rule_name[len(prefix):]}"
        return None

    def enabled(self, path: tuple, state: Any) -> list:
        """The enabled steps of ``state``, reached by ``path``: (choice, agent, outcome label or None)."""
        out = self.moves.get(path)
        if out is None:
            out = [(c, self.system.agent_of(c, state), self.outcome_of(c.rule))
                   for c in self.system.program.steps(state)]
            self._remember(self.moves, path, out)
        return out

    def successor(self, path: tuple, state: Any, k: int) -> tuple:
        """(state, engine step, rule) after taking enabled step ``k`` of ``state``, reached by ``path``."""
        key = path + (k,)
        hit = self.states.get(key)
        if hit is None:
            succ = self.system._successor(state, self.enabled(path, state)[k][0])
            hit = (succ.state, succ.step, succ.label)
            self._remember(self.states, key, hit)
        return hit

    @staticmethod
    def _remember(cache: dict, key: tuple, value: Any) -> None:
        if len(cache) > 50_000:   # keep memory bounded: start over
            cache.clear()
        cache[key] = value


class RoarMachine(RuleBasedStateMachine):
    """Subclass with ``spec`` (an :class:`AgentSpec` or a path) and ``request``; ``TestCase`` is
    the test. Class attributes choose the built-in checks."""

    spec: ClassVar[Union[AgentSpec, str, Path, None]] = None
    request: ClassVar[Optional[str]] = None
    #: CLF patterns no reachable state may match (docs/checking.md, "Invariants")
    never: ClassVar[Sequence[str]] = ()
    #: a quiescent state must be final: every request success or failure, no recipe live
    check_deadlock: ClassVar[bool] = True
    exclusive_writes: ClassVar[bool] = True
    sequential_achievement: ClassVar[bool] = False
    #: "event": a rule takes one agent's steps up to its next ROAR event (the first step drawn,
    #: the next ones the agent's first enabled step); "step": a rule is one engine step
    granularity: ClassVar[str] = "event"
    #: the longest run tried (hypothesis' stateful_step_count)
    stateful_step_count: ClassVar[int] = 100

    _setups: ClassVar[dict] = {}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if cls.spec is not None:
            cls.TestCase.settings = Settings(cls.TestCase.settings, stateful_step_count=cls.stateful_step_count)

    def __init__(self) -> None:
        super().__init__()
        setup = RoarMachine._setups.get(type(self))
        if setup is None:
            setup = RoarMachine._setups[type(self)] = _Setup(type(self))
        self._s = setup
        self.state = setup.start
        self.events: list = []          # the ROAR events so far, with their step numbers
        self.rules: list[str] = []      # the rule of each step taken
        self._narrator = self._new_narrator()
        self._path: tuple = ()
        self._checked: Any = None
        if self.granularity not in ("event", "step"):
            raise RoarError(f"{type(self).__name__}.granularity must be 'event' or 'step', not {self.granularity!r}")

    # -------------------------------------------------------------- reading the state
    @property
    def model(self) -> Any:
        return self._s.model

    def _choices(self) -> list:
        return self._s.enabled(self._path, self.state)

    @property
    def quiescent(self) -> bool:
        """No step is enabled: the run is over."""
        return not self._choices()

    @property
    def final(self) -> bool:
        """Every request is final (success or failure) and no recipe is live."""
        from ..roar.explore import roar_final
        return roar_final(self.state)

    def value(self, var: str) -> object:
        """The current value of ``agent::var`` (numbers as int or Fraction)."""
        from ..clf.terms import Const
        from ..roar import vocabulary as V
        from ..roar.run import value_of
        agent, _, name = var.partition("::")
        cell = f"v_{agent}_{name}"
        if cell not in self.model.cells:
            raise RoarError(f"no variable {var!r} in {self._s.spec.name}")
        bag = self.state.index.get(Const(V.CONTAINS))
        for c in map(V.contains, bag.items if bag else ()):
            if c.cell.head.name == cell:
                return value_of(c.value)
        raise RoarError(f"{var} holds no value in this state")

    def format_run(self) -> str:
        """The run so far, one ROAR event a line (``step. agent text``)."""
        lines = [f"    {e.step:>3}. {e.agent:<12} {e.text}" for e in self.events]
        return "\n".join(lines) if lines else "    (no ROAR event yet)"

    def __repr__(self) -> str:
        return f"<{type(self).__name__} after {len(self.rules)} steps, {len(self.events)} ROAR events>"

    # -------------------------------------------------------------- stepping
    def _new_narrator(self) -> Any:
        """The run's narrator, as for a counterexample (roar.explore.path_events): R0 is the request."""
        from ..clf.terms import Const
        from ..roar import vocabulary as V
        from ..roar.run import Narrator
        nar = Narrator(self.model)
        bag = self._s.start.index.get(Const(V.RQ))
        for q in map(V.rq, bag.items if bag else ()):
            nar.label(q.request)
            nar.req_info["R0"] = (self.model.request_agent, self.model.csts[self.model.request_cst][1])
        return nar

    def _take(self, k: int) -> list:
        """Take enabled step ``k``; the ROAR events it made."""
        state, step, rule_name = self._s.successor(self._path, self.state, k)
        self._path += (k,)
        self.state = state
        self.rules.append(rule_name)
        made = self._narrator.events(len(self.rules), step)
        self.events.extend(made)
        return made

    def _move(self, k: int) -> None:
        """Step ``k``, then (granularity "event") the same agent's first enabled steps until one
        makes a ROAR event: silent bookkeeping is not a choice hypothesis has to make or shrink."""
        agent = self._choices()[k][1]
        made = self._take(k)
        for _ in range(200):
            if made or self.granularity != "event":
                return
            nxt = next((i for i, (_c, who, out) in enumerate(self._choices()) if who == agent and out is None), None)
            if nxt is None:
                return
            made = self._take(nxt)

    def _agent_moves(self) -> dict[str, list]:
        out: dict[str, list] = {}
        for i, (c, agent, outcome) in enumerate(self._choices()):
            if outcome is None:
                out.setdefault(agent, []).append((i, c.rule))
        return out

    def _outcomes(self) -> list:
        return [(i, outcome) for i, (_c, _a, outcome) in enumerate(self._choices()) if outcome is not None]

    @staticmethod
    def _labels(names: list[str]) -> list[str]:
        seen: dict[str, int] = {}
        out = []
        for n in names:
            seen[n] = seen.get(n, 0) + 1
            out.append(n if seen[n] == 1 else f"{n} #{seen[n]}")
        return out

    @precondition(lambda self: bool(self._agent_moves()))
    @rule(data=st.data())
    def agent_step(self, data: Any) -> None:
        moves = self._agent_moves()
        agent = data.draw(st.sampled_from(sorted(moves)), label="agent")
        labels = self._labels([r for _i, r in moves[agent]])
        pick = data.draw(st.sampled_from(labels), label="step")
        self._move(moves[agent][labels.index(pick)][0])

    @precondition(lambda self: bool(self._outcomes()))
    @rule(data=st.data())
    def primitive_outcome(self, data: Any) -> None:
        outs = self._outcomes()
        labels = self._labels([o for _i, o in outs])
        pick = data.draw(st.sampled_from(labels), label="outcome")
        self._move(outs[labels.index(pick)][0])

    @precondition(lambda self: self.quiescent)
    @rule()
    def quiescent_state(self) -> None:
        """The run is over; the checks have seen this state."""

    # -------------------------------------------------------------- checks
    def fail(self, what: str) -> None:
        """Fail the run: ``what`` and the ROAR events that led here."""
        exc = AssertionError(f"{what}\n{self._run_note()}")
        exc._roar_run_shown = True  # type: ignore[attr-defined]
        raise exc

    def _run_note(self) -> str:
        return f"  after {len(self.rules)} steps; the run, one ROAR event a line:\n{self.format_run()}"

    def check_invariants(self, *args: Any, **kwargs: Any) -> None:
        """Hypothesis' invariant checks; a failing ``assert`` of a subclass's invariant gets the run
        so far as a note, so every failure shows the ROAR events that led to it."""
        try:
            super().check_invariants(*args, **kwargs)
        except AssertionError as exc:
            if not getattr(exc, "_roar_run_shown", False):
                exc.add_note(self._run_note())
                exc._roar_run_shown = True  # type: ignore[attr-defined]
            raise

    @invariant()
    def roar_model_checks(self) -> None:
        if self._checked is self.state:
            return
        self._checked = self.state
        s = self._s
        if s.never is not None:
            why = s.never(self.state)
            if why:
                self.fail(f"invariant violated: {why}")
        if self.exclusive_writes:
            w = s.system.shared_write(self.state)
            if w:
                self.fail(f"exclusive-writes violated: {w[0]} is written by the where clauses of two live "
                          f"constraints: {' and '.join(w[1])}")
        if s.system.pairs:
            pair = s.system.violates_sequence(self.state)
            if pair:
                self.fail(f"sequential-achievement violated in {pair.where}: a command of the subtree of "
                          f"'{pair.b_text}' started before every command of the subtree of '{pair.a_text}' ended")
        if self.check_deadlock and self.quiescent and not self.final:
            self.fail("deadlock: nothing can move, but a request is not final or a recipe is still live")
