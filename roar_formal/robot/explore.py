"""Robot-backed exploration: every interleaving of the agents, the pymunk robot as the functional layer.

The abstract explorer answers a primitive call with each of its declared
outcomes. Here the answer comes from the reference robot: a state of the
search is a pair (CLF state, robot state), and its successors are

* every enabled agent step (the interleavings; agent steps take no time). A
  poll found false puts its activation to sleep for the wait's period, as in
  a simulation (``rb_sleep`` holds the activation's control fact and the
  ticks left);
* when the agents are quiescent and calls are pending: launching them on the
  robot, in every order, and with every choice of the fault points the job
  allows at these calls (a fault point is *armed* at a call: its own timeline
  starts there; it may be armed at this call or a later one, or never). A
  call that ends at once is answered in the same step; the others run
  (``rb_run`` marks them);
* when the agents are quiescent and nothing is left to launch: the physics
  advancing, deterministically, until a running call ends or a sleeping
  activation wakes (or the scenario's horizon).

Robot states live in a tree of :class:`RobotNode` (a node is its parent
plus one launch or advance), memoised, so CLF states that share a robot
history share its node. A node keeps its robot as a snapshot; the live robot
is handed down to the first child computed from it (no copy on a chain) and
restored from the snapshot for the others (a restore replays the world: it
costs the node's age; ``RobotTree.restores`` counts them).

Two states are the same when their CLF states are equal up to renaming of
fresh names and their robot states are equal under the job's
:class:`Abstraction` (``key``). A state at the horizon has no successors: a
verdict is about the behaviours up to the horizon.
"""

from __future__ import annotations

import itertools
import math
import pickle
import hashlib
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Optional

from ..clf.context import Context
from ..clf.rules import LIN
from ..clf.state import canonical_key
from ..clf.terms import Const, Root, const
from ..errors import RoarError
from ..explore.system import Options, Successor
from ..roar import vocabulary as V
from ..roar.compile import CompiledModel
from ..roar.explore import RoarSystem, roar_final
from ..roar.functional import Registry
from ..roar.run import Values, list_items, primitive_error
from .activity import Activity, CallResult
from .robot import BLOCKED_WINDOW, WAIT_LIMIT, Robot
from .scenario import Scenario
from .sim import classify, poll_period, result_term

__all__ = ["Abstraction", "RobotNode", "RobotTree", "RobotState", "RobotStep", "RobotSystem", "FaultChoices",
           "robot_key", "ROBOT_GROUP"]

#: the fairness group of launches and of the physics advancing
ROBOT_GROUP = "robot"
#: at most this many pending calls are launched in every order; more are launched in one order
MAX_ORDERED = 3


# ---------------------------------------------------------------------------------------------- abstraction


@dataclass(frozen=True)
class Abstraction:
    """When two robot states count as the same (the job's ``[robot.quantise]``).

    ``exact``: only states with the same robot history (the same launches, fault choices
    and advances) are the same; nothing is merged that the physics might tell apart.
    Otherwise the base's true and odometry pose to ``position`` m and ``heading`` degrees,
    its speed to ``speed`` m/s (and turn rate to ``heading`` deg/s), the pan angle to
    ``heading``, objects to ``position``; actuator and contact states, doors, fault
    points, running activities and every timer (ticks to the next control step, scan,
    scheduled change, activity deadline, wake-up) exactly. The clock itself is compared
    only when ``clock`` > 0 (to that many seconds); what the robot remembers (its map,
    its last scan, the binding's memo) only when ``memory`` is true."""

    exact: bool = False
    position: float = 0.05
    heading: float = 5.0
    speed: float = 0.05
    clock: float = 0.0
    memory: bool = False

    def describe(self) -> str:
        if self.exact:
            return "exact: states are the same only with the same robot history"
        clock = f"clock to {self.clock:g} s" if self.clock else "clock not compared"
        memory = "memory compared" if self.memory else "memory (map, last scan, memo) not compared"
        return (f"position {self.position:g} m, heading {self.heading:g} deg, speed {self.speed:g} m/s, {clock}, "
                f"{memory}; actuators, contacts, doors, faults, activities and timers exact")

    def as_json(self) -> dict:
        return {"exact": self.exact, "position": self.position, "heading": self.heading, "speed": self.speed,
                "clock": self.clock, "memory": self.memory}


