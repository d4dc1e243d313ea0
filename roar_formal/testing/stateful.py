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

With a ``scenario``, the machine drives the model and the reference robot in
lockstep (docs/robot.md): the spec runs with its primitives on the robot
(``robot.explore.RobotSystem``: the agents' steps take no time; when they are
quiescent, pending calls are launched on the robot, in an order and with fault
points armed as hypothesis draws, or the physics advances until a call ends).
Every step is taken on the model too: an agent step is the model's step with
the same rule, and each answer of the robot is the model's outcome step of the
declared outcome the robot's result falls into. The two disagree, and the test
fails at that step, when the robot produces a result no declared outcome
covers, or takes a step the model cannot take::

    class PairOnRobot(RoarMachine):
        spec = load_spec("pair.roar")
        request = "mission::done == true"
        scenario = "pair.toml"
        faults = ["blind", "spill"]       # fault points the machine may arm at a launch
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar, Optional, Sequence, Union

from hypothesis import settings as Settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, precondition, rule

from ..errors import Pos, RoarError
from .api import AgentSpec, load_spec, split_never, variable_value

__all__ = ["RoarMachine"]


def _class_pos(cls: type) -> Pos:
    """Where a machine class is written: its ``never`` patterns are reported there."""
    import inspect
    try:
        return Pos(inspect.getsourcefile(cls) or "<python>", inspect.getsourcelines(cls)[1], 1)
    except (OSError, TypeError):
        return Pos(cls.__module__, 1, 1)


def _written_pos(cls: type, text: str) -> Pos:
    """Where a class's source writes the string ``text`` (its first character, inside the quotes),
    so that an error in a ``never`` predicate points at its line and column; the class's line if
    the source does not show it (a string built at run time)."""
    import inspect
    try:
        lines, start = inspect.getsourcelines(cls)
        file = inspect.getsourcefile(cls) or "<python>"
    except (OSError, TypeError):
        return _class_pos(cls)
    for k, line in enumerate(lines):
        col = line.find(text)
        if col > 0 and line[col - 1] in "\"'":
            return Pos(file, start + k, col + 1)
    return _class_pos(cls)


