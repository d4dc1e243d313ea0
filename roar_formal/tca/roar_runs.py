"""ROAR runs as TCA task trees: the project's traces read in Simmons' vocabulary.

A trace written by ``run --trace``, ``simulate --trace`` or a ``check``
counterexample records, per CLF step, the ROAR events it means. The
mapping (docs/tca.md, "ROAR runs as task trees"):

* **a request is a goal message**: the outside request R0 is the root; a
  request sent by a recipe's ``make`` or ``ensure``, or a task run started by
  reading a task-initialised variable, is a child of the request that
  recipe's activation handles. It is sent when its constraint is sent, is
  active from when it is accepted (``-> pending``) until its final state
  (``success``, ``failure``, or ``aborted``; a held ``ensure`` ends when it is
  aborted). Its achievement interval is left to the checker, as TCA leaves a
  goal's;
* **a primitive call is a command message**, a child of the request its
  calling activation handles, active from the call until its answer;
* **two constraint-sending statements of one block, ``make``/``ensure`` A
  before B, declare SeqAch(A, B)** for each instance: the requests sent from
  A's site and then B's site by the same activation (every ordered pair). The
  trace header's ``seq_pairs`` (written by the commands that write traces)
  names the pairs of sites;
* **a plan of sub-goal tasks is a sequence of goals**: when the decision for a
  request R of an agent named in ``seq_pairs`` (a pair ``plan:AGENT``) plans
  tasks T1, ..., Tk (k >= 2), each task becomes a goal ``R.Ti`` (``R.Ti#n`` for
  R's n-th plan), child of R, handled from when it is the task being run
  (recipe selection included) until its recipe ends well (or the plan is
  dropped, or R ends), and the commands and requests of its activations are its
  children; consecutive tasks declare SeqAch(R.Ti, R.Ti+1).

Times are the steps' ``time`` (simulated seconds of robot runs; the steps of
one instant ordered by their number) or, without one, the step number.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Iterable, Optional

from ..errors import Pos, RoarError
from ..trace.format import ROAR_EVENT_KINDS
from .trace_events import Declared, Event, Mark, Sent

__all__ = ["is_roar_trace", "seq_pairs_of", "task_tree_events"]

FINAL = ("success", "failure", "aborted")


def is_roar_trace(header: dict) -> bool:
    return header.get("trace") == "roar-formal"


def _events_of(rec: dict) -> list[dict]:
    ev = rec.get("event")
    if not isinstance(ev, dict):
        return []
    if ev.get("kind") == "several":
        return [e for e in ev.get("events", []) if isinstance(e, dict)]
    return [ev]


#: steps at one simulated instant are ordered by their number: step n is at time + n * TICK
TICK = Fraction(1, 10 ** 9)


def _time(rec: dict, n: int) -> Fraction:
    """The step's time: its simulated time (robot runs) or its number, plus n ticks so that the
    agents' zero-time steps keep their order (TCA's intervals are strict: start < end)."""
    t = rec.get("time")
    if isinstance(t, (int, float)) and not isinstance(t, bool):
        return (Fraction(str(t)) if isinstance(t, float) else Fraction(t)) + n * TICK
    s = rec.get("step")
    return Fraction(s if isinstance(s, int) and not isinstance(s, bool) else n)


def task_tree_events(header: dict, records: Iterable[dict], file: str = "<trace>",
                     first_line: int = 2) -> list[Event]:
    """The TCA events of a ROAR trace (header and step records as ``trace.format.read_trace`` gives them)."""
    sent: dict[str, Sent] = {}
    order: list[str] = []
    starts: dict[str, tuple[Fraction, Pos]] = {}
    ends: dict[str, tuple[Fraction, Pos]] = {}
    rkind: dict[str, str] = {}
    by_emitter: dict[str, list[tuple[str, Optional[str], Fraction]]] = {}
    last_time = Fraction(0)
    recs = list(records)
    timed = any(isinstance(r, dict) and isinstance(r.get("time"), (int, float)) for r in recs)
    plans = _Plans(header, sent, order, starts, ends, file)
    for n, rec in enumerate(recs, 1):
        if not isinstance(rec, dict):
            continue
        pos = Pos(file, first_line + n - 1, 1)
        step = rec.get("step")
        if "step" in rec and (not isinstance(step, int) or isinstance(step, bool)):
            raise RoarError(f"the step number is {step!r}: a whole number is expected", pos)
        t = _time(rec, n)
        if isinstance(rec.get("time"), (int, float)) and not isinstance(rec.get("time"), bool):
            if t < last_time:   # (steps without a time count by number: another unit, not compared)
                raise RoarError(f"step {step}'s time {rec['time']} is before the step before it: a trace's steps "
                                "are in the order they were taken, and time does not go back", pos)
            last_time = t
        for ev in _events_of(rec):
            kind = ev.get("kind")
            if kind not in ROAR_EVENT_KINDS:
                raise RoarError(f"an event of unknown kind {kind!r}: a ROAR trace's events are "
                                f"{', '.join(sorted(ROAR_EVENT_KINDS))}", pos)
            req = ev.get("request")
            plans.event(kind, ev, t, pos)
            if kind in ("sent", "state") and isinstance(req, str):
                if req not in sent:
                    parent = ev.get("parent")
                    parent = parent if isinstance(parent, str) else None
                    if req == "R0":
                        parent = None
                    em = ev.get("emitter")
                    parent = plans.parent(parent, em if isinstance(em, str) else None, t)
                    sent[req] = Sent(req, "goal", parent, t, pos, ev.get("agent"), _constraint(ev))
                    order.append(req)
                    rkind[req] = str(ev.get("rkind") or "make")
                    em = ev.get("emitter")
                    if isinstance(em, str):
                        by_emitter.setdefault(em, []).append((req, ev.get("site"), t))
                if kind == "state":
                    to = ev.get("to")
                    if to in ("pending", "running") and req not in starts:   # accepted (task runs: at once)
                        starts[req] = (t, pos)
                    elif to in FINAL:
                        if req not in starts:            # accepted and decided in one step
                            starts[req] = (t, pos)
                        if req not in ends or rkind.get(req) == "ensure":
                            ends[req] = (t, pos)
            elif kind == "primitive-start" and isinstance(ev.get("call"), str):
                c = ev["call"]
                parent = plans.parent(req, None, t) if isinstance(req, str) else None
                sent[c] = Sent(c, "command", parent, t, pos, ev.get("agent"), str(ev.get("text", "")))
                order.append(c)
                starts[c] = (t, pos)
            elif kind == "primitive-end" and isinstance(ev.get("call"), str):
                ends.setdefault(ev["call"], (t, pos))
    plans.close_all()
    out: list[Event] = []
    # R0 may show no 'sent': it was in the start state
    for m in order:
        out.append(sent[m])
    for m in order:
        if m in starts:
            out.append(Mark("started", m, starts[m][0], starts[m][1]))
        if m in ends:
            t_end = ends[m][0]
            if m in starts and t_end == starts[m][0]:
                # handled within one step (a constraint that already held): it ends within that
                # step, before the next one (TCA's handling intervals are not empty). An end
                # before the start is kept as written: the axioms say what is wrong with it
                t_end = starts[m][0] + (TICK / 2 if timed else Fraction(1, 2))
            out.append(Mark("ended", m, t_end, ends[m][1]))
    # the end of a call the trace never started: kept, so that the task tree reports it (a
    # message that was never sent) instead of dropping it
    for m, (t, pos) in ends.items():
        if m not in sent:
            out.append(Mark("ended", m, t, pos))
    out += _seq_ach(header, by_emitter, file)
    out += [Declared("seq_ach", x, y, Pos(file, 1, 1)) for x, y in plans.declared if x in sent and y in sent]
    return out


def _constraint(ev: dict) -> Optional[str]:
    text = ev.get("text")
    if isinstance(text, str) and "(" in text and text.endswith(")"):
        return text[text.rfind("(") + 1:-1]
    return text if isinstance(text, str) else None


def seq_pairs_of(header: dict, file: str) -> list[list]:
    """The header's ``seq_pairs``: ``[first site, second site, where, ...]`` lists (``plan:AGENT``
    as the first site: that agent's plans). Absent: none; anything else is refused, not read as
    none (a trace whose pairs were garbled would check no SeqAch and pass)."""
    pairs = header.get("seq_pairs", [])
    if not isinstance(pairs, list) or not all(isinstance(p, list) and len(p) >= 2 and isinstance(p[0], str)
                                              and isinstance(p[1], str) for p in pairs):
        raise RoarError('expected "seq_pairs" in the trace header to be a list of [first site, second site, ...] '
                        "lists of strings (as the commands that write traces write it)", Pos(file, 1, 1))
    return pairs


def _seq_ach(header: dict, by_emitter: dict, file: str) -> list[Event]:
    """SeqAch(A, B) for every request A sent from site a and B sent later from site b by one
    activation, (a, b) a pair of the header (every ordered pair of one block, docs/tca.md)."""
    wanted = {(p[0], p[1]) for p in seq_pairs_of(header, file)}
    out: list[Event] = []
    for em, sends in by_emitter.items():
        for k, (a_req, a_site, _t) in enumerate(sends):
            paired = set()
            for b_req, b_site, _tb in sends[k + 1:]:
                if b_site == a_site:          # a new instance of A: pair it, not this one
                    break
                if (a_site, b_site) in wanted and b_site not in paired:
                    paired.add(b_site)
                    out.append(Declared("seq_ach", a_req, b_req, Pos(file, 1, 1)))
    return out


class _Plans:
    """The plans of sub-goal tasks, read from the ``tasks``, ``recipe-end`` and final ``state``
    events of the requests of the agents the header names (``plan:AGENT``): the task goals,
    their handling intervals, the parents they give to what their activations send and call,
    and SeqAch between consecutive tasks."""

    def __init__(self, header: dict, sent: dict, order: list, starts: dict, ends: dict, file: str):
        self.agents = {p[0][5:] for p in seq_pairs_of(header, file) if p[0].startswith("plan:")}
        self.sent, self.order, self.starts, self.ends = sent, order, starts, ends
        self.current: dict[str, dict] = {}     # request -> {"tasks", "k", "goals", "agent"}
        self.count: dict[str, int] = {}        # request -> plans seen
        self.emitters: dict[str, str] = {}     # activation label -> the task goal it runs for
        self.last: dict[str, tuple] = {}       # task goal -> (time, pos) of its last child
        self.open: dict[str, tuple] = {}       # task goal -> when it stopped being the current task
        self.declared: list[tuple[str, str]] = []

    def event(self, kind, ev: dict, t: Fraction, pos: Pos) -> None:
        if not self.agents:
            return
        req = ev.get("request")
        if not isinstance(req, str):
            return
        if kind == "tasks":
            self._stop(req, t, pos)
            ts = ev.get("tasks")
            if ev.get("agent") in self.agents and isinstance(ts, list) and len(ts) >= 2 \
                    and all(isinstance(x, str) for x in ts):
                k = self.count[req] = self.count.get(req, 0) + 1
                self.current[req] = {"tasks": ts, "k": k, "i": 0, "goals": []}
                self._begin(req, t, pos)
        elif kind == "recipe-end" and ev.get("reason") == "ok" and req in self.current:
            plan = self.current[req]
            self._end_goal(plan, t, pos)
            plan["i"] += 1
            if plan["i"] < len(plan["tasks"]):
                self._begin(req, t, pos)
            else:
                del self.current[req]
        elif kind == "state" and ev.get("to") in FINAL:
            self._stop(req, t, pos)

    def _begin(self, req: str, t: Fraction, pos: Pos) -> None:
        plan = self.current[req]
        task = plan["tasks"][plan["i"]]
        gid = f"{req}.{task}" + (f"#{plan['k']}" if plan["k"] > 1 else "")
        agent = self.sent[req].agent if req in self.sent else None
        self.sent[gid] = Sent(gid, "goal", req, t, pos, agent, f"task {task}")
        self.order.append(gid)
        self.starts[gid] = (t, pos)
        if plan["goals"]:
            self.declared.append((plan["goals"][-1], gid))
        plan["goals"].append(gid)

    def _end_goal(self, plan: dict, t: Fraction, pos: Pos) -> None:
        if plan["goals"] and plan["goals"][-1] not in self.open:
            self.open[plan["goals"][-1]] = (t, pos)

    def _stop(self, req: str, t: Fraction, pos: Pos) -> None:
        plan = self.current.pop(req, None)
        if plan is not None:
            self._end_goal(plan, t, pos)

    def parent(self, parent: Optional[str], emitter: Optional[str], t: Fraction) -> Optional[str]:
        """The parent of a message sent at ``t`` by an activation of request ``parent``: the task
        goal that activation runs for, when the request's current plan has one."""
        if not self.agents or parent is None:
            return parent
        goal = self.emitters.get(emitter) if emitter is not None else None
        if goal is None:
            plan = self.current.get(parent)
            if plan is None or not plan["goals"]:
                return parent
            goal = plan["goals"][-1]
            if emitter is not None:
                self.emitters[emitter] = goal
        self.last[goal] = t
        return goal

    def close_all(self) -> None:
        """End every task goal: when it stopped being the current task, or at its last child's
        sending if that came later (an activation's end block runs after it is stopped). The
        current task of a plan still running has not ended."""
        for g, (t, pos) in self.open.items():
            late = self.last.get(g)
            self.ends[g] = (max(t, late), pos) if late is not None else (t, pos)