def _q(v: float, step: float) -> int:
    return int(math.floor(v / step + 0.5))


def _qa(rad: float, step_deg: float) -> int:
    """An angle (radians) to ``step_deg`` degrees, wrapped so that -180 and 180 are one."""
    n = max(1, int(round(360.0 / step_deg)))
    return _q(math.degrees(rad), step_deg) % n


def _ticks(seconds: float, dt: float) -> int:
    return int(round(seconds / dt))


def activity_key(act: Activity, robot: Robot) -> tuple:
    """What of a running activity decides its future: its own ``state_key(robot)`` when it
    defines one, else its class and plain attributes (absolute times included, so states
    that differ only in them are kept apart: more states, never fewer; the clock is then
    part of the key, since such times are absolute)."""
    own = getattr(act, "state_key", None)
    if callable(own):
        return (type(act).__name__,) + tuple(own(robot))
    items = []
    for k, v in sorted(vars(act).items()):
        if isinstance(v, (bool, int, float, str, type(None))):
            items.append((k, v))
        elif isinstance(v, (tuple, list)) and all(isinstance(x, (bool, int, float, str)) for x in v):
            items.append((k, tuple(v)))
        else:
            items.append((k, type(v).__name__))
    return (type(act).__name__, tuple(items), ("clock", robot.world.steps))


def robot_key(robot: Robot, a: Abstraction) -> tuple:
    """The robot state under abstraction ``a`` (see :class:`Abstraction`)."""
    w = robot.world
    dt = w.dt
    now = robot.time
    base = w.base
    x, y, th = base.pose
    ox, oy, oth = base.odometry
    v, om = base.velocity
    p, h = a.position, a.heading
    parts: list = [
        ("pose", _q(x, p), _q(y, p), _qa(th, h)),
        ("odometry", _q(ox, p), _q(oy, p), _qa(oth, h)),
        ("velocity", _q(v, a.speed), _q(math.degrees(om), h)),
        ("wheels", tuple(round(s, 6) for s in base.wheel_speeds)),
        ("contact", base.bumped),
        ("doors", tuple(sorted((n, d.open) for n, d in w._doors.items()))),
        ("faults", tuple(sorted(w.faults)), tuple(sorted(n for n, _t in w.armed)), w.scheduled_ticks()),
        ("lidar", w.lidar.dropped_out, _ticks(robot._next_scan - now, dt)),
        ("control", _ticks(robot._next_control - now, dt)),
    ]
    follow: tuple = (robot.follow_state,)
    if robot.path:
        gx, gy = robot.path[-1]
        follow += (_q(gx, p), _q(gy, p))
    if robot.follow_state in ("following", "waiting"):
        t0, best = robot._progress
        cap = WAIT_LIMIT if robot.follow_state == "waiting" else BLOCKED_WINDOW
        follow += (min(_ticks(now - t0, dt), _ticks(cap, dt) + 1), _q(best, p) if math.isfinite(best) else None)
    parts.append(("follow", follow))
    if w.ptu is not None:
        parts.append(("ptu", _qa(math.radians(w.ptu.angle_deg), h), round(w.ptu.target_deg, 6), w.ptu.cable_deg))
    if w.gripper is not None:
        g = w.gripper
        parts.append(("gripper", g.closed, g.holding, g._moving_ticks, g.force))
    for name in sorted(w.objects):
        b = w.objects[name]
        parts.append(("object", name, _q(b.position[0], p), _q(b.position[1], p), _qa(b.angle, h)))
    acts = []
    for hd in sorted(robot.activities):
        dl = robot._deadlines.get(hd)
        acts.append((activity_key(robot.activities[hd], robot), None if dl is None else _ticks(dl - now, dt)))
    parts.append(("activities", tuple(acts)))
    if a.clock:
        parts.append(("clock", _q(now, a.clock)))
    if a.memory:
        digest = hashlib.blake2b(digest_size=16)
        digest.update(pickle.dumps((robot.memo, robot.last_scan, robot.scans), protocol=4))
        digest.update(robot.map.grid.tobytes() if hasattr(robot.map, "grid") else b"")
        parts.append(("memory", digest.hexdigest()))
    return tuple(parts)