class _Setup:
    """What every run of one machine class shares: the compiled model, its start state, the checks."""

    def __init__(self, cls: type["RoarMachine"]):
        from ..clf.signature import ExecDirective
        from ..verify.models import make_never
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
        clf_never, spec_never = [], []
        for pattern in cls.never:   # (each located where the class writes it)
            c, f = split_never([pattern], _written_pos(cls, pattern) if isinstance(pattern, str) else _class_pos(cls))
            clf_never += c
            spec_never += f
        self.never = make_never(self.model.program().sig, str(spec.path or spec.name), clf_never) \
            if clf_never else None
        #: predicates in the spec's terms, read on each state (as a job's [invariant] never)
        self.spec_never = [f.bind(self.model) for f in spec_never]
        for f in self.spec_never:
            if f.events:
                raise RoarError(f"{cls.__name__}.never: {f.text!r} names an event (a step): a machine reads "
                                f"its predicates on states; check events with explore(never=...) or a job file",
                                f.at(1))
        self.outcome_rules = {}
        for fc, (owner, name) in self.model.functions.items():
            self.outcome_rules[f"outcome_{fc}_"] = f"{owner}::{name}" if owner else name
        # a state is a function of the choices that led to it: shrinking replays the same prefixes
        # again and again, so successors and enabled steps are cached by path
        self.states: dict[tuple, tuple] = {}
        self.moves: dict[tuple, list] = {}
        self.lock = _Lockstep(cls, self) if cls.scenario is not None else None

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
            out = [(c, _agent_label(self.system, c, state), self.outcome_of(c.rule))
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


class _Lockstep:
    """The robot side of a machine with a ``scenario``: the spec compiled in run mode, stepped with
    the reference robot as its functional layer, each step mirrored on the model of ``_Setup``."""

    def __init__(self, cls: type["RoarMachine"], setup: _Setup):
        from ..explore.system import Options
        from ..roar.compile import compile_spec
        from ..roar.explore import PROGRESS_RULES
        from ..robot.binding import load_robot_binding
        from ..robot.explore import FaultChoices, RobotSystem, RobotTree
        from ..robot.scenario import did_you_mean, load_scenario
        spec = setup.spec
        pos = _class_pos(cls)
        if spec.text is not None and spec.functional is None:
            raise RoarError(f"{cls.__name__}: a spec given as text has no functional-layer module to bind to the "
                            f"robot; pass functional=... to AgentSpec.from_text", pos)
        self.scenario = load_scenario(Path(cls.scenario))
        faults = cls.faults
        if isinstance(faults, dict):
            fault_at = {n: None if at is None else frozenset([at] if isinstance(at, str) else at)
                        for n, at in faults.items()}
        else:
            fault_at = {n: None for n in ([faults] if isinstance(faults, str) else faults)}
        on = [cls.on] if isinstance(cls.on, str) else list(cls.on)
        for n in [*fault_at, *on]:
            if n not in self.scenario.faults:
                known = ", ".join(self.scenario.faults) or "none"
                raise RoarError(f"{cls.__name__}: fault point '{n}' is not in scenario '{self.scenario.name}'"
                                f"{did_you_mean(n, self.scenario.faults)}; its fault points: {known}", pos)
        binding = load_robot_binding(spec._file(), spec.functional)
        self.registry = binding.robot
        self.model = compile_spec(spec.ast, cls.request, registry=binding.robot, functional="python")
        program = self.model.program()
        start = program.start_context(next(d for d in program.sig.directives if hasattr(d, "start")).start)
        self.tree = RobotTree(self.model, binding.robot, self.scenario, int(cls.seed), tuple(on))
        self.system = RobotSystem(self.model, start, self.tree, FaultChoices(fault_at),
                                  Options(progress_rules=PROGRESS_RULES, fairness="agent"))
        self.start = self.system.initial()
        self.setup = setup
        self.moves: dict[tuple, list] = {}
        self.steps: dict[tuple, tuple] = {}
        # a mirrored model state -> (itself, the robot's fresh names -> the model's as the steps to it
        # matched them): of two instances of a rule that differ only by their names (two requests
        # received), the model takes the one the robot took
        self.renamings: dict[int, tuple] = {}

    def enabled(self, path: tuple, rstate: Any) -> list:
        """(choice or robot successor, agent or "robot", None or the robot step's label) of ``rstate``:
        the agents' enabled steps, or (when they are quiescent) the robot's launches and advance."""
        from ..robot.explore import ROBOT_GROUP
        out = self.moves.get(path)
        if out is None:
            choices = [] if rstate.node.at_horizon else self.system.program.steps(rstate.ctx)
            if choices:
                out = [(c, _agent_label(self.system, c, rstate.ctx), None) for c in choices]
            else:
                out = [(succ, ROBOT_GROUP, _robot_label(succ)) for succ in self.system.successors(rstate)]
            _Setup._remember(self.moves, path, out)
        return out

    def successor(self, path: tuple, rstate: Any, k: int, state: Any) -> tuple:
        """Step ``k`` of ``rstate`` on the robot and on the model (in ``state``): (robot state, robot
        step or None, [(model state, model step, rule)] mirrored, disagreement or None)."""
        key = path + (k,)
        hit = self.steps.get(key)
        if hit is None:
            item, _who, label = self.enabled(path, rstate)[k]
            if label is None:   # an agent step, on the robot's side
                succ = self.system._agent(rstate, item)
                mirrored, why = self._mirror_agent(state, succ.step)
                hit = (succ.state, None, mirrored, why)
            else:
                mirrored, why = self._mirror_robot(state, item.step, item.state.node.time)
                hit = (item.state, item, mirrored, why)
            _Setup._remember(self.steps, key, hit)
        return hit

    def _mirror_agent(self, state: Any, step: Any) -> tuple[list, Optional[str]]:
        from ..explore.replay import match_renaming
        from ..robot.conform import best_match, consistent_match
        sys = self.setup.system
        cands = [c for c in sys.program.steps(state) if c.rule == step.rule]
        if not cands:
            enabled = sorted({c.rule for c in sys.program.steps(state)})
            return [], (f"the robot run takes {step.rule}, which the model cannot take here (the model's enabled "
                        f"steps: {', '.join(enabled) or 'none'})")
        ren = self._renaming(state)
        want = _printed(step)
        got = consistent_match(cands, state, sys.program, want, ren)
        choice = got[0] if got is not None else best_match(cands, state, sys.program, want)[0]
        succ = sys._successor(state, choice)
        # (the successor's fresh names are its own, not those of the trial step matched above)
        self._keep_renaming(succ.state, match_renaming(want, _printed(succ.step), ren) or ren)
        return [(succ.state, succ.step, succ.label)], None

    def _renaming(self, state: Any) -> dict:
        got = self.renamings.get(id(state))
        return got[1] if got is not None and got[0] is state else {}

    def _keep_renaming(self, state: Any, ren: dict) -> None:
        self.renamings[id(state)] = (state, ren)

    def _mirror_robot(self, state: Any, step: Any, t: float) -> tuple[list, Optional[str]]:
        """The model's outcome steps for the calls a launch or an advance answered."""
        from ..clf.printer import show
        from ..roar import vocabulary as V
        from ..explore.replay import match_renaming
        from ..robot.conform import best_match, consistent_match
        from ..roar.run import list_items
        from ..robot.sim import classify
        sys = self.setup.system
        answered = [c for c in step.calls if c[2] is not None]
        parts = [p for p in step.parts if p.rule == "functional_layer"]
        out: list = []
        for part, (fn, _args, res) in zip(parts, answered):
            pend = part.consumed[0][1]
            fc = V.pending(pend).fn.head.name
            owner, name = self.model.functions[fc]
            tys = self.model.fn_params.get(fc, [])
            args = ", ".join(repr(self.system.values.python(x, tys[k] if k < len(tys) else None))
                             for k, x in enumerate(list_items(V.pending(pend).args)))
            shown = f"{owner}::{name}" if owner else name
            rules = [c for c in sys.program.steps(state) if c.rule.startswith(f"outcome_{fc}_")]
            if fc not in self.tree.now_fc:
                prim = self.registry.lookup(name, owner)
                names = classify(prim.outcomes, res, self.model.fn_types.get(fc)) if prim is not None else []
                if not names:
                    declared = ", ".join(o.name for o in prim.outcomes) if prim is not None else "none"
                    return out, (f"the robot's {shown}({args}) returned {res.as_json()} at t = {t:.2f} s, which no "
                                 f"declared outcome of {shown} covers (declared: {declared})")
                wanted = {f"outcome_{fc}_{o}" for o in names}
                cands = [c for c in rules if c.rule in wanted]
                if not cands:
                    return out, (f"the robot's {shown}({args}) ended {res.status} (outcome {names[0]}) at t = "
                                 f"{t:.2f} s, but the model cannot answer {shown} with {' or '.join(names)} here")
            else:
                cands = rules
            if not cands:
                return out, f"the robot answered {shown}({args}), but the model has no answer to it here"
            ren = self._renaming(state)
            got = consistent_match(cands, state, sys.program, ([show(pend)], []), ren, pending_only=True)
            choice = got[0] if got is not None else \
                best_match(cands, state, sys.program, ([show(pend)], []), by_pending=True)[0]
            succ = sys._successor(state, choice)
            self._keep_renaming(succ.state, match_renaming(([show(pend)], []), (_printed(succ.step)[0][:1], []), ren)
                                or ren)
            out.append((succ.state, succ.step, succ.label))
            state = succ.state
        return out, None


def _printed(step: Any) -> tuple[list, list]:
    from ..clf.printer import show
    from ..clf.terms import Root
    return ([show(f) for _m, f in step.consumed if type(f) is Root],
            [show(f) for _m, f in step.produced if type(f) is Root])


def _agent_label(system: Any, choice: Any, state: Any) -> str:
    """The agent taking a step, as hypothesis draws and prints it; "framework" for the steps no agent
    takes (the functional layer's answer to a call its aborted caller no longer waits for)."""
    who = system.agent_of(choice, state)
    return who if who in system.model.agents.values() else FRAMEWORK_GROUP


#: the agent label of steps no agent takes
FRAMEWORK_GROUP = "framework"


def _robot_label(succ: Any) -> str:
    """A robot step as hypothesis shows a draw: the launch (calls, fault points armed) or the advance."""
    ev = succ.step.event
    return succ.label if ev[0] == "launch" else "advance"


class RoarMachine(RuleBasedStateMachine):
    """Subclass with ``spec`` (an :class:`AgentSpec` or a path) and ``request``; ``TestCase`` is
    the test. Class attributes choose the built-in checks."""

    spec: ClassVar[Union[AgentSpec, str, Path, None]] = None
    request: ClassVar[Optional[str]] = None
    #: predicates in the spec's terms no reachable state may satisfy ("arm::holding == true &&
    #: gripper::closed == false"), or CLF patterns no state may match (docs/checking.md, "Invariants")
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
    #: lockstep with the reference robot: its scenario (a TOML path); None drives the model alone
    scenario: ClassVar[Union[str, Path, None]] = None
    #: the robot's seed (every noise term)
    seed: ClassVar[int] = 0
    #: fault points of the scenario the machine may arm at a launch: a list (at any call) or a dict
    #: from fault point to the primitives at whose calls it may be armed (as ``explore_on_robot``)
    faults: ClassVar[Union[Sequence[str], dict]] = ()
    #: fault points on from the start
    on: ClassVar[Sequence[str]] = ()

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
        #: with a scenario, the robot's side: the run-mode context and the robot (a RobotState)
        self.robot_state: Any = setup.lock.start if setup.lock is not None else None
        self.robot_events: list = []    # the robot's launches and advances, numbered as steps
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
        if self._s.lock is not None:
            return self._s.lock.enabled(self._path, self.robot_state)
        return self._s.enabled(self._path, self.state)

    @property
    def robot_time(self) -> Optional[float]:
        """With a scenario, the robot's simulated time (s)."""
        return None if self.robot_state is None else self.robot_state.node.time

    @property
    def robot_pose(self) -> Optional[tuple]:
        """With a scenario, the robot base's pose (x, y, heading in radians)."""
        return None if self.robot_state is None else tuple(self.robot_state.node.pose)

    @property
    def quiescent(self) -> bool:
        """No step is enabled: the run is over."""
        return not self._choices()

    @property
    def final(self) -> bool:
        """Every request is final (success or failure) and no recipe is live."""
        from ..roar.explore import roar_final
        if self.robot_state is not None and self.robot_state.node.at_horizon:
            return True   # the scenario's horizon: the run is cut, not stuck
        return roar_final(self.state)

    def value(self, var: str) -> object:
        """The current value of ``agent::var`` (numbers as int or Fraction)."""
        return variable_value(self.model, self.state, var, self._s.spec.name)

    def format_run(self) -> str:
        """The run so far, one ROAR event a line (``step. agent text``)."""
        evs = sorted(self.robot_events + self.events, key=lambda e: e.step)   # stable: a robot step, then its events
        lines = [f"    {e.step:>3}. {e.agent:<12} {e.text}" for e in evs]
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
        if self._s.lock is not None:
            return self._take_lockstep(k)
        state, step, rule_name = self._s.successor(self._path, self.state, k)
        self._path += (k,)
        self.state = state
        self.rules.append(rule_name)
        made = self._narrator.events(len(self.rules), step)
        self.events.extend(made)
        return made

    def _take_lockstep(self, k: int) -> list:
        """Step ``k`` on the robot and the same step on the model; a disagreement fails the run."""
        from ..roar.run import RoarEvent
        rstate, robot_step, mirrored, why = self._s.lock.successor(self._path, self.robot_state, k, self.state)
        self._path += (k,)
        self.robot_state = rstate
        if robot_step is not None:
            self.robot_events.append(RoarEvent(len(self.rules) + 1, "robot", "robot",
                                               f"{_robot_label(robot_step)} (t = {rstate.node.time:.2f} s)"))
            if not mirrored:
                self.rules.append(robot_step.label)
        made: list = []
        for state, step, rule_name in mirrored:
            self.state = state
            self.rules.append(rule_name)
            got = self._narrator.events(len(self.rules), step)
            self.events.extend(got)
            made.extend(got)
        if why is not None:
            self.fail(f"the robot and the model disagree: {why}")
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

    def _step_label(self, rule: str) -> str:
        """A step as Hypothesis prints the draw: a statement's rule with the statement and its
        line (``st1_make: make(gripper::holding == true) (line 17)``), a framework rule by name."""
        site = self.model.rule_sites.get(rule)
        if not site:
            return rule
        s = self.model.sites[site]
        text = s.text if len(s.text) <= 60 else s.text[:57] + "..."
        return f"{rule}: {text} (line {s.pos.line})"

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
        labels = self._labels([self._step_label(r) for _i, r in moves[agent]])
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
        __tracebackhide__ = True   # (pytest: the failure is the test's, not this library's)
        exc = AssertionError(f"{what}\n{self._run_note()}")
        exc._roar_run_shown = True  # type: ignore[attr-defined]
        raise exc

    def _run_note(self) -> str:
        return f"  after {len(self.rules)} steps; the run, one ROAR event a line:\n{self.format_run()}"

    def check_invariants(self, *args: Any, **kwargs: Any) -> None:
        """The built-in checks, then Hypothesis' invariant checks (the subclass's, which Hypothesis
        runs in the order of their names: the built-in ones first whatever the names); a failing
        ``assert`` of a subclass's invariant gets the run so far as a note, so every failure shows
        the ROAR events that led to it."""
        __tracebackhide__ = True
        try:
            self._builtin_checks()
            super().check_invariants(*args, **kwargs)
        except AssertionError as exc:
            if not getattr(exc, "_roar_run_shown", False):
                exc.add_note(self._run_note())
                exc._roar_run_shown = True  # type: ignore[attr-defined]
            raise

    @invariant()
    def roar_model_checks(self) -> None:
        """The built-in checks, as an invariant Hypothesis lists (check_invariants runs them first)."""
        __tracebackhide__ = True
        self._builtin_checks()

    def _builtin_checks(self) -> None:
        __tracebackhide__ = True
        if self._checked is self.state:
            return
        self._checked = self.state
        s = self._s
        if s.never is not None:
            why = s.never(self.state)
            if why:
                self.fail(f"invariant violated: {why}")
        if s.spec_never:
            from ..roar.props import view_of
            view = view_of(s.model, self.state)
            for f in s.spec_never:
                if f.pf(view):
                    self.fail(f"invariant violated: a reachable state satisfies never {f.text!r}: {f.explain(view)}")
        if self.exclusive_writes:
            w = s.system.shared_write(self.state)
            if w:
                self.fail(f"exclusive-writes violated: {w[0]} is written by the where clauses of two live "
                          f"constraints: {' and '.join(w[1])}")
        if s.system.pairs:
            why = s.system.sequence_reason(self.state)
            if why:
                self.fail(f"sequential-achievement violated: {why}")
        if self.check_deadlock and self.quiescent and not self.final:
            self.fail("deadlock: nothing can move, but a request is not final or a recipe is still live\n"
                      + self._deadlock_note())

    def _deadlock_note(self) -> str:
        """The quiescent state per agent and who waits for whom, as ``roar-verify check`` prints a
        deadlock's final state."""
        from ..roar.report import decode_state
        from ..verify.report import roar_final_lines
        nar = self._narrator
        final = decode_state(self.model, self.state, nar.labels, nar.req_info)
        blocked = [{"agent": a, **act} for a, row in final["agents"].items() for act in row["activities"]]
        rep = {"final": final["agents"],
               "deadlock": {"blocked": blocked, "wait_for": final["wait_for"], "cycle": final["cycle"]}}
        return roar_final_lines(rep, "path").text()
