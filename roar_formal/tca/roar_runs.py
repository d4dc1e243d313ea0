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
* **``make A; make B`` in one recipe declares SeqAch(A, B)** for each
  instance: the request sent from B's site after one from A's site by the
  same activation. The trace header's ``seq_pairs`` (written by the commands
  that write traces) names the pairs of sites.

Times are the steps' ``time`` (simulated seconds of robot runs; the steps of
one instant ordered by their number) or, without one, the step number.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Iterable, Optional

from ..errors import Pos
from .trace_events import Declared, Event, Mark, Sent

__all__ = ["is_roar_trace", "task_tree_events"]

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
    for n, rec in enumerate(recs, 1):
        if not isinstance(rec, dict):
            continue
        t = _time(rec, n)
        last_time = max(last_time, t)
        pos = Pos(file, first_line + n - 1, 1)
        for ev in _events_of(rec):
            kind = ev.get("kind")
            req = ev.get("request")
            if kind in ("sent", "state") and isinstance(req, str):
                if req not in sent:
                    parent = ev.get("parent")
                    parent = parent if isinstance(parent, str) else None
                    if req == "R0":
                        parent = None
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
                parent = req if isinstance(req, str) else None
                sent[c] = Sent(c, "command", parent, t, pos, ev.get("agent"), str(ev.get("text", "")))
                order.append(c)
                starts[c] = (t, pos)
            elif kind == "primitive-end" and isinstance(ev.get("call"), str):
                ends.setdefault(ev["call"], (t, pos))
    out: list[Event] = []
    # R0 may show no 'sent': it was in the start state
    for m in order:
        out.append(sent[m])
    for m in order:
        if m in starts:
            out.append(Mark("started", m, starts[m][0], starts[m][1]))
        if m in ends:
            t_end = ends[m][0]
            if m in starts and t_end <= starts[m][0]:
                # handled within one step (a constraint that already held): it ends within that
                # step, before the next one (TCA's handling intervals are not empty)
                t_end = starts[m][0] + (TICK / 2 if timed else Fraction(1, 2))
            out.append(Mark("ended", m, t_end, ends[m][1]))
    out += _seq_ach(header, by_emitter, file)
    return out


def _constraint(ev: dict) -> Optional[str]:
    text = ev.get("text")
    if isinstance(text, str) and "(" in text and text.endswith(")"):
        return text[text.rfind("(") + 1:-1]
    return text if isinstance(text, str) else None


def _seq_ach(header: dict, by_emitter: dict, file: str) -> list[Event]:
    """SeqAch(A, B) for each request B sent from site b right after a request A from site a by one activation."""
    pairs = header.get("seq_pairs")
    if not isinstance(pairs, list):
        return []
    wanted = {(p[0], p[1]) for p in pairs if isinstance(p, list) and len(p) >= 2}
    out: list[Event] = []
    for em, sends in by_emitter.items():
        for k, (a_req, a_site, _t) in enumerate(sends):
            for b_req, b_site, _tb in sends[k + 1:]:
                if b_site == a_site:          # a new instance of A: pair it, not this one
                    break
                if (a_site, b_site) in wanted:
                    out.append(Declared("seq_ach", a_req, b_req, Pos(file, 1, 1)))
                    break
    return out