# ---------------------------------------------------------------------------------------------- the robot tree


class CallArgs:
    """A call's arguments inside an event: compared by their printed form (lists are not hashable)."""

    __slots__ = ("values", "_key")

    def __init__(self, values: list):
        self.values = list(values)
        self._key = repr(self.values)

    def __eq__(self, other) -> bool:
        return isinstance(other, CallArgs) and self._key == other._key

    def __hash__(self) -> int:
        return hash(self._key)

    def __repr__(self) -> str:
        return self._key


class RobotNode:
    """One robot state: its parent, the event that made it, what it observed."""

    __slots__ = ("id", "parent", "event", "tick", "time", "pose", "key", "results", "children", "armed",
                 "at_horizon", "bad", "depth")


def describe_event(event) -> str:
    kind = event[0]
    if kind == "start":
        return "start"
    if kind == "launch":
        calls = ", ".join(f"{fn}({', '.join(_show(x) for x in args.values)})" for _fc, fn, args in event[1])
        arm = f"; fault {', '.join(event[2])} armed" if event[2] else ""
        return f"launch {calls}{arm}"
    return "advance" + ("" if event[1] is None else f" to tick {event[1]}")


def _show(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float) and v == int(v):
        return str(int(v))
    return repr(v) if isinstance(v, str) else str(v)


