"""A task tree in DOT: goals and commands as nodes under their parents, with the times they
were handled, and the declared sequential-achievement constraints as dashed edges.

Read from TCA events (:mod:`.trace_events`; a ROAR trace gives them through
:func:`.roar_runs.task_tree_events`), so a run, a robot run and a counterexample all
draw the same way; ``dot -Tsvg`` lays it out.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Iterable

from .trace_events import Declared, Event, Mark, Sent

__all__ = ["task_tree_dot"]

_SHAPE = {"goal": "box", "command": "ellipse", "monitor": "hexagon", "query": "diamond"}


def _q(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def _t(x: Fraction) -> str:
    return f"{float(x):g}"


def task_tree_dot(events: Iterable[Event], title: str = "task tree") -> str:
    """The task tree of ``events`` as DOT text (deterministic: messages in the order sent)."""
    sent: list[Sent] = []
    started: dict[str, Fraction] = {}
    ended: dict[str, Fraction] = {}
    declared: list[Declared] = []
    for e in events:
        if isinstance(e, Sent):
            sent.append(e)
        elif isinstance(e, Mark) and e.what == "started":
            started.setdefault(e.msg, e.time)
        elif isinstance(e, Mark) and e.what == "ended":
            ended[e.msg] = e.time
        elif isinstance(e, Declared):
            declared.append(e)
    out = ["digraph task_tree {", f"  label={_q(title)}; labelloc=t; rankdir=TB;",
           '  node [fontname="Helvetica", fontsize=10]; edge [fontname="Helvetica", fontsize=9];']
    known = {m.msg for m in sent}
    for m in sent:
        span = f"[{_t(started[m.msg]) if m.msg in started else '?'}, {_t(ended[m.msg]) if m.msg in ended else '…'}]"
        what = m.constraint or ""
        who = f"{m.agent}: " if m.agent else ""
        label = f"{m.msg} {m.kind}\n{who}{what}\n{span}"
        style = "" if m.msg in ended else ', style=dashed'
        out.append(f"  {_q(m.msg)} [shape={_SHAPE.get(m.kind, 'box')}, label={_q(label)}{style}];")
    for m in sent:
        if m.parent is not None and m.parent in known:
            out.append(f"  {_q(m.parent)} -> {_q(m.msg)};")
    for d in declared:
        if d.m1 in known and d.m2 in known:
            name = {"seq_ach": "SeqAch"}.get(d.relation, d.relation)
            out.append(f"  {_q(d.m1)} -> {_q(d.m2)} [style=dashed, color=\"#c00000\", constraint=false, "
                       f"label={_q(name)}];")
    out.append("}")
    return "\n".join(out) + "\n"
