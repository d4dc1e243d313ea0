"""Replaying recorded steps on a CLF program, one engine step at a time.

Each recorded step must be an enabled step of the current state (same rule,
same facts consumed and produced, compared as printed multisets, fresh names
up to a consistent renaming); the replay applies it with the engine's general
driver. A counterexample found by any backend therefore doubles as an
independent check: it must replay on the plain engine. A lasso's cycle must
come back to the state where it started.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass, field
from typing import Callable, Optional

from ..clf.context import Context
from ..clf.program import Program
from ..clf.query import show_context
from ..clf.signature import ExecDirective
from ..clf.state import canonical_key
from ..errors import Pos, RoarError
from ..trace.fingerprint import shown
from .system import ClfSystem, Options

__all__ = ["ReplayResult", "replay_steps", "start_index"]


@dataclass
class ReplayResult:
    steps: int
    states: list[Context]
    cycle_closes: Optional[bool]  # None when the trace is not a lasso
    notes: list[str] = field(default_factory=list)  # e.g. no fingerprint recorded, or replayed despite one
    engine_steps: list = field(default_factory=list, repr=False)  # the engine's steps, in order
    records: list[dict] = field(default_factory=list, repr=False)  # each step as the engine took it
    system: Optional[ClfSystem] = field(default=None, repr=False)   # the system replayed on


_PLAIN = re.compile(r"[A-Za-z0-9_'#.-]{1,200}")


def trace_name(value) -> str:
    """A step number or rule name read from a trace: as is when plain, else quoted."""
    text = str(value) if isinstance(value, int) and not isinstance(value, bool) else value
    return text if isinstance(text, str) and _PLAIN.fullmatch(text) else shown(value)


def start_index(path, header: dict) -> int:
    """The header's ``start``: which ``#exec`` directive of the model the trace starts from."""
    start = header.get("start", 1)
    if isinstance(start, bool) or not isinstance(start, int) or start < 1:
        raise RoarError(f'expected "start" in the trace header to be a whole number from 1, not {shown(start)}',
                        Pos(str(path), 1, 1))
    return start


def replay_steps(path, program: Program, start: int, steps: list[dict],
                 on_step: Optional[Callable[[int, dict, Context], None]] = None,
                 notes: Optional[list[str]] = None,
                 make_system: Optional[Callable[[Program, Context], ClfSystem]] = None,
                 stands_for: Optional[dict] = None) -> ReplayResult:
    """Replay the recorded ``steps`` of the trace at ``path`` on ``program`` from its
    ``start``-th ``#exec`` directive. ``on_step(i, record, state)`` sees each step as the engine
    took it (rule, group, consumed, produced come from the engine, not from the file).
    ``make_system`` builds the system to step (a front end's, with its monitors); by default the
    engine's plain :class:`ClfSystem`. ``stands_for`` (printed answered value -> printed value of
    the outcome read for it; it may grow as the steps are read) lets a recorded fact hold an
    answered value where the model holds the outcome's (:func:`reads_as`)."""
    notes = notes if notes is not None else []
    execs = [d for d in program.sig.directives if isinstance(d, ExecDirective)]
    if start > len(execs):
        raise RoarError(f"{path}: start #{start} but the model has {len(execs)} #exec or #trace directive(s)")
    begin = program.start_context(execs[start - 1].start)
    system = make_system(program, begin) if make_system is not None else ClfSystem(program, begin, Options())
    state = system.initial()
    states = [state]
    taken_steps: list = []
    records: list[dict] = []
    loop_start: Optional[Context] = None
    names: dict = {}  # fresh name in the trace -> fresh name in this replay (a bijection)
    for rec in steps:
        if rec.get("loop") and loop_start is None:
            loop_start = state
        want = (rec.get("consumed", []), rec.get("produced", []))
        if not all(isinstance(w, list) and all(isinstance(x, str) for x in w) for w in want):
            raise RoarError(f"{path}: step {trace_name(rec.get('step'))}: \"consumed\" and \"produced\" must be "
                            "lists of facts (strings)")
        nxt = None
        for succ in system.successors(state):
            if succ.label != rec.get("rule"):
                continue
            d = system.describe_step(succ.step)
            m = match_renaming(want, (d["consumed"], d["produced"]), names, stands_for)
            if m is not None:
                names = m
                nxt = succ
                break
        if nxt is None:
            enabled = sorted({s.label for s in system.successors(state)})
            raise RoarError(
                f"{path}: step {trace_name(rec.get('step'))} ({trace_name(rec.get('rule'))}) cannot be replayed: "
                "no such enabled step",
                None, [f"enabled rules here: {', '.join(enabled) or 'none (quiescent)'}",
                       "state: " + "; ".join(show_context(state))])
        state = nxt.state
        states.append(state)
        taken_steps.append(nxt.step)
        d = system.describe_step(nxt.step)
        taken = {"step": len(states) - 1, "rule": nxt.label, "group": nxt.group,
                 "consumed": d["consumed"], "produced": d["produced"], "loop": bool(rec.get("loop"))}
        records.append(taken)
        if on_step is not None:
            on_step(len(states) - 1, taken, state)
    closes = None
    if loop_start is not None:
        closes = canonical_key(loop_start) == canonical_key(state)
        if not closes:
            raise RoarError(f"{path}: the lasso's cycle does not return to the state where it started")
    return ReplayResult(len(steps), states, closes, notes, taken_steps, records, system)