class RobotTree:
    """Robot states reached by launches and advances from the scenario's start, memoised."""

    def __init__(self, model: CompiledModel, registry: Registry, scenario: Scenario, seed: Optional[int], faults_on=(),
                 abstraction: Abstraction = Abstraction(), conditions=(), snapshot_cap: int = 4000,
                 live_cap: int = 8):
        self.model = model
        self.registry = registry
        self.scenario = scenario
        self.seed = scenario.seed if seed is None else seed
        self.faults_on = tuple(faults_on)
        self.abstraction = abstraction
        self.conditions = list(conditions)
        self.dt = scenario.dt
        self.horizon_tick = _ticks(float(scenario.horizon), scenario.dt)
        self.nodes: list[RobotNode] = []
        self.snaps: OrderedDict = OrderedDict()
        self.live: OrderedDict = OrderedDict()
        self.snapshot_cap = snapshot_cap
        self.live_cap = live_cap
        self.restores = 0
        self.recomputed = 0
        self.physics_ticks = 0
        self.outcomes_seen: dict = {}     # function constant -> {declared outcome names produced}
        self.uncovered: dict = {}         # (function, status, value) -> CallResult: results no declared outcome covers
        self.now_fc = {fc for fc, (owner, name) in model.functions.items() if owner is None and name == "now"}
        self._mid_bad: list = []          # robot invariants broken during the advance being computed
        robot = Robot(scenario, seed=self.seed, faults=self.faults_on)
        self.root = self._node(None, ("start",), robot, ())

    # ------------------------------------------------------------------ nodes
    def _node(self, parent: Optional[RobotNode], event, robot: Robot, results) -> RobotNode:
        n = RobotNode()
        n.id = len(self.nodes)
        n.parent = parent
        n.event = event
        n.depth = 0 if parent is None else parent.depth + 1
        n.tick = robot.world.steps
        n.time = robot.time
        n.pose = tuple(robot.world.base.pose)
        n.results = results
        n.children = {}
        n.armed = frozenset(robot.world.faults) | frozenset(x for x, _t in robot.world.armed)
        n.at_horizon = n.tick >= self.horizon_tick
        n.key = ("history", n.id) if self.abstraction.exact else robot_key(robot, self.abstraction)
        bad, self._mid_bad = self._mid_bad, []
        for i, c in enumerate(self.conditions):
            why = c.violated(robot)
            if why:
                bad.append((i, why, robot.time, tuple(robot.world.base.pose)))
        n.bad = tuple(bad)
        self.nodes.append(n)
        self.snaps[n.id] = robot.snapshot()
        if len(self.snaps) > self.snapshot_cap:
            self.snaps.popitem(last=False)
        self.live[n.id] = robot
        if len(self.live) > self.live_cap:
            self.live.popitem(last=False)
        return n

    def child(self, node: RobotNode, event) -> RobotNode:
        c = node.children.get(event)
        if c is None:
            robot = self._take(node)
            results = self._apply(robot, event)
            c = self._node(node, event, robot, results)
            node.children[event] = c
        return c

    def robot_at(self, node: RobotNode) -> Robot:
        """A robot in ``node``'s state that the caller may change (for pictures and checks)."""
        return self._take(node)

    def _take(self, node: RobotNode) -> Robot:
        r = self.live.pop(node.id, None)
        if r is not None:
            return r
        snap = self.snaps.get(node.id)
        if snap is not None:
            self.restores += 1
            self.snaps.move_to_end(node.id)
            return Robot.restore(snap)
        chain = []
        a = node
        while a.id not in self.snaps and a.id not in self.live:
            chain.append(a)
            a = a.parent
        r = self._take(a)
        for b in reversed(chain):
            self.recomputed += 1
            self._apply(r, b.event, record=False)
        return r

    # ------------------------------------------------------------------ events
    def _apply(self, robot: Robot, event, record: bool = True):
        kind = event[0]
        if kind == "launch":
            for f in event[2]:
                robot.world.arm(f)
            out = []
            for fc, fn, args in event[1]:
                h, res = self._start(robot, fc, args.values)
                if res is not None and record:
                    self._classify(fc, res)
                out.append((h, res))
            return tuple(out)
        if kind == "advance":
            stop = self.horizon_tick if event[1] is None else min(event[1], self.horizon_tick)
            done: list = []
            t0 = robot.world.steps
            conds = self.conditions if record else ()
            seen_bad = False
            while not done and robot.world.steps < stop:
                done = robot.step()
                if conds and not seen_bad:   # robot invariants hold at every tick, not only at events
                    for i, c in enumerate(conds):
                        why = c.violated(robot)
                        if why:
                            self._mid_bad.append((i, why + " during the advance", robot.time,
                                                  tuple(robot.world.base.pose)))
                            seen_bad = True
                            break
            self.physics_ticks += robot.world.steps - t0
            return tuple(done)
        raise ValueError(f"unknown robot event {event!r}")

    def _start(self, robot: Robot, fc: str, args: list):
        return start_call(self.model, self.registry, robot, fc, args, self.now_fc)

    def _classify(self, fc: str, res: CallResult) -> list:
        if fc in self.now_fc:
            return []
        owner, name = self.model.functions[fc]
        prim = self.registry.lookup(name, owner)
        covering = classify(prim.outcomes, res, self.model.fn_types.get(fc)) if prim is not None else []
        self.outcomes_seen.setdefault(fc, set()).update(covering)
        if not covering:
            fn = f"{owner}::{name}" if owner else name
            self.uncovered.setdefault((fn, res.status, repr(res.value)), res)
        return covering

    def stats(self) -> dict:
        return {"robot_states": len(self.nodes), "restores": self.restores, "recomputed": self.recomputed,
                "physics_ticks": self.physics_ticks}


def start_call(model: CompiledModel, registry: Registry, robot: Robot, fc: str, args: list, now_fc=()):
    """Start a call of function ``fc`` on ``robot``: (activity handle, None) while it runs, or
    (None, result) when it ended at once. A primitive that raises is a located error (a bug of the
    binding), as in ``run``."""
    if fc in now_fc:
        return None, CallResult(int(round(robot.time * 1000)), False, "now", {})
    owner, name = model.functions[fc]
    prim = registry.lookup(name, owner)
    if prim is None or prim.fn is None:
        shown = f"{owner}::{name}" if owner else name
        raise RoarError(f"the robot binding has no implementation of '{shown}' (register it in robot_registry())")
    try:
        v = prim(*args)
        if isinstance(v, Activity):
            return robot.start(v)
        if isinstance(v, CallResult):
            return None, v
        return None, CallResult(v, False, "returned", {})
    except RoarError:
        raise
    except Exception as exc:   # a bug of the binding: located, never a failure to retry
        raise primitive_error(model, fc, prim, args, exc) from None


