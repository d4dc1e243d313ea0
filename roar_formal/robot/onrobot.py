"""Replaying a model counterexample on the robot: does the physics realise it?

The explorer's counterexample is an order of agent steps and functional-layer
outcomes. Here the spec runs in simulated time with its primitives on the
robot, but the order is the counterexample's: each agent step is the enabled
step with the same rule (closest facts, values may differ where the robot's
concrete value stands for an outcome's representative one); each outcome
step starts the call on the robot (if it has not started yet), lets the
physics run until the call ends, and checks that the robot's result falls
into the outcome the counterexample names. Calls that end meanwhile wait,
answered, until the counterexample consumes them; a poll found false lets the
robot run for the wait's period, as in a simulation.

The verdict: *realised* (every step happened on the robot: for a deadlock,
the robot run is then stuck as well; for a lasso, the cycle was driven
``loops`` times) or *diverges* at the first step the robot does not take,
with both sides shown.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Optional

from ..clf.context import LIN
from ..clf.terms import Const, Root, const
from ..errors import RoarError
from ..roar import vocabulary as V
from ..roar.run import Narrator, Values, list_items, primitive_error, site_of
from .activity import Activity, CallResult
from .conform import TIMING_RULES, best_match, consistent_match
from .robot import Robot
from .sim import DEFAULT_POLL, CallRecord, classify

__all__ = ["OnRobot", "replay_on_robot"]


@dataclass
class OnRobot:
    realised: bool
    steps: int                   # counterexample steps taken on the robot
    total: int                   # counterexample steps to take (the cycle counted ``loops`` times)
    time: float
    pose: tuple
    message: str
    lines: list = field(default_factory=list)     # what happened, for people
    robot: Optional[Robot] = None
    calls: list = field(default_factory=list)


def replay_on_robot(model, registry, scenario, records: list[dict], seed: Optional[int] = None, faults=(),
                    loops: int = 3, on_line: Optional[Callable[[str], None]] = None, stuck: bool = True) -> OnRobot:
    """Drive ``model`` (compiled in run mode) on the robot in the order of the counterexample ``records``.
    A counterexample without a cycle is realised when every step happened on the robot and, with
    ``stuck`` (a deadlock's), the robot run is stuck where it ends; a path to a state a safety
    property forbids (``stuck`` false) is realised once that state is reached. ``seed`` is the
    robot's (default: the scenario's)."""
    stem = [r for r in records if not r.get("loop")]
    cycle = [r for r in records if r.get("loop")]
    order = stem + cycle * max(1, loops) if cycle else stem
    prog = model.program()
    start = next(d for d in prog.sig.directives if hasattr(d, "start"))
    state = prog.start_context(start.start)
    robot = Robot(scenario, seed=seed, faults=faults)
    values = Values(model)
    narrator = Narrator(model)
    for _mode, f, _n in state.facts():
        if type(f) is Root and isinstance(f.head, Const) and f.head.name == V.RQ:
            narrator.label(V.rq(f).request)
            narrator.req_info["R0"] = (model.request_agent, model.csts[model.request_cst][1])
    lines: list[str] = []
    calls: list[CallRecord] = []
    by_dest: dict = {}          # dest -> CallRecord
    running: dict = {}          # robot handle -> dest
    answered: dict = {}         # dest -> CallResult (ended on the robot, not yet consumed by the counterexample)
    renaming: dict = {}         # the counterexample's fresh names -> this run's, as its steps matched them

    def say(text: str) -> None:
        lines.append(text)
        if on_line:
            on_line(text)

    def done(realised: bool, n: int, msg: str) -> OnRobot:
        lines.append(msg)
        return OnRobot(realised, n, len(order), robot.time, tuple(robot.world.base.pose), msg, lines, robot, calls)

    def advance(until: Optional[float] = None, dest=None) -> None:
        """Run the physics until the call ``dest`` has an answer, or until time ``until``."""
        while True:
            if dest is not None and dest in answered:
                return
            if until is not None and robot.time >= until - 1e-9:
                return
            if robot.time >= robot.horizon - 1e-9:
                return
            for h, res in robot.step():
                d = running.pop(h)
                answered[d] = res
                by_dest[d].result = res
                by_dest[d].t_end = robot.time

    def launch(f) -> None:
        p = V.pending(f)
        d = p.dest
        if d in by_dest:
            return
        fc = p.fn.head.name
        owner, name = model.functions[fc]
        tys = model.fn_params.get(fc, [])
        args = [values.python(x, tys[k] if k < len(tys) else None) for k, x in enumerate(list_items(p.args))]
        rec = CallRecord(len(calls) + 1, f"{owner}::{name}" if owner else name, fc, owner or "?", args, 0, robot.time)
        calls.append(rec)
        by_dest[d] = rec
        if owner is None and name == "now":
            answered[d] = CallResult(int(round(robot.time * 1000)), False, "now", {})
            return
        prim = registry.lookup(name, owner)
        if prim is None or prim.fn is None:
            raise RoarError(f"the robot binding has no implementation of '{rec.function}'")
        try:
            v = prim(*args)
            if isinstance(v, Activity):
                h, res = robot.start(v)
                if res is None:
                    running[h] = d
                    return
            else:
                res = v if isinstance(v, CallResult) else CallResult(v, False, "returned", {})
        except RoarError:
            raise
        except Exception as exc:   # a bug of the binding: located, never a failure to retry
            raise primitive_error(model, fc, prim, args, exc) from None
        answered[d] = res
        rec.result = res
        rec.t_end = robot.time

    def launch_pending(ctx) -> None:
        bag = ctx.index.get(Const(V.PENDING))
        for f in (list(bag.items) if bag else []):
            launch(f)

    for n, rec in enumerate(order, 1):
        rule = rec.get("rule", "")
        if rule in TIMING_RULES:
            continue
        if rec.get("loop") and (n == len(stem) + 1):
            say(f"-- the cycle, driven {max(1, loops)} times --")
        launch_pending(state)
        want = (list(rec.get("consumed", [])), list(rec.get("produced", [])))
        if rule.startswith("outcome_"):
            fc, oname = _split_outcome(rule, model)
            bag = state.index.get(Const(V.PENDING))
            cands = [f for f in (list(bag.items) if bag else []) if V.pending(f).fn.head.name == fc]
            if not cands:
                return done(False, n - 1, f"diverges at step {n}: the counterexample answers {fc} with {oname}, "
                                          f"but the robot run has no such call under way")
            cands.sort(key=lambda f: by_dest[V.pending(f).dest].n)
            f = cands[0]
            d = V.pending(f).dest
            advance(dest=d)
            crec = by_dest[d]
            if d not in answered:
                return done(False, n - 1, f"diverges at step {n}: {crec.function}({_args(crec)}) had not ended "
                                          f"when the scenario's horizon of {robot.horizon:g} s was reached")
            res = answered.pop(d)
            owner, name = model.functions[fc]
            prim = registry.lookup(name, owner)
            names = classify(prim.outcomes, res, model.fn_types.get(fc)) if prim is not None else []
            crec.covering = names
            crec.outcome = names[0] if names else None
            if oname not in names:
                return done(False, n - 1,
                            f"diverges at step {n}: the counterexample needs {crec.function}({_args(crec)}) to end "
                            f"'{oname}'; on the robot it ended {res.status} "
                            f"({', '.join(names) or 'no declared outcome'}) at t = {robot.time:.2f} s")
            state = _answer(state, f, crec, res, model, values)
            say(f"{n:>5} {robot.time:8.2f}s  {crec.function}({_args(crec)}) -> {oname} ({res.status})")
            continue
        choices = [c for c in prog.steps(state) if c.rule == rule]
        if not choices:
            enabled = sorted({c.rule for c in prog.steps(state)})
            return done(False, n - 1, f"diverges at step {n}: the counterexample takes {rule}; on the robot the "
                                      f"enabled rules are {', '.join(enabled) or 'none'}")
        got = consistent_match(choices, state, prog, want, renaming)
        if got is not None:   # the instance the counterexample took, by the names its steps matched
            choice, state, renaming = got
        else:
            choice, state, _exact = best_match(choices, state, prog, want)
        step_printed = rec.get("event") or {}
        text = step_printed.get("text") if isinstance(step_printed, dict) else None
        if text:
            say(f"{n:>5} {robot.time:8.2f}s  {step_printed.get('agent', '')}: {text}")
        period = _poll_period(model, rule)
        if period is not None and any(p.startswith("ctl ") and " m_run " in p for p in want[1]):
            advance(until=robot.time + period)
    launch_pending(state)
    if cycle:
        return done(True, len(order), f"realised: the cycle of {len(cycle)} steps was driven {max(1, loops)} times "
                                      f"on the robot (t = {robot.time:.2f} s)")
    if not stuck:
        return done(True, len(order), f"realised: every step of the counterexample happened on the robot, to the "
                                      f"state it ends in (t = {robot.time:.2f} s)")
    # a deadlock: nothing may happen any more on the robot either
    advance(until=robot.horizon)
    enabled = prog.steps(state)
    if enabled or answered or running:
        what = (f"enabled rules {', '.join(sorted({c.rule for c in enabled}))}" if enabled else
                "a call still under way or answered")
        return done(False, len(order), f"not realised: after the counterexample the robot run goes on ({what})")
    return done(True, len(order), f"realised: the robot run is stuck where the counterexample ends "
                                  f"(nothing enabled, no call under way, t = {robot.time:.2f} s)")


def _split_outcome(rule: str, model) -> tuple[str, str]:
    body = rule[len("outcome_"):]
    for fc in sorted(model.functions, key=len, reverse=True):
        if body.startswith(fc + "_"):
            return fc, body[len(fc) + 1:]
    raise RoarError(f"the counterexample's step {rule} names a function the spec does not have "
                    f"(was it made from another spec?)")


def _answer(state, f, crec, res: CallResult, model, values):
    rty = model.fn_types.get(crec.fc)
    if res.failed:
        term = const("vbool", const("ff")) if rty == "bool" else None
    elif rty is None or (res.value is None and rty != "bool"):
        term = const("vunit")
    else:
        term = values.term(res.value, rty)
    d = V.pending(f).dest
    ans = const(V.RETURN, term, d) if term is not None else const(V.CALLFAIL, d)
    new = state.copy()
    new.remove_fact(f, LIN)
    new.add_fact(ans, LIN)
    return new


def _poll_period(model, rule: str) -> Optional[float]:
    if not rule.endswith("_false"):
        return None
    site = model.sites.get(site_of(model, rule))
    if site is None or site.kind != "wait":
        return None
    return site.period_ms / 1000.0 if site.period_ms else DEFAULT_POLL


def _args(rec: CallRecord) -> str:
    return ", ".join(str(a) for a in rec.args)


# ------------------------------------------------------------------------------------------------
# robot-backed counterexamples: the robot's own events, driven straight


def _robot_record_error(file: str, n: int, what: str) -> RoarError:
    from ..errors import Pos
    return RoarError(f"robot-backed counterexample record: {what}", Pos(file, n + 1, 1))


def check_robot_records(records: list, file: str) -> None:
    """Refuse, at its line, a robot event whose fields do not have the types the replay reads."""
    for n, rec in enumerate(records, 1):
        r = rec.get("robot")
        if r is None:
            continue
        if not isinstance(r, dict) or r.get("kind") not in ("launch", "advance"):
            raise _robot_record_error(file, n, "expected 'robot' to be an object of kind 'launch' or 'advance'")
        if r["kind"] == "launch":
            calls = r.get("calls")
            if not isinstance(calls, list) or not all(isinstance(c, dict) and isinstance(c.get("fc"), str)
                                                      and isinstance(c.get("args"), list) for c in calls):
                raise _robot_record_error(file, n, "expected 'robot.calls' to be a list of {fc, function, args}")
            if not isinstance(r.get("arm", []), list) or not all(isinstance(x, str) for x in r.get("arm", [])):
                raise _robot_record_error(file, n, "expected 'robot.arm' to be a list of fault point names")
            if not isinstance(r.get("results"), list) or len(r["results"]) != len(calls):
                raise _robot_record_error(file, n, "expected 'robot.results' to hold one result (or null) per call")
        else:
            u = r.get("until")
            if u is not None and (isinstance(u, bool) or not isinstance(u, int) or u < 0):
                raise _robot_record_error(file, n, "expected 'robot.until' to be null or a number of ticks")
            if not isinstance(r.get("ended", []), list):
                raise _robot_record_error(file, n, "expected 'robot.ended' to be a list")
        pose = rec.get("pose")
        if pose is not None and (not isinstance(pose, list) or len(pose) != 3
                                 or not all(isinstance(v, (int, float)) for v in pose)):
            raise _robot_record_error(file, n, "expected 'pose' to be [x, y, theta]")


def _same_result(mine: CallResult, rec: Optional[dict]) -> bool:
    if rec is None:
        return False
    got = mine.as_json()
    return got["failed"] == rec.get("failed") and got["status"] == rec.get("status") and \
        got["value"] == rec.get("value")


def replay_robot_path(model, registry, scenario, header: dict, records: list, loops: int = 1,
                      on_line: Optional[Callable[[str], None]] = None) -> OnRobot:
    """Drive one robot, straight (no snapshot, no restore), through the robot events of a
    robot-backed counterexample: the launches with their fault choices and the advances. Each
    call must end as recorded, and the robot must end the path where the explorer said (the
    pose, to a micrometre). A lasso's cycle is driven ``loops`` times; after the first time its
    answers must fall into the same results, since the explorer closed the cycle on states it
    judged the same under its abstraction (which the loops test)."""
    from .explore import start_call
    info = header.get("robot") or {}
    robot = Robot(scenario, seed=None if info.get("seed") is None else int(info["seed"]), faults=tuple(info.get("on", ())))
    now_fc = {fc for fc, (owner, name) in model.functions.items() if owner is None and name == "now"}
    stem = [r for r in records if not r.get("loop")]
    cycle = [r for r in records if r.get("loop")]
    order = [(r, 0) for r in stem] + [(r, k + 1) for k in range(max(1, loops) if cycle else 0) for r in cycle]
    lines: list = []

    def say(text: str) -> None:
        lines.append(text)
        if on_line:
            on_line(text)

    horizon = int(round(float(scenario.horizon) / scenario.dt))
    done_steps = 0
    for i, (rec, loop) in enumerate(order, 1):
        r = rec.get("robot")
        if r is None:
            done_steps += 1
            continue
        tag = f"step {i}" + (f" (cycle, loop {loop})" if loop else "")
        if r["kind"] == "launch":
            for f in r.get("arm", []):
                robot.world.arm(f)
            for c, want in zip(r["calls"], r["results"]):
                fc = c["fc"]
                if fc not in model.functions:
                    return _diverged(robot, done_steps, len(order), lines, say,
                                     f"{tag}: the spec has no function {c.get('function', fc)!r}")
                _h, res = start_call(model, registry, robot, fc, list(c["args"]), now_fc)
                if (res is None) != (want is None) or (res is not None and not _same_result(res, want)):
                    shown = "still running" if res is None else f"{res.status} ({res.value!r})"
                    return _diverged(robot, done_steps, len(order), lines, say,
                                     f"{tag}: {c.get('function', fc)} ended {shown} on the robot; the "
                                     f"counterexample says {'still running' if want is None else want.get('status')}")
            arm = f"; armed {', '.join(r.get('arm', []))}" if r.get("arm") else ""
            say(f"{robot.time:8.2f}s  launch {', '.join(c.get('function', c['fc']) for c in r['calls'])}{arm}")
        else:
            stop = horizon if r.get("until") is None else min(horizon, robot.world.steps + int(r["until"]))
            ended: list = []
            while not ended and robot.world.steps < stop:
                ended = robot.step()
            want = [e.get("result") for e in r.get("ended", [])]
            got = [res for _h, res in ended]
            unmatched = [w for w in want if not any(_same_result(g, w) for g in got)]
            if unmatched:
                return _diverged(robot, done_steps, len(order), lines, say,
                                 f"{tag}: the counterexample has a call end {unmatched[0].get('status')!r} at "
                                 f"t = {robot.time:.2f} s; the robot ended "
                                 f"{', '.join(g.status for g in got) or 'nothing'}")
            if got:
                say(f"{robot.time:8.2f}s  ended: {', '.join(g.status for g in got)}")
        done_steps += 1
        pose = rec.get("pose")
        if pose is not None and not loop:
            err = max(abs(a - b) for a, b in zip(robot.world.base.pose, pose))
            if err > 1e-6:
                return _diverged(robot, done_steps, len(order), lines, say,
                                 f"{tag}: the robot is at {tuple(round(v, 4) for v in robot.world.base.pose)}, the "
                                 f"counterexample says {tuple(round(v, 4) for v in pose)}")
    x, y, th = robot.world.base.pose
    msg = (f"realised on the robot: {done_steps} steps" + (f", the cycle driven {loops} times" if cycle else "")
           + f"; the robot ends at ({x:.2f}, {y:.2f}) as the counterexample says")
    return OnRobot(True, done_steps, len(order), robot.time, (x, y, th), msg, lines, robot)


def _diverged(robot, steps, total, lines, say, why: str) -> OnRobot:
    say(why)
    return OnRobot(False, steps, total, robot.time, tuple(robot.world.base.pose), f"not realised: {why}", lines,
                   robot)
