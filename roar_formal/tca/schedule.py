"""An execution semantics for unrolled task trees: TCA dispatching every
message as soon as it may run.

A handler issues its query children first, one at a time, waiting for each
answer, then works for its ``work`` time, then issues its other children.
A message is ready once issued and once its declared constraints allow it:
``precedes(x, m)`` waits for x to end, ``delay_planning(x, m)`` for x's
achievement to end, and a command or monitor also waits for the achievement
of x to end for every ``seq_ach(x, y)`` with y the message itself or one of
its ancestors (that is how TCA implements sequential achievement). A query is
ready when asked. It starts one dispatch delay after it is ready. Commands,
monitors and queries are achieved while handled; a goal's achievement spans
its children's, and lasts at least until its own handling ends.

The same rules run on numbers (a simulated run, written out as a trace) and
on Z3 terms (the metric analysis), so both read one semantics.
"""

from __future__ import annotations

import random
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, Callable, Optional

import z3

from ..errors import Pos, RoarError
from .trace_events import Declared, Event, Mark, Sent
from .unroll import Instance, Node

Key = tuple[str, str]  # (quantity, message id)


@dataclass(frozen=True)
class Timing:
    """One message's dispatch delay and its handler's own work time."""

    delay: Any
    work: Any


def z3_max(values: list) -> Any:
    out = values[0]
    for v in values[1:]:
        out = z3.If(v > out, v, out)
    return out


def z3_min(values: list) -> Any:
    out = values[0]
    for v in values[1:]:
        out = z3.If(v < out, v, out)
    return out


class Schedule:
    """The times of every message of ``inst`` under ``timing``, computed on demand."""

    def __init__(self, inst: Instance, timing: dict[str, Timing], zero: Any = Fraction(0),
                 maximum: Callable = max, minimum: Callable = min):
        self.inst, self.timing, self.zero = inst, timing, zero
        self.maximum, self.minimum = maximum, minimum
        self.memo: dict[Key, Any] = {}
        self.waits: dict[str, list[Key]] = {m: [] for m in inst.nodes}
        self.seq_before: dict[str, list[str]] = {m: [] for m in inst.nodes}
        for relation, first, second in inst.constraints:
            if relation == "precedes":
                self.waits[second].append(("end", first))
            elif relation == "delay_planning":
                self.waits[second].append(("ach_end", first))
            else:
                self.seq_before[second].append(first)
        # does m or an ancestor of m wait for a seq_ach?
        self.seq_waits: dict[str, bool] = {}
        for m in inst.nodes:
            chain, here = [], m
            while here is not None and here not in self.seq_waits:
                chain.append(here)
                here = inst.nodes[here].parent
            above = self.seq_waits[here] if here is not None else False
            for x in reversed(chain):
                above = self.seq_waits[x] = above or bool(self.seq_before[x])

    # the rules, each a list of dependencies and how to combine their values

    def _queries(self, m: str) -> list[Node]:
        return [c for c in self.inst.children(m) if c.kind == "query"]

    def _ancestors(self, m: str) -> list[str]:
        out, here = [], m
        while here is not None:
            out.append(here)
            here = self.inst.nodes[here].parent
        return out

    def _rule(self, key: Key) -> tuple[list[Key], Callable[[list], Any]]:
        what, m = key
        node = self.inst.nodes[m]
        t = self.timing[m]
        if what == "sent":
            if node.parent is None:
                return [], lambda _: self.zero
            if node.kind != "query":
                return [("end", node.parent)], lambda v: v[0]
            asked = self._queries(node.parent)
            i = next(i for i, q in enumerate(asked) if q.id == m)
            return [("start", node.parent) if i == 0 else ("end", asked[i - 1].id)], lambda v: v[0]
        if what == "start":
            deps = [("sent", m)]
            if node.kind != "query":
                deps += self.waits[m]
                if (node.kind in ("command", "monitor") or not self._achieved_by_children(m)) and self.seq_waits[m]:
                    deps.append(("seq_wait", m))
            return deps, lambda v: self.maximum(v) + t.delay
        if what == "seq_wait":
            # the latest achievement end m waits for: seq_ach(x, y) with y m or an ancestor of m
            # (one key per message, so a deep chain costs linear time, not quadratic)
            deps = [("ach_end", x) for x in self.seq_before[m]]
            if node.parent is not None and self.seq_waits[node.parent]:
                deps.append(("seq_wait", node.parent))
            return deps, lambda v: self.maximum(v)
        if what == "end":
            asked = self._queries(m)
            return [("end", asked[-1].id) if asked else ("start", m)], lambda v: v[0] + t.work
        kids = self._achieved_by_children(m)
        if what == "ach_start":
            if not kids:
                return [("start", m)], lambda v: v[0]
            return [("ach_start", c) for c in kids], lambda v: self.minimum(v)
        if not kids:
            return [("end", m)], lambda v: v[0]
        return [("end", m)] + [("ach_end", c) for c in kids], lambda v: self.maximum(v)

    def _achieved_by_children(self, m: str) -> list[str]:
        node = self.inst.nodes[m]
        if node.kind != "goal":
            return []
        return [c.id for c in self.inst.children(m) if c.kind != "query"]

    def value(self, what: str, m: str) -> Any:
        """A time of a message: sent, start, end, ach_start or ach_end (iterative, so chains may be long)."""
        goal = (what, m)
        stack, busy = [goal], set()
        while stack:
            key = stack[-1]
            if key in self.memo:
                stack.pop()
                continue
            deps, combine = self._rule(key)
            missing = [d for d in deps if d not in self.memo]
            if not missing:
                self.memo[key] = combine([self.memo[d] for d in deps])
                busy.discard(key)
                stack.pop()
                continue
            if key in busy:
                raise RoarError(f"the model's constraints wait on each other around {key[1]}: no schedule")
            busy.add(key)
            stack.extend(missing)
        return self.memo[goal]