# ---------------------------------------------------------------------------------------------- the system


@dataclass
class FaultChoices:
    """The fault points the search may arm, each at the calls of which primitives (None: any)."""

    at: dict = field(default_factory=dict)    # fault name -> frozenset of function names, or None

    def armable(self, scenario: Scenario, armed: frozenset, functions: set) -> list[str]:
        out = []
        for name, prims in self.at.items():
            if name in armed:
                continue
            if prims is not None and not (prims & functions):
                continue
            f = scenario.faults[name]
            if f.kind == "door" and any(scenario.faults[g].kind == "door" and scenario.faults[g].door == f.door
                                        for g in armed):
                continue
            out.append(name)
        return out


class RobotState:
    """A search state: the CLF context and the robot node (and which robot activity answers which call)."""

    __slots__ = ("ctx", "node", "handles")

    def __init__(self, ctx: Context, node: RobotNode, handles: dict):
        self.ctx = ctx
        self.node = node
        self.handles = handles   # destination term of a running call -> robot activity handle


@dataclass
class RobotStep:
    """A launch or an advance, as one transition: what it consumed and produced, and the robot event."""

    rule: str
    consumed: list
    produced: list
    event: tuple
    parts: list = field(default_factory=list)   # narratable sub-steps (each answer, each wake-up)
    calls: list = field(default_factory=list)   # [(function, args, result or None)]
    until: Optional[int] = None                 # an advance: ticks to the first wake-up (None: none asleep)
    elapsed: int = 0                            # an advance: ticks the physics ran

    def as_json(self) -> dict:
        """The robot event, as a trace records it (replay drives a robot with it)."""
        if self.event[0] == "launch":
            return {"kind": "launch", "calls": [{"fc": fc, "function": fn, "args": _plain(args.values)}
                                                for fc, fn, args in self.event[1]],
                    "arm": list(self.event[2]),
                    "results": [None if res is None else res.as_json() for _fn, _a, res in self.calls]}
        return {"kind": "advance", "until": self.until, "ticks": self.elapsed,
                "ended": [{"function": fn, "result": res.as_json()} for fn, _a, res in self.calls]}


def _plain(v):
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if v is None or isinstance(v, (bool, int, float, str)):
        return v
    return repr(v)


class _Part:
    """A sub-step the ROAR narrator reads (rule, consumed, produced)."""

    __slots__ = ("rule", "consumed", "produced")

    def __init__(self, rule, consumed, produced):
        self.rule = rule
        self.consumed = consumed
        self.produced = produced


_PENDING, _RUN, _SLEEP = Const(V.PENDING), Const(V.RB_RUN), Const(V.RB_SLEEP)


def _bag(ctx: Context, fam: Const) -> list:
    b = ctx.index.get(fam)
    return list(b.items) if b else []


def _tick_const(n: int):
    return const(f"rbt_{n}")


def _const_ticks(t) -> int:
    return int(t.head.name[4:])


