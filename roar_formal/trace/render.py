"""Traces for people: one step table shared by ``run``, ``simulate`` and ``replay``.

A row is one ROAR event: the CLF step it comes from, the simulated time
when there is one, the agent, the event, and the robot's pose when the run
had a robot. The table is a :class:`~roar_formal.lines.Lines` document:
input-derived text is never read as markup, so nothing a spec or trace
contains can turn into a style or a picture.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Optional, Sequence

from ..lines import Lines

__all__ = ["Row", "event_rows", "event_lines", "folded", "Repeat", "KIND_STYLE"]

#: the longest block of events whose repeats are folded into one line
MAX_PERIOD = 16
#: a block is folded from this many consecutive occurrences on
MIN_REPEATS = 3

KIND_STYLE = {
    "sent": "cyan", "state": "bold", "tasks": "magenta", "recipe": "magenta", "recipe-end": "magenta",
    "primitive-start": "blue", "primitive-end": "blue", "write": "green", "pause": "yellow",
    "resume": "yellow", "abort": "yellow", "conflict": "red", "calling-context": "red",
}


@dataclass(frozen=True)
class Row:
    step: int
    kind: str
    agent: str
    text: str
    time: Optional[float] = None
    pose: Optional[tuple] = None
    rule: Optional[str] = None

    def cells(self) -> list[str]:
        out = [f"{self.step:>5}"]
        if self.time is not None:
            out.append(f"{self.time:7.2f}s")
        out.append(f"{self.agent:<12}")
        out.append(self.text)
        return out


def _get(ev, key, default=None):
    return ev.get(key, default) if isinstance(ev, dict) else getattr(ev, key, default)


def event_rows(events: Iterable, times: Optional[Sequence[float]] = None, poses: Optional[Sequence] = None,
               rules: Optional[Sequence[str]] = None) -> list[Row]:
    """Rows of the events; ``times``, ``poses`` and ``rules`` are per CLF step (index step - 1)."""
    rows = []
    for ev in events:
        i = int(_get(ev, "step", 0))
        t = times[i - 1] if times is not None and 0 < i <= len(times) else None
        p = tuple(poses[i - 1]) if poses is not None and 0 < i <= len(poses) and poses[i - 1] is not None else None
        r = rules[i - 1] if rules is not None and 0 < i <= len(rules) else None
        rows.append(Row(i, str(_get(ev, "kind", "")), str(_get(ev, "agent", "")), str(_get(ev, "text", "")),
                        t, p, r))
    return rows


@dataclass(frozen=True)
class Repeat:
    """``times`` more occurrences of the ``period`` events just shown, from step ``first`` to ``last``."""

    period: int
    times: int
    first: int
    last: int

    def text(self, unit: str = "event") -> str:
        what = f"the {unit} above" if self.period == 1 else f"the {self.period} {unit}s above"
        return (f"... {what} {'repeats' if self.period == 1 else 'repeat'} {self.times} more time"
                f"{'s' if self.times > 1 else ''} (steps {self.first} to {self.last}; --verbose shows them)")


def folded(rows: Sequence, key=None, step=None) -> list:
    """The rows with each run of at least :data:`MIN_REPEATS` consecutive occurrences of a block
    of events (the same agents, kinds and texts, at other steps) kept once, followed by a
    :class:`Repeat`: a recipe retried for ever reads as one attempt and a count. The block
    folded at a row is the one that covers the most rows (the shortest of those). Other items
    than :class:`Row` are folded by ``key`` (what must repeat) and ``step`` (their step)."""
    key = key or (lambda r: (r.kind, r.agent, r.text))
    step = step or (lambda r: r.step)
    keys = [key(r) for r in rows]
    out: list = []
    i, n = 0, len(rows)
    while i < n:
        best = None   # (rows covered, period, occurrences)
        for p in range(1, MAX_PERIOD + 1):
            if i + MIN_REPEATS * p > n:
                break
            k = 1
            while i + (k + 1) * p <= n and keys[i + k * p:i + (k + 1) * p] == keys[i:i + p]:
                k += 1
            if k >= MIN_REPEATS and (best is None or k * p > best[0]):
                best = (k * p, p, k)
        if best is None:
            out.append(rows[i])
            i += 1
            continue
        _covered, p, k = best
        out.extend(rows[i:i + p])
        out.append(Repeat(p, k - 1, step(rows[i + p]), step(rows[i + k * p - 1])))
        i += k * p
    return out


def event_lines(rows: Iterable[Row], verbose: bool = False, poses: bool = True) -> Lines:
    """The step table as styled lines (styled by kind; printed by the CLI, joined by the library).
    Repeated blocks of events are folded (:func:`folded`) unless ``verbose``."""
    import math

    out = Lines()
    last_pose = None
    rows = list(rows)
    for row in (rows if verbose else folded(rows)):
        if isinstance(row, Repeat):
            out.add((f"{'':>5} ", "dim"), (row.text(), "dim"))
            continue
        parts: list = [(f"{row.step:>5} ", "dim")]
        if row.time is not None:
            parts.append((f"{row.time:8.2f}s ", "dim"))
        parts.append((f"{row.agent:<12} ", ""))
        parts.append((row.text, KIND_STYLE.get(row.kind, "")))
        if poses and row.pose is not None and row.pose != last_pose:
            x, y, th = row.pose[:3]
            parts.append((f"   @ ({x:.2f}, {y:.2f}, {math.degrees(th):.0f}°)", "dim"))
            last_pose = row.pose
        if verbose and row.rule:
            parts.append((f"  ({row.rule})", "dim"))
        out.add(*parts)
    return out