def sample_timing(inst: Instance, rng: random.Random, pick: Optional[Callable] = None) -> dict[str, Timing]:
    """Durations drawn within the model's bounds, to the hundredth (``pick`` may choose instead)."""
    bounds = inst.model.durations

    def draw(name: str) -> Fraction:
        lo, hi = bounds[name]
        if pick is not None:
            return pick(name, lo, hi)
        return lo + (hi - lo) * Fraction(rng.randint(0, 100), 100)

    out = {}
    for node in inst.nodes.values():
        out[node.id] = Timing(draw("dispatch"), draw(inst.model.classes[node.cls].work))
    return out


def simulate(inst: Instance, timing: dict[str, Timing], achievement: bool = True) -> list[Event]:
    """The trace events of one run under the eager semantics, in time order."""
    sched = Schedule(inst, timing)
    here = Pos(f"<simulated {inst.model.name}>", 0, 0)
    stamped: list[tuple[Fraction, int, Event]] = []
    for node in inst.nodes.values():
        cls = inst.model.classes[node.cls]
        stamped.append((sched.value("sent", node.id), 1,
                        Sent(node.id, node.kind, node.parent, sched.value("sent", node.id), here, cls.agent, cls.name)))
        stamped.append((sched.value("start", node.id), 0, Mark("started", node.id, sched.value("start", node.id), here)))
        stamped.append((sched.value("end", node.id), 4, Mark("ended", node.id, sched.value("end", node.id), here)))
        if achievement and node.kind == "goal":
            for what, order in (("achieving_started", 3), ("achieving_ended", 5)):
                t = sched.value("ach_start" if what == "achieving_started" else "ach_end", node.id)
                stamped.append((t, order, Mark(what, node.id, t, here)))
    for relation, first, second in inst.constraints:
        t = sched.value("sent", second)
        stamped.append((t, 2, Declared(relation, first, second, here, t)))
    stamped.sort(key=lambda s: (s[0], s[1]))
    return [e for _, _, e in stamped]