FRESH_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_']*#\d+")


def match_renaming(want: tuple, got: tuple, names: dict, stands_for: Optional[dict] = None) -> Optional[dict]:
    """Do the recorded facts equal the replayed ones up to a consistent renaming of fresh
    names (``hint#id``)? Returns the extended renaming, or None. With ``stands_for`` a recorded
    fact may also hold values an answer gave where the replayed one holds the value of the
    outcome that stands for them (:func:`reads_as`)."""
    for w, g in zip(want, got):
        if len(w) != len(g):
            return None
    ren = dict(names)
    used = set(ren.values())

    def shape(text: str) -> str:
        return FRESH_NAME.sub("#", text)

    def assign(w_lines: list, g_lines: list) -> bool:
        if not w_lines:
            return True
        w = w_lines[0]
        for k, g in enumerate(g_lines):
            if shape(g) != shape(w) and not (stands_for and reads_as(shape(w), shape(g), stands_for)):
                continue
            wn, gn = FRESH_NAME.findall(w), FRESH_NAME.findall(g)
            added = []
            ok = True
            for a, b in zip(wn, gn):
                if a in ren:
                    ok = ren[a] == b
                elif b in used:
                    ok = False
                else:
                    ren[a] = b
                    used.add(b)
                    added.append(a)
                if not ok:
                    break
            if ok and assign(w_lines[1:], g_lines[:k] + g_lines[k + 1:]):
                return True
            for a in added:
                used.discard(ren.pop(a))
        return False

    for w, g in zip(want, got):
        if not assign(list(w), list(g)):
            return None
    return ren


# ------------------------------------------------------------ answers read as their outcomes

_RETURN = re.compile(r"^return (.+) \S+$")


def returned_values(facts: list) -> list[str]:
    """The values of the ``return V D`` facts among printed facts, in order."""
    return [m.group(1) for m in map(_RETURN.match, facts) if m]


def reads_as(recorded: str, replayed: str, stands_for: dict) -> bool:
    """Is ``replayed`` the ``recorded`` fact with some of the values an answer gave (the keys of
    ``stands_for``) written as the value of the outcome that stands for them? Occurrence by
    occurrence: an answer of 4 read as the outcome's 5 leaves a goal of 4 elsewhere in the same
    fact as it is (a blanket replacement read that goal as 5 too)."""
    if recorded == replayed:
        return True
    keys = sorted((k for k in stands_for if k in recorded), key=len, reverse=True)
    if not keys:
        return False
    return _occurrences_pattern(recorded, tuple((k, stands_for[k]) for k in keys)).fullmatch(replayed) is not None


@functools.lru_cache(maxsize=4096)
def _occurrences_pattern(recorded: str, pairs: tuple) -> "re.Pattern":
    """A pattern of ``recorded`` in which each occurrence of an answered value may also be its
    outcome's value (longer values first, so a struct is one occurrence)."""
    alts = {k: f"(?:{re.escape(k)}|{re.escape(v)})" for k, v in pairs}
    find = re.compile("|".join(re.escape(k) for k, _v in pairs))
    out, at = [], 0
    for m in find.finditer(recorded):
        out.append(re.escape(recorded[at:m.start()]))
        out.append(alts[m.group(0)])
        at = m.end()
    out.append(re.escape(recorded[at:]))
    return re.compile("".join(out))


def read_as(fact: str, stands_for: dict) -> str:
    """A printed fact of a trace with each value an answer gave written as the declared outcome
    that stands for it writes it (``stands_for``: printed value -> printed value; compound values
    only, a bare constant being too common to swap). Robot and run replays read traces so."""
    for answered, model_v in stands_for.items():
        fact = fact.replace(answered, model_v)
    return fact