class RobotSystem(RoarSystem):
    """The compiled spec (run mode: calls stay pending) explored with the robot as its functional layer."""

    freeze = None   # its states pair a context with a robot node: kept as they are
    thaw = None
    frozen_type = None

    def __init__(self, model: CompiledModel, start: Context, tree: RobotTree, choices: FaultChoices,
                 options: Optional[Options] = None, pairs=None):
        super().__init__(model, start, options, pairs)
        self.tree = tree
        self.choices = choices
        self.values = Values(model)
        self.dt = tree.dt

    # ------------------------------------------------------------------ explorer API
    def initial(self) -> RobotState:
        return RobotState(self.start, self.tree.root, {})

    def key(self, state: RobotState):
        return (canonical_key(state.ctx), state.node.key, state.node.at_horizon)

    def successors(self, state: RobotState) -> list[Successor]:
        if state.node.at_horizon:
            return []
        choices = self.program.steps(state.ctx)
        if choices:
            return [self._agent(state, c) for c in choices]
        running = {V.rb_run(f).dest for f in _bag(state.ctx, _RUN)}
        fresh = [f for f in _bag(state.ctx, _PENDING) if V.pending(f).dest not in running]
        if fresh:
            return self._launches(state, fresh)
        if running or _bag(state.ctx, _SLEEP):
            return [self._advance(state)]
        return []

    def reduced_successors(self, state: RobotState):
        return self.successors(state), None, ()

    def describe(self, state: RobotState) -> list[str]:
        n = state.node
        x, y, th = n.pose
        return super().describe(state.ctx) + [f"robot: t = {n.time:.2f} s, pose ({x:.2f}, {y:.2f}, "
                                              f"{math.degrees(th):.0f} deg)"]

    def describe_step(self, step) -> dict:
        d = super().describe_step(step)
        if isinstance(step, RobotStep):
            d["robot"] = step.as_json()
            d["robot_event"] = describe_event(step.event)
        return d

    # ------------------------------------------------------------------ agent steps
    def _agent(self, state: RobotState, choice) -> Successor:
        ctx = state.ctx
        nxt, step = self.program.successor(ctx, choice)
        if self.pairs:
            self._monitor(ctx, nxt, step)
        period = poll_period(self.model, step)
        if period is not None:
            ctl = next(f for _m, f in step.produced if type(f) is Root and f.head.name == V.CTL)
            nxt.remove_fact(ctl, LIN)
            nxt.add_fact(const(V.RB_SLEEP, ctl, _tick_const(max(1, _ticks(period, self.dt)))), LIN)
        handles = state.handles
        if any(_h_of(f) == V.PENDING for _m, f in step.consumed):   # a call withdrawn
            handles = {d: h for d, h in handles.items() if _present_dest(nxt, d)}
        return Successor(choice.rule, self.agent_of(choice, ctx), self._progress(choice.rule),
                         RobotState(nxt, state.node, handles), step)

    # ------------------------------------------------------------------ launches
    def _launches(self, state: RobotState, fresh: list) -> list[Successor]:
        values = self.values
        calls = []
        for f in fresh:
            p = V.pending(f)
            fc = p.fn.head.name
            owner, name = self.model.functions[fc]
            tys = self.model.fn_params.get(fc, [])
            args = [values.python(x, tys[k] if k < len(tys) else None) for k, x in enumerate(list_items(p.args))]
            calls.append((f, fc, f"{owner}::{name}" if owner else name, CallArgs(args)))
        if len(calls) <= MAX_ORDERED:
            orders = list(itertools.permutations(calls))
        else:
            orders = [tuple(sorted(calls, key=lambda c: (c[2], repr(c[3]))))]
        names = {c[2].rpartition("::")[2] for c in calls} | {c[2] for c in calls}
        armable = self.choices.armable(self.tree.scenario, state.node.armed, names)
        subsets = []
        for k in range(len(armable) + 1):
            for sub in itertools.combinations(armable, k):
                if _compatible(self.tree.scenario, sub):
                    subsets.append(tuple(sorted(sub)))
        out = []
        for order in orders:
            for arm in subsets:
                event = ("launch", tuple((fc, fn, args) for _f, fc, fn, args in order), arm)
                out.append(self._launch(state, order, event))
        return out

    def _launch(self, state: RobotState, order, event) -> Successor:
        node = self.tree.child(state.node, event)
        nxt = state.ctx.copy()
        handles = dict(state.handles)
        consumed, produced, parts, shown = [], [], [], []
        for (f, fc, fn, args), (h, res) in zip(order, node.results):
            shown.append((fn, args.values, res))
            if res is None:
                dest = V.pending(f).dest
                mark = const(V.RB_RUN, dest)
                nxt.add_fact(mark, LIN)
                produced.append((LIN, mark))
                handles[dest] = h
                continue
            self._answer_call(nxt, f, fc, res, consumed, produced, parts)
        step = RobotStep("functional_layer" if parts else "robot_launch", consumed, produced, event, parts, shown)
        if self.pairs:
            self._monitor(state.ctx, nxt, step)
        return Successor(describe_event(event), ROBOT_GROUP, False, RobotState(nxt, node, handles), step)

    def _answer_call(self, nxt: Context, f, fc: str, res: CallResult, consumed, produced, parts) -> None:
        """Answer pending call ``f`` with ``res`` in ``nxt`` (one narratable part of the step)."""
        ans = _answer(f, result_term(self.model, self.values, fc, res))
        nxt.remove_fact(f, LIN)
        nxt.add_fact(ans, LIN)
        consumed.append((LIN, f))
        produced.append((LIN, ans))
        parts.append(_Part("functional_layer", [(LIN, f)], [(LIN, ans)]))

    # ------------------------------------------------------------------ the physics advancing
    def _advance(self, state: RobotState) -> Successor:
        ctx = state.ctx
        sleepers = [(f, _const_ticks(V.rb_sleep(f).ticks)) for f in _bag(ctx, _SLEEP)]
        node = state.node
        until = node.tick + min(r for _f, r in sleepers) if sleepers else None
        event = ("advance", until)
        child = self.tree.child(node, event)
        elapsed = child.tick - node.tick
        nxt = ctx.copy()
        handles = dict(state.handles)
        by_handle = {h: d for d, h in handles.items()}
        consumed, produced, parts, shown = [], [], [], []
        pend = {V.pending(f).dest: f for f in _bag(ctx, _PENDING)}
        for h, res in child.results:
            d = by_handle.get(h)
            if d is None:
                continue   # an activity whose call was withdrawn: its result goes nowhere
            del handles[d]
            mark = const(V.RB_RUN, d)
            nxt.remove_fact(mark, LIN)
            consumed.append((LIN, mark))
            f = pend.get(d)
            if f is None:
                continue
            fc = V.pending(f).fn.head.name
            self._answer_call(nxt, f, fc, res, consumed, produced, parts)
            owner, name = self.model.functions[fc]
            self.tree._classify(fc, res)
            shown.append((f"{owner}::{name}" if owner else name, None, res))
        for f, rem in sleepers:
            nxt.remove_fact(f, LIN)
            consumed.append((LIN, f))
            left = rem - elapsed
            sleeping = V.rb_sleep(f).ctl
            g = sleeping if left <= 0 else const(V.RB_SLEEP, sleeping, _tick_const(left))
            nxt.add_fact(g, LIN)
            produced.append((LIN, g))
            if left <= 0:
                parts.append(_Part("poll_wake", [], [(LIN, g)]))
        step = RobotStep("robot_advance", consumed, produced, event, parts, shown,
                         None if until is None else until - node.tick, elapsed)
        if self.pairs:
            self._monitor(ctx, nxt, step)
        label = f"advance {elapsed * self.dt:.2f} s"
        return Successor(label, ROBOT_GROUP, False, RobotState(nxt, child, handles), step)

    # ------------------------------------------------------------------ verdict helpers
    def final(self, state: RobotState) -> bool:
        """Not a deadlock: every request final and no recipe left, or the horizon reached."""
        return state.node.at_horizon or roar_final(state.ctx)


def _h_of(t) -> Optional[str]:
    return t.head.name if type(t) is Root and isinstance(t.head, Const) else None


def _present_dest(ctx: Context, d) -> bool:
    return any(V.pending(f).dest is d for f in _bag(ctx, _PENDING))


def _answer(f, term):
    d = V.pending(f).dest
    return const(V.RETURN, term, d) if term is not None else const(V.CALLFAIL, d)


def _compatible(scenario: Scenario, names) -> bool:
    doors = [scenario.faults[n].door for n in names if scenario.faults[n].kind == "door"]
    return len(doors) == len(set(doors))

