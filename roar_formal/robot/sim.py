"""Lockstep simulation: the agents on the CLF engine, the functional layer on the pymunk robot.

The agents run as in ``roar-verify run``: the compiled spec, committed
choice, every ROAR event one CLF step. What changes is the functional layer
and time:

* the agents' own steps take no simulated time; they run until nothing more
  can happen at this instant;
* a ``pending`` call starts its primitive on the robot. A primitive that
  returns a plain value answers at once; one that returns an
  :class:`~roar_formal.robot.activity.Activity` answers when the activity
  ends, after the physics has advanced (the other agents meanwhile go on);
* a ``wait`` whose predicate calls the functional layer polls with its
  period: when it is found false, its activation sleeps for the period of
  simulated time (steps ``poll_sleep`` / ``poll_wake``, which take the
  activation's control fact out of the context and put it back; the model
  with that fact present allows every step the robot took, so a robot run is
  still a path of the model);
* ``now()`` reads the simulated clock, in ms.

The run ends when the agents are quiescent with no activity under way, at
the scenario's horizon, or after ``max_steps`` CLF steps.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from collections.abc import Sequence
from typing import Callable, Optional

from ..clf.forward import Run
from ..clf.printer import show
from ..clf.terms import Const, Root, const
from ..errors import RoarError
from ..roar import vocabulary as V
from ..roar.compile import CompiledModel
from ..roar.functional import Registry, misfit, type_table
from ..roar.run import (Fault, Narrator, Resolver, RoarEvent, RunResult, Values, collect_result, list_items,
                        primitive_error, primitive_result_error, site_of)
from .activity import Activity, CallResult
from .robot import Robot
from .scenario import Scenario

__all__ = ["CallRecord", "SimResult", "simulate", "classify", "poll_period", "result_term", "DEFAULT_POLL"]

#: the poll period of a wait written without one (s)
DEFAULT_POLL = 0.1
#: this many CLF steps without simulated time advancing end a run: a loop that takes no time
#: (a retry of a primitive that fails at once) would otherwise spin to the step bound
ZENO_STEPS = 5_000


@dataclass
class CallRecord:
    """One primitive call on the robot: when it started and ended, what it returned, its outcome."""

    n: int                       # the call's number in the run, from 1
    function: str                # 'f' or 'agent::f' as the registry names it
    fc: str                      # the compiled function constant
    agent: str
    args: list                   # the arguments, as Python values (displayable)
    step_start: int              # the CLF step that made the call
    t_start: float
    step_end: Optional[int] = None   # the functional_layer step that answered it
    t_end: Optional[float] = None
    result: Optional[CallResult] = None
    forced: Optional[str] = None     # a --fault that decided the answer
    outcome: Optional[str] = None    # the declared outcome the result falls into (None: none covers it)
    covering: list = field(default_factory=list)   # every declared outcome that covers it

    def as_json(self) -> dict:
        from .activity import jsonable
        return {"n": self.n, "function": self.function, "agent": self.agent, "args": jsonable(self.args),
                "started": round(self.t_start, 4), "ended": None if self.t_end is None else round(self.t_end, 4),
                "result": None if self.result is None else self.result.as_json(), "forced": self.forced,
                "outcome": self.outcome, "covering": self.covering}


@dataclass
class SimResult:
    run: RunResult
    times: list            # per CLF step: the simulated time (s)
    poses: list            # per CLF step: the base's true pose (x, y, theta)
    calls: list            # CallRecord, in the order made
    robot: Robot
    end: str               # quiescent | horizon | max-steps
    seed: int
    faults: tuple          # scenario fault points turned on
    prim_faults: tuple     # --fault on primitives
    snapshots: dict = field(default_factory=dict)   # CLF step -> robot snapshot (when asked for)

    @property
    def outcome(self) -> str:
        return self.run.outcome

    @property
    def ok(self) -> bool:
        return self.run.ok

    @property
    def events(self) -> list[RoarEvent]:
        return self.run.events

    def uncovered(self) -> list[CallRecord]:
        return [c for c in self.calls if c.result is not None and c.forced is None and c.outcome is None]


class _PrintedSteps(Sequence):
    """The run's CLF steps as (rule, consumed, produced) with printed facts, printed when first read:
    a run that writes no trace never pays for printing."""

    def __init__(self):
        self.raw: list = []
        self.printed: dict = {}

    def append(self, step) -> None:
        self.raw.append(step)

    def rule(self, i: int) -> str:
        return self.raw[i].rule

    def __len__(self) -> int:
        return len(self.raw)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(len(self.raw)))]
        if i < 0:
            i += len(self.raw)
        got = self.printed.get(i)
        if got is None:
            step = self.raw[i]
            got = (step.rule, [show(f) for _m, f in step.consumed if type(f) is Root],
                   [show(f) for _m, f in step.produced if type(f) is Root])
            self.printed[i] = got
        return got


def classify(outcomes, result: CallResult, rty: Optional[str] = None) -> list[str]:
    """The names of the declared outcomes that cover ``result`` (see Outcome.covers).

    Without a ``covers`` predicate an outcome covers the results whose success is its own
    and, when it declares a value, whose value is that value; a function of result type
    ``rty`` = bool that returns anything but a bool (and did not fail) is covered by none."""
    if rty == "bool" and not result.failed and not isinstance(result.value, bool):
        return [o.name for o in outcomes if o.covers is not None and _covers(o, result)]
    out = []
    for o in outcomes:
        if o.covers is not None:
            hit = _covers(o, result)   # a predicate that fails on a value does not cover it
        else:
            hit = o.success == result.ok and (o.result is None or _same_value(o.result, result.value))
        if hit:
            out.append(o.name)
    return out


def _covers(o, result) -> bool:
    try:
        return bool(o.covers(result))
    except Exception:
        return False


def _same_value(a, b) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same_value(a[k], b[k]) for k in a)
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return float(a) == float(b)
    return a == b



def poll_period(model: CompiledModel, step) -> Optional[float]:
    """The period (s) an activation sleeps after ``step`` when the step is a poll found false
    (a wait whose predicate calls the functional layer); None for any other step."""
    rule = step.rule
    if not rule.endswith("_false"):
        return None
    site = model.sites.get(site_of(model, rule))
    if site is None or site.kind != "wait":
        return None
    for _m, f in step.produced:
        if type(f) is Root and isinstance(f.head, Const) and f.head.name == V.CTL:
            mode = V.ctl(f).mode
            if isinstance(mode.head, Const) and mode.head.name == "m_run":
                return site.period_ms / 1000.0 if site.period_ms else DEFAULT_POLL
    return None


def result_term(model: CompiledModel, values: Values, fc: str, res: CallResult):
    """The CLF value a call of function ``fc`` answers with ``res`` (None: the call fails)."""
    rty = model.fn_types.get(fc)
    if res.failed:
        return const("vbool", const("ff")) if rty == "bool" else None
    if rty is None or (res.value is None and rty != "bool"):
        return const("vunit")
    return values.term(res.value, rty)

def simulate(model: CompiledModel, registry: Registry, scenario: Scenario, seed: Optional[int] = None, faults=(),
             prim_faults: Optional[list[Fault]] = None, max_steps: int = 200_000,
             on_event: Optional[Callable[[RoarEvent, float], None]] = None, snapshots: bool = False,
             robot: Optional[Robot] = None) -> SimResult:
    """Run ``model`` on a request with ``registry``'s primitives on the robot of ``scenario``; ``seed``
    (of the scheduler and of the robot's noise) is the scenario's unless given."""
    if seed is None:
        seed = scenario.seed
    sim = _Sim(model, registry, scenario, seed, tuple(faults), list(prim_faults or ()), max_steps, on_event,
               snapshots, robot)
    return sim.run()


class _Sim:
    def __init__(self, model, registry, scenario, seed, faults, prim_faults, max_steps, on_event, snapshots, robot):
        self.model = model
        self.registry = registry
        self.robot = robot if robot is not None else Robot(scenario, seed=seed, faults=faults)
        self.seed = seed
        self.faults = faults
        self.prim_faults = prim_faults
        self.max_steps = max_steps
        self.on_event = on_event
        self.want_snapshots = snapshots
        self.snapshots: dict = {}
        prog = model.program()
        start = next(d for d in prog.sig.directives if hasattr(d, "start"))
        self.ctx = prog.start_context(start.start)
        self.values = Values(model)
        self.types: Optional[dict] = None   # the spec's type table, read when a result is first checked
        self.resolver = Resolver(model, registry, prim_faults, self.values)
        self.narrator = Narrator(model)
        self.steps = _PrintedSteps()
        self.events: list = []
        self.times: list = []
        self.poses: list = []
        self.calls: list[CallRecord] = []
        self.by_dest: dict = {}         # dest term -> CallRecord
        self.inflight: dict = {}        # robot handle -> (pending fact, CallRecord)
        self.sleepers: list = []        # (wake time, order, ctl fact)
        self._pose_at, self._pose = None, None
        self._order = 0
        self.now_fc = {fc for fc, (owner, name) in model.functions.items() if owner is None and name == "now"}
        for _mode, f, _n in self.ctx.facts():
            if type(f) is Root and isinstance(f.head, Const) and f.head.name == V.RQ:
                self.narrator.label(V.rq(f).request)
                self.narrator.req_info["R0"] = (model.request_agent, model.csts[model.request_cst][1])
        self.runner = Run(prog.templates, self.ctx, seed=seed, prover=prog.prover(), on_step=self._on_step)

    # ------------------------------------------------------------------ recording
    def _record(self, step) -> int:
        i = len(self.steps) + 1
        self.steps.append(step)
        now = self.robot.time
        if now != self._pose_at:   # the pose changes only when the physics ran: read it once per instant
            self._pose_at, self._pose = now, tuple(self.robot.world.base.pose)
        self.times.append(now)
        self.poses.append(self._pose)
        if step.rule in ("poll_sleep", "poll_wake"):   # timing: no ROAR event
            return i
        for ev in self.narrator.events(i, step):
            self.events.append(ev)
            if self.on_event:
                self.on_event(ev, self.robot.time)
        if self.want_snapshots:
            self.snapshots[i] = self.robot.snapshot()
        return i

    def _on_step(self, step, _ctx) -> None:
        i = self._record(step)
        for _m, f in step.produced:
            if type(f) is Root and isinstance(f.head, Const) and f.head.name == "pending":
                self._called(f, i)
        period = self._poll_period(step)
        if period is not None:
            ctl = next(f for _m, f in step.produced if type(f) is Root and f.head.name == "ctl")
            sleep = self.runner.external([ctl], [], rule="poll_sleep")
            self._record(sleep)
            self._order += 1
            self.sleepers.append((self.robot.time + period, self._order, ctl))

    def _poll_period(self, step) -> Optional[float]:
        return poll_period(self.model, step)

    # ------------------------------------------------------------------ calls
    def _called(self, f, step: int) -> None:
        p = V.pending(f)
        fc = p.fn.head.name
        owner, name = self.model.functions[fc]
        site = self.model.sites.get(site_of(self.model, self.steps.rule(step - 1)))
        agent = site.agent if site else (owner or "?")
        tys = self.model.fn_params.get(fc, [])
        args = [self.values.python(x, tys[k] if k < len(tys) else None) for k, x in enumerate(list_items(p.args))]
        rec = CallRecord(len(self.calls) + 1, f"{owner}::{name}" if owner else name, fc, agent, args, step,
                         self.robot.time)
        self.calls.append(rec)
        self.by_dest[p.dest] = rec

    def _launch(self, f) -> bool:
        """Start the call of pending fact ``f``; True if it was answered at once."""
        rec = self.by_dest[V.pending(f).dest]
        fc = rec.fc
        forced = self.resolver.forced(fc)
        if forced is not None:
            term, how, writes = forced
            rec.forced = how
            # the value the agents receive (a bool function's failing outcome: false, not true)
            value = None if term is None else self.values.python(term, self.model.fn_types.get(fc))
            rec.result = CallResult(value, term is None, how, {})
            self._answer(f, rec, term, writes)
            return True
        if fc in self.now_fc:
            self._finish(f, rec, CallResult(int(round(self.robot.time * 1000)), False, "now", {}))
            return True
        owner, name = self.model.functions[fc]
        prim = self.registry.lookup(name, owner)
        if prim is None or prim.fn is None:
            raise RoarError(f"the robot binding has no implementation of '{rec.function}' "
                            f"(register it in robot_registry())")
        try:
            v = prim(*rec.args)
            res = None
            if isinstance(v, Activity):
                h, res = self.robot.start(v)
                if res is None:
                    self.inflight[h] = (f, rec)
                    return False
            elif isinstance(v, CallResult):
                res = v
            else:
                res = CallResult(v, False, "returned", {})
        except RoarError:
            raise
        except Exception as exc:  # a bug of the binding: located, never a failure to retry
            raise primitive_error(self.model, fc, prim, rec.args, exc) from None
        self._finish(f, rec, res)
        return True

    def _finish(self, f, rec: CallRecord, res: CallResult) -> None:
        rec.result = res
        owner, name = self.model.functions[rec.fc]
        prim = self.registry.lookup(name, owner)
        rty = self.model.fn_types.get(rec.fc)
        if not res.failed and rty is not None and (res.value is not None or rty == "bool"):
            # a value of another type than the declaration's is a bug of the binding, as in a run
            # (read as it is, it would stop the recipe that reads it, silently)
            if self.types is None:
                self.types = type_table(self.model.spec)
            why = misfit(res.value, rty, self.types)
            if why is not None:
                raise primitive_result_error(self.model, rec.fc, prim, list(rec.args), res.value, rty, why)
        rec.covering = classify(prim.outcomes, res, self.model.fn_types.get(rec.fc)) if prim is not None else []
        rec.outcome = rec.covering[0] if len(rec.covering) >= 1 else None
        self._answer(f, rec, result_term(self.model, self.values, rec.fc, res), {})

    def _answer(self, f, rec: CallRecord, term, writes: dict) -> None:
        d = V.pending(f).dest
        ans = const(V.RETURN, term, d) if term is not None else const(V.CALLFAIL, d)
        eaten, made = [f], [ans]
        owner = self.model.functions[rec.fc][0]
        for var, value in writes.items():   # a forced outcome's declared writes
            agent, _, vname = var.rpartition("::")
            cell = f"v_{agent or owner}_{vname}"
            bag = self.ctx.index.get(Const(V.CONTAINS))
            old = next((g for g in (bag.items if bag else ()) if V.contains(g).cell.head.name == cell), None)
            if old is not None:
                eaten.append(old)
                made.append(const(V.CONTAINS, V.contains(old).cell,
                                  self.values.term(value, self.model.cell_types.get(cell))))
        step = self.runner.external(eaten, made, rule="functional_layer")
        i = self._record(step)
        rec.step_end = i
        rec.t_end = self.robot.time

    # ------------------------------------------------------------------ the loop
    def run(self) -> SimResult:
        robot = self.robot
        pending = Const("pending")
        launched: set = set()
        end = "quiescent"
        zeno_mark = (robot.time, 0)
        while True:
            budget = self.max_steps - self.runner.steps if self.max_steps else None
            budget = ZENO_STEPS if budget is None else min(budget, ZENO_STEPS)
            quiet = self.runner.run(self.runner.steps + budget)
            if robot.time > zeno_mark[0]:
                zeno_mark = (robot.time, len(self.steps))
            elif len(self.steps) - zeno_mark[1] >= ZENO_STEPS:
                end = "zero-time loop"
                break
            if not quiet:
                if self.max_steps and self.runner.steps >= self.max_steps:
                    end = "max-steps"
                    break
                continue
            bag = self.ctx.index.get(pending)
            fresh = [f for f in (list(bag.items) if bag else []) if V.pending(f).dest not in launched]
            fresh.sort(key=lambda f: self.by_dest[V.pending(f).dest].n)
            answered = False
            for f in fresh:
                launched.add(V.pending(f).dest)
                answered = self._launch(f) or answered
            if answered:
                continue
            if not self.inflight and not self.sleepers:
                break
            # advance the physics until an activity ends or a sleeper wakes
            done: list = []
            wake = min(self.sleepers)[0] - 1e-9 if self.sleepers else float("inf")
            stop = min(wake, robot.horizon - 1e-9)
            while not done and robot.time < stop:
                done = robot.step()
            if not done and robot.time < wake:
                end = "horizon"
                break
            for h, res in done:
                f, rec = self.inflight.pop(h)
                self._finish(f, rec, res)
            self.sleepers.sort()
            while self.sleepers and self.sleepers[0][0] <= robot.time + 1e-9:
                _t, _o, ctl = self.sleepers.pop(0)
                self._record(self.runner.external([], [ctl], rule="poll_wake"))
            if self.max_steps and self.runner.steps >= self.max_steps:
                end = "max-steps"
                break
        unused = [f for f in self.resolver.faults if f not in self.resolver.used]
        if unused:
            names = ", ".join(str(f) for f in unused)
            raise RoarError(f"--fault {names}: no such call happened in this run (check the name and the call number)")
        res = collect_result(self.model, self.ctx, self.steps, self.events, end == "quiescent", self.narrator)
        return SimResult(res, self.times, self.poses, self.calls, robot, end, self.seed, self.faults,
                         tuple(str(f) for f in self.prim_faults), self.snapshots)
