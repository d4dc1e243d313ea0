"""The task tree a trace describes: messages with their kinds, parents, and
the send, handling and achievement times the trace recorded.

Extraction never fails on content: what makes the tree ill-formed (an event
for a message never sent, a second start, a parent cycle) is returned as a
list of :class:`Problem` for the checker to report; the tree keeps the first
of each duplicate and cuts cycles so that later passes terminate.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from typing import Iterable, Iterator, Optional

from ..errors import Pos
from .trace_events import Declared, Event, Mark, Sent

TIME_FIELDS = {"started": "start", "ended": "end", "achieving_started": "ach_start", "achieving_ended": "ach_end"}


@dataclass
class Message:
    """One task-tree node; times the trace did not record are None."""

    id: str
    kind: str
    parent: Optional[str]
    sent: Fraction
    pos: Pos
    agent: Optional[str] = None
    constraint: Optional[str] = None
    start: Optional[Fraction] = None
    end: Optional[Fraction] = None
    ach_start: Optional[Fraction] = None
    ach_end: Optional[Fraction] = None
    lines: dict[str, int] = field(default_factory=dict)  # field -> trace line
    children: list[str] = field(default_factory=list)

    @property
    def executes(self) -> bool:
        """Commands and monitors: the messages whose handling is the robot acting."""
        return self.kind in ("command", "monitor")


@dataclass(frozen=True)
class Problem:
    """Something that makes the trace's task tree ill-formed."""

    message: str
    pos: Pos
    messages: tuple[str, ...] = ()


@dataclass
class TaskTree:
    """Messages by id, declared constraints, and a pre-order numbering for ``desc``."""

    messages: dict[str, Message]
    declared: list[Declared]
    horizon: Fraction  # the last time the trace mentions
    order: dict[str, int] = field(default_factory=dict)  # pre-order index
    last: dict[str, int] = field(default_factory=dict)  # largest pre-order index in the subtree

    def is_desc(self, ancestor: str, m: str) -> bool:
        """``m`` is a proper descendant of ``ancestor``."""
        a = self.order[ancestor]
        return a < self.order[m] <= self.last[ancestor]

    def subtree(self, root: str) -> Iterator[Message]:
        """``root`` and its descendants."""
        stack = [root]
        while stack:
            m = self.messages[stack.pop()]
            yield m
            stack.extend(reversed(m.children))

    def path(self, ancestor: str, m: str) -> list[str]:
        """The chain of messages from ``ancestor`` down to ``m``."""
        chain = [m]
        while chain[-1] != ancestor:
            chain.append(self.messages[chain[-1]].parent)
        return chain[::-1]

    def edges(self) -> Iterator[tuple[Message, Message]]:
        for m in self.messages.values():
            if m.parent is not None:
                yield self.messages[m.parent], m


def _number_tree(tree: TaskTree) -> None:
    counter = 0
    roots = [m.id for m in tree.messages.values() if m.parent is None]
    for root in roots:
        stack: list[tuple[str, bool]] = [(root, False)]
        while stack:
            mid, done = stack.pop()
            if done:
                tree.last[mid] = counter - 1
                continue
            tree.order[mid] = counter
            counter += 1
            stack.append((mid, True))
            stack.extend((c, False) for c in reversed(tree.messages[mid].children))


def _cut_cycles(messages: dict[str, Message], problems: list[Problem]) -> None:
    """Make every message reach a root; a parent chain that loops is cut at the message that closes it."""
    state: dict[str, int] = {}  # 1 = on the current chain, 2 = reaches a root
    for start in messages:
        chain = []
        mid: Optional[str] = start
        while mid is not None and state.get(mid) is None:
            state[mid] = 1
            chain.append(mid)
            mid = messages[mid].parent
        if mid is not None and state[mid] == 1:
            loop = chain[chain.index(mid):]
            problems.append(Problem(f"parent links form a cycle: {' -> '.join(loop + [mid])}",
                                    messages[mid].pos, tuple(loop)))
            messages[mid].parent = None
        for c in chain:
            state[c] = 2


def _add_sent(ev: Sent, messages: dict[str, Message], problems: list[Problem]) -> None:
    if ev.msg in messages:
        first = messages[ev.msg].pos
        problems.append(Problem(f"message {ev.msg} sent twice (first at line {first.line})", ev.pos, (ev.msg,)))
        return
    messages[ev.msg] = Message(ev.msg, ev.kind, ev.parent, ev.time, ev.pos, ev.agent, ev.constraint,
                               lines={"sent": ev.pos.line})


def _add_mark(ev: Mark, messages: dict[str, Message], problems: list[Problem]) -> None:
    m = messages.get(ev.msg)
    name = TIME_FIELDS[ev.what]
    if m is None:
        problems.append(Problem(f"'{ev.what}' for message {ev.msg}, which was never sent", ev.pos, (ev.msg,)))
    elif getattr(m, name) is not None:
        problems.append(Problem(f"message {ev.msg} {ev.what} twice (first at line {m.lines[name]})", ev.pos, (ev.msg,)))
    else:
        setattr(m, name, ev.time)
        m.lines[name] = ev.pos.line


def build_tree(events: Iterable[Event]) -> tuple[TaskTree, list[Problem]]:
    """The task tree of ``events`` and what makes it ill-formed."""
    events = list(events)
    messages: dict[str, Message] = {}
    problems: list[Problem] = []
    for ev in events:
        if isinstance(ev, Sent):
            _add_sent(ev, messages, problems)
    for ev in events:
        if isinstance(ev, Mark):
            _add_mark(ev, messages, problems)
    for m in messages.values():
        if m.parent is not None and m.parent not in messages:
            problems.append(Problem(f"message {m.id} names parent {m.parent}, which was never sent", m.pos, (m.id,)))
            m.parent = None
        for end, start in (("end", "start"), ("ach_end", "ach_start")):
            if getattr(m, end) is not None and getattr(m, start) is None:
                problems.append(Problem(f"message {m.id} has {end.replace('_', '.')} but no "
                                        f"{start.replace('_', '.')}", m.pos, (m.id,)))
    _cut_cycles(messages, problems)
    for m in messages.values():
        if m.parent is not None:
            messages[m.parent].children.append(m.id)
    declared = []
    for ev in events:
        if isinstance(ev, Declared):
            unknown = [x for x in (ev.m1, ev.m2) if x not in messages]
            if unknown:
                problems.append(Problem(f"{ev.relation}({ev.m1}, {ev.m2}) names {', '.join(unknown)}, never sent",
                                        ev.pos, tuple(unknown)))
            else:
                declared.append(ev)
    times = [ev.time for ev in events if getattr(ev, "time", None) is not None]
    tree = TaskTree(messages, declared, max(times, default=Fraction(0)))
    _number_tree(tree)
    return tree, problems
